// `excite` names an input that does not exist.
dynid::model! {
    model excite_typo {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        excite uu: lowpass(corner = 10) levels [6, 15, 40]
    }
}

fn main() {}
