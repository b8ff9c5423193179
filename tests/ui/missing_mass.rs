// Every body needs a mass, known (`= 1.0`) or unknown (`~ 1.0`).
dynid::model! {
    model massless {
        body m
        input u on m
        spring k (ground, m) ~ 4.0
    }
}

fn main() {}
