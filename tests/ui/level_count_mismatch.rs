// Both inputs are excited at every level, so they need the same number of levels.
dynid::model! {
    model levels {
        body m1 = 1.0
        body m2 = 1.0
        input u1 on m1
        input u2 on m2
        spring k1 (ground, m1) ~ 4.0
        spring k2 (m1, m2) ~ 3.0
        excite u1: lowpass(corner = 10) levels [6, 15, 40]
        excite u2: lowpass(corner = 10) levels [6, 15]
    }
}

fn main() {}
