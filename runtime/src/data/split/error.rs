//! Why a record cannot be cut into levels: each error names the record, the judged signal
//! and what to do.

use super::MIN_CROSSINGS;

/// Why a record cannot be split.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum SplitError {
    #[error("{origin}: cannot judge the amplitude by `{signal}`: the record has no such column (columns: {present})")]
    #[diagnostic(
        code(dynid::split::unknown_signal),
        help("name one of the record's columns with `--split-by SIGNAL`, best a measured response such as a position")
    )]
    UnknownSignal {
        origin: String,
        signal: String,
        present: String,
    },
    #[error("a record is split into {segments} segment(s), but at least 2 are needed")]
    #[diagnostic(
        code(dynid::split::segments),
        help("give `--segments N` with N of at least 2 (3–8 levels make the drift test sharpest)")
    )]
    TooFewSegments { segments: usize },
    #[error("{origin}: `{signal}` has the non-finite value {value} at sample {sample}")]
    #[diagnostic(
        code(dynid::split::non_finite),
        help("repair or cut away the samples with NaN or infinite values")
    )]
    NonFinite {
        origin: String,
        signal: String,
        sample: usize,
        value: f64,
    },
    #[error("{origin}: `{signal}` does not oscillate about its mean ({crossings} crossings; at least {MIN_CROSSINGS} are needed to tell its dominant frequency, which sets the shortest segment)")]
    #[diagnostic(
        code(dynid::split::no_oscillation),
        help("judge the amplitude by a response that the excitation moves (`--split-by SIGNAL`), or record a longer run")
    )]
    NoOscillation {
        origin: String,
        signal: String,
        crossings: usize,
    },
    #[error("{flag} splits a single data file, but {files} files were given")]
    #[diagnostic(
        code(dynid::split::several_files),
        help("give one file to be split into levels, or drop the flag: with several files each file is one level")
    )]
    SeveralFiles { flag: &'static str, files: usize },
    #[error("`{model}` measures no response to judge the amplitude of `{origin}` by")]
    #[diagnostic(
        code(dynid::split::no_response),
        help("measure a position or velocity of a body, or give one file per level")
    )]
    NoResponse { model: String, origin: String },
    #[error("{origin}: no signal repeats at least twice ({checked} checked: autocorrelation below {correlation} at every lag up to half the record)")]
    #[diagnostic(
        code(dynid::split::no_cycles),
        help("cut it by amplitude (`--cut amplitude`), or give one file per level")
    )]
    NoCycles {
        origin: String,
        checked: String,
        correlation: f64,
    },
    #[error("{origin}: `{by}` repeats every {period} s, {count} whole cycles: too few for {segments} segments of whole cycles")]
    #[diagnostic(
        code(dynid::split::few_cycles),
        help("give `--segments {count}` or fewer (whole cycles per segment), or cut by amplitude with `--cut amplitude`")
    )]
    FewCycles {
        origin: String,
        by: String,
        period: String,
        count: usize,
        segments: usize,
    },
    #[error("{origin}: {n} samples are too short for {segments} segments: each needs at least {min_len} samples ({min_duration} s, 80 / ω₀ with the dominant frequency ω₀ = {omega} rad/s of `{signal}`, so that identification's slowest filter settles)")]
    #[diagnostic(code(dynid::split::too_short), help("{help}"))]
    TooShort {
        origin: String,
        signal: String,
        n: usize,
        segments: usize,
        min_len: usize,
        min_duration: String,
        omega: String,
        help: String,
    },
}
