// `m2` is used as a node but never declared.
dynid::model! {
    model undefined {
        body m1 = 1.0
        input u on m1
        spring k (ground, m2) ~ 4.0
    }
}

fn main() {}
