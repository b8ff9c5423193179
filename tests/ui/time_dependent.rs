// Forces may depend on the state and the inputs, not on time.
dynid::model! {
    model timed {
        body m = 1.0
        input u on m
        spring k (ground, m) ~ 4.0
        force f (ground, m) = a ~ 1.0 * tanh(t)
    }
}

fn main() {}
