// Every mistake in the file is reported, each with its line and column.
dynid::include_model!("models/many_errors.dyn");

fn main() {}
