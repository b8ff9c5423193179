// A spring from a body to itself exerts no force.
dynid::model! {
    model loops {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        spring k2 (m, m) ~ 1.0
    }
}

fn main() {}
