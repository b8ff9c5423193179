// Without an input or a known coefficient every parameter can be scaled by the same factor.
dynid::model! {
    model free {
        body m ~ 1.0
        spring k (ground, m) ~ 4.0
        damper d (ground, m) ~ 0.4
    }
}

fn main() {}
