// `q` is declared but no force uses it, so it cannot be identified.
dynid::model! {
    model unused {
        body m = 1.0
        input u on m
        param q ~ 1.0
        spring k (ground, m) ~ 4.0
    }
}

fn main() {}
