// The path is relative to the calling crate's Cargo.toml; this file does not exist.
dynid::include_model!("models/does_not_exist.dyn");

fn main() {}
