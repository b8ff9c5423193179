// A cubic spring needs the position, but only the velocity is measured (a nonlinear term
// in an unmeasured velocity is fine where the position is measured: identification
// estimates the velocity from it).
dynid::model! {
    model no_position {
        body m = 1.0
        input u on m
        measure m.v, u
        damper d (ground, m) ~ 0.4
        force h (ground, m) = k3 ~ 2.0 * s^3
    }
}

fn main() {}
