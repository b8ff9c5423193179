// Two springs are both called `k`.
dynid::model! {
    model dup {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        spring k (ground, m) ~ 2.0
    }
}

fn main() {}
