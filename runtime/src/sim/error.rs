//! Errors of the simulator.

use std::path::PathBuf;

/// Why a simulation could not be run or written.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum SimError {
    #[error("parameter{} {} of model `{model}` {} no value to simulate with",
        if .names.len() > 1 { "s" } else { "" },
        .names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", "),
        if .names.len() > 1 { "have" } else { "has" })]
    #[diagnostic(
        code(dynid::sim::no_nominal),
        help("give each unknown parameter a nominal value in the model (the value the simulation uses), or make it known")
    )]
    MissingNominal { model: String, names: Vec<String> },

    #[error("model `{model}` has no excitation, so there is nothing to drive it")]
    #[diagnostic(
        code(dynid::sim::no_excitation),
        help("add an `excite` line for at least one input, or drive the model with measured input data (`--input data.csv`)")
    )]
    NoExcitation { model: String },

    #[error("no excitation levels to simulate")]
    #[diagnostic(
        code(dynid::sim::no_levels),
        help("list the white-noise intensities in the model's `excite` line or pass `--levels 6,15,40`")
    )]
    NoLevels,

    #[error("inputs `{first}` and `{other}` are excited at different numbers of levels ({n_first} and {n_other})")]
    #[diagnostic(
        code(dynid::sim::level_count),
        help("every `excite` line must list one intensity per experiment; or override all of them with `--levels`")
    )]
    LevelCountMismatch {
        first: String,
        n_first: usize,
        other: String,
        n_other: usize,
    },

    #[error("input `{input}` has more than one excitation")]
    #[diagnostic(
        code(dynid::sim::excited_twice),
        help("keep one `excite` line per input")
    )]
    ExcitedTwice { input: String },

    #[error("the form filter of input `{input}` is unusable: {reason}")]
    #[diagnostic(
        code(dynid::sim::form_filter),
        help("corner frequencies, natural frequencies and damping ratios of form filters must be positive and finite, levels finite and non-negative")
    )]
    BadFormFilter { input: String, reason: String },

    #[error("invalid simulation setting: {what}")]
    #[diagnostic(code(dynid::sim::config), help("{help}"))]
    InvalidConfig { what: String, help: String },

    #[error("{context}: cannot write the simulated samples: {source}")]
    #[diagnostic(
        code(dynid::sim::scratch),
        help("the samples go to temporary files (of the system's temporary directory when noise is added) and to the output files: free space there, or set TMPDIR to a directory with room")
    )]
    Scratch {
        context: String,
        #[source]
        source: std::io::Error,
    },

    #[error("{what} would take {estimate}")]
    #[diagnostic(code(dynid::sim::too_long), help("{help}"))]
    TooLong {
        what: String,
        estimate: String,
        help: String,
    },

    #[error("the mass matrix is singular (body `{body}` has no usable inertia)")]
    #[diagnostic(
        code(dynid::sim::singular_mass),
        help("every body needs a non-zero mass (check the sign and value of its mass parameter)")
    )]
    SingularMass { body: String },

    #[error("equation of body `{body}` has a term the simulator cannot handle: {what}")]
    #[diagnostic(
        code(dynid::sim::unsupported_term),
        help("only inertia (second derivatives), velocity terms and static functions of signals can be simulated")
    )]
    UnsupportedTerm { body: String, what: String },

    #[error("the simulation diverged at {context}, {when} ({what})")]
    #[diagnostic(
        code(dynid::sim::diverged),
        help("the model is unstable at this excitation (e.g. a negative stiffness or damping, or a softening spring driven past its limit); check parameter values and signs, lower the level, or raise `--substeps`")
    )]
    Diverged {
        context: String,
        /// When, in words: seconds since the run started, and whether in the warm-up.
        when: String,
        what: String,
    },

    #[error("the control law `{law}` gives {value} at {context}, {when}, although everything it reads is finite")]
    #[diagnostic(
        code(dynid::sim::control_law),
        help("the law itself is undefined there (a square root of a negative number, a division by a signal that passes through zero, an overflow): rewrite it so that it is defined for every state the loop reaches (e.g. `sqrt(abs(…))`, or no division by a signal)")
    )]
    ControlLaw {
        law: String,
        value: String,
        context: String,
        when: String,
    },

    #[error("at {context} the motion of `{body}` is too fast for the sample interval {ts} s (ω·Ts ≈ {omega_ts:.2}, {samples_per_period:.1} samples per period)")]
    #[diagnostic(
        code(dynid::sim::under_resolved),
        help("the record would alias and the integration is not trustworthy: use a smaller `--sample`, or check the model for runaway parameters (negative damping, very stiff or strongly hardening springs at this level)")
    )]
    UnderResolved {
        context: String,
        body: String,
        omega_ts: f64,
        samples_per_period: f64,
        ts: f64,
    },

    #[error("the input data has no column `{input}`")]
    #[diagnostic(
        code(dynid::sim::missing_input),
        help("the driving data needs one column per model input not computed by a control law, and one per reference, named like them (found: {found})")
    )]
    MissingInputColumn { input: String, found: String },

    #[error("the input data is unusable: {what}")]
    #[diagnostic(
        code(dynid::sim::bad_input_data),
        help("give a uniformly sampled record with at least two finite samples per input")
    )]
    BadInputData { what: String },

    #[error("cannot write `{}`", .path.display())]
    #[diagnostic(
        code(dynid::sim::write),
        help("check that the output directory exists and is writable")
    )]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}
