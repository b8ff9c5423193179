// A force that depends on no signal is a constant bias, which the method cannot separate.
dynid::model! {
    model constant {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        force bias (ground, m) = f0 ~ 0.5 * 2
    }
}

fn main() {}
