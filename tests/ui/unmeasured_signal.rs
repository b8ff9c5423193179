// Coulomb friction needs the velocity, but only the position is measured (the linear
// damper is fine: its derivative moves onto the filter).
dynid::model! {
    model no_velocity {
        body m = 1.0
        input u on m
        measure m.x, u
        spring k (ground, m) ~ 4.0
        damper d (ground, m) ~ 0.4
        force friction (ground, m) = r ~ 0.3 * sign(v)
    }
}

fn main() {}
