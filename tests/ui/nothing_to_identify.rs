// Every coefficient is known (`=`), so there is nothing to identify.
dynid::model! {
    model all_known {
        body m = 1.0
        input u on m
        spring k (ground, m) = 4.0
        damper d (ground, m) = 0.4
    }
}

fn main() {}
