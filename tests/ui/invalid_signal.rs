// A body has the signals `.x` and `.v` only.
dynid::model! {
    model signal {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        force f (ground, m) = c ~ 1.0 * sign(m.y)
    }
}

fn main() {}
