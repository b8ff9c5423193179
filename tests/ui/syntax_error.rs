// A force expression that ends after an operator.
dynid::model! {
    model sdof {
        body m1 { mass = 1.0 }
        param k ~ 4.0
        spring k1 (ground, m1) = k * s +
    }
}

fn main() {}
