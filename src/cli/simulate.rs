//! `dynid simulate`.

/// Arguments of `dynid simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The model file.
    pub model: std::path::PathBuf,
}

pub fn run(_args: Args) -> miette::Result<()> {
    Err(miette::miette!("`dynid simulate` is not available yet"))
}
