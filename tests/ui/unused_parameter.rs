// `k3` is declared but no force uses it, so it cannot be identified.
dynid::model! {
    model sdof {
        body m1 { mass = 1.0 }
        param k ~ 4.0
        param k3 ~ 2.0
        spring k1 (ground, m1) = k * s
    }
}

fn main() {}
