// A parameter must enter the force linearly (as a coefficient), not inside `tanh`.
dynid::model! {
    model sdof {
        body m1 { mass = 1.0 }
        param k ~ 4.0
        param a ~ 10.0
        spring k1 (ground, m1) = k * tanh(a * s)
    }
}

fn main() {}
