// The connection of an element needs a comma between its two nodes.
dynid::model! {
    model oops {
        body m = 1.0
        input u on m
        spring k (ground m) ~ 4.0
    }
}

fn main() {}
