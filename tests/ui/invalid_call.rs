// There is no function `sgn`: the sign function is `sign`.
dynid::model! {
    model calls {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        force f (ground, m) = r ~ 0.3 * sgn(v)
    }
}

fn main() {}
