// The input `u` is excited twice.
dynid::model! {
    model twice {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        excite u: lowpass(corner = 10) levels [6, 15, 40]
        excite u: white levels [1, 2, 3]
    }
}

fn main() {}
