// A parameter must enter the force as a coefficient, not as an exponent.
dynid::model! {
    model nonlinear {
        body m = 1.0
        input u on m
        param n ~ 3
        spring k (ground, m) ~ 4.0
        force a (ground, m) = c ~ 1.0 * s^n
    }
}

fn main() {}
