// `k4` is used but never declared.
dynid::model! {
    model sdof {
        body m1 { mass = 1.0 }
        param k ~ 4.0
        spring k1 (ground, m1) = k * s + k4 * s^3
    }
}

fn main() {}
