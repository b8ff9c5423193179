// A mass must be positive.
dynid::model! {
    model values {
        body m = -1.0
        input u on m
        spring k (ground, m) ~ 4.0
    }
}

fn main() {}
