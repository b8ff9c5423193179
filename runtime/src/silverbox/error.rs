//! The errors of the Silverbox procedure: the data (missing, unreadable, not the
//! benchmark's layout), the model (not one body driven by one input), and what
//! identification or simulation refuse.

use crate::data::DataError;
use crate::ident::IdentifyError;
use crate::sim::SimError;
use std::path::PathBuf;

/// Errors of the Silverbox procedure.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum SilverboxError {
    #[error("cannot read the Silverbox data `{}`", path.display())]
    #[diagnostic(
        code(dynid::silverbox::io),
        help("put the original SNLS80mV.csv (Wigren & Schoukens 2013) into the data directory, or point to its directory with `--data DIR`")
    )]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}, line {line}: {what}", path.display())]
    #[diagnostic(
        code(dynid::silverbox::malformed),
        help("the file must be the original SNLS80mV.csv: a header \"V1\",\"V2\" and two numbers (volts) per line")
    )]
    Malformed {
        path: PathBuf,
        line: u64,
        what: String,
    },
    #[error("{}: found {found} multisine realisations after the arrow, expected {expected}", path.display())]
    #[diagnostic(
        code(dynid::silverbox::segments),
        help("the file is not the original SNLS80mV.csv, or it was cut; use the unchanged file")
    )]
    Segments {
        path: PathBuf,
        found: usize,
        expected: usize,
    },
    #[error("the model `{model}` does not fit the Silverbox data: {what}")]
    #[diagnostic(
        code(dynid::silverbox::model),
        help("use one body whose position is measured and one measured input (e.g. `body y`, `input u on y`, `measure y.x, u`)")
    )]
    Model { model: String, what: String },
    #[error("{what} would need {estimate}")]
    #[diagnostic(code(dynid::silverbox::too_large), help("{help}"))]
    TooLarge {
        what: String,
        estimate: String,
        help: String,
    },
    #[error(transparent)]
    #[diagnostic(transparent)]
    Identify(#[from] IdentifyError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Refine(#[from] crate::refine::RefineError),
}
