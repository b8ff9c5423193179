// `s` is the relative displacement in force expressions and cannot name a body.
dynid::model! {
    model reserved {
        body s = 1.0
        input u on s
        spring k (ground, s) ~ 4.0
    }
}

fn main() {}
