// A bare number as a force term: a constant force needs a parameter (`f0 ~ 1.0`).
dynid::model! {
    model constant {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        force bias (ground, m) = 0.5 * 2
    }
}

fn main() {}
