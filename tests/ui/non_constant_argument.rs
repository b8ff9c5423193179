// The gap of a dead zone must be a number, not a signal.
dynid::model! {
    model arguments {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        force f (ground, m) = b ~ 1.0 * deadzone(s, v)
    }
}

fn main() {}
