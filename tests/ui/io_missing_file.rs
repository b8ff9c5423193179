// The model file does not exist. (A relative path, the usual form, is taken from the
// directory of the calling crate's Cargo.toml; the error then names the absolute path it
// tried, which differs between checkouts, so this case uses an absolute path.)
dynid::include_model!("/nonexistent/models/two_mass.dyn");

fn main() {}
