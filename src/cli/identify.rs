//! `dynid identify`.

/// Arguments of `dynid identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The model file.
    pub model: std::path::PathBuf,
}

pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`dynid identify` is not available yet"))
}
