//! What identification is configured with and what it returns: options, errors and the
//! result types.

use super::design::{LowerBy, UpperBy};
use super::filter::Hold;
use super::moments::PhaseTimes;
use super::noise::NoiseSummary;
use super::rests::RestSummary;
use super::velocity::VelocityEstimate;
use crate::data::DataError;
use dynid_ir::ir::SignalId;
use serde::Serialize;
use std::collections::BTreeMap;

/// A level counts as centred (its mean removed) when every signal driving the filters has
/// `|mean| ≤ CENTRED_REL · std`: far below any sampling spread of a mean, far above the
/// rounding left by subtracting one.
pub const CENTRED_REL: f64 = 1e-9;

/// An estimate counts as significant when `|value| > SIGNIFICANCE_T · stderr` (about 95 %
/// two-sided for a normal estimate).
pub const SIGNIFICANCE_T: f64 = 2.0;

/// Choices of the identification; `Default` gives the method's recommended settings.
#[derive(Clone, Debug)]
pub struct IdentifyOptions {
    /// Filter corners in rad/s. `None`: the model's filter block, else designed from the data.
    pub corners: Option<Vec<f64>>,
    /// Number of corners when they are designed from the data.
    pub n_corners: usize,
    /// Sections per low-pass chain. `None`: the model's filter block, else 3, or 4 when
    /// accelerations must come from positions alone (so the instruments keep relative
    /// degree ≥ 3), 5 when bodies are measured by accelerations only, and at least 6 for
    /// the filtered equation with the inputs' delays (`filtered` and `input_delay`).
    pub order: Option<usize>,
    /// Signals driving the filter bank. `None`: the model's filter block, else the measured
    /// positions and inputs.
    pub drivers: Option<Vec<SignalId>>,
    /// Add virial and power-balance rows where velocities are measured (default: no; they
    /// do not improve the pooled estimate, `ident::tests::recovery`).
    pub balance: bool,
    /// Time blocks per level for the standard errors (hat windows span two blocks). `None`:
    /// chosen from the record ([`design::blocks`]: between 20 and 80).
    pub n_blocks: Option<usize>,
    /// Samples per chunk of streamed work (memory use is proportional to this, not to the
    /// record length). Each chunk is one round of parallel work in tasks of about a
    /// thousand samples: on a machine with many cores a longer chunk gives every thread
    /// several tasks per round. Results do not depend on it beyond rounding from 8192
    /// samples up (test `chunks_of_8192_samples_and_more_give_the_same_identification`).
    pub chunk_len: usize,
    /// Singular values below `rcond · σ_max` count as rank loss.
    pub rcond: f64,
    /// Inter-sample model of the filter input (first-order hold; zero-order for comparison).
    pub hold: Hold,
    /// De-bias the moments of nonlinear static terms in signals whose estimated measurement
    /// noise is significant (see [`noise`]). The noise is estimated and reported either way.
    pub noise_correction: bool,
    /// Drive filter chains by the model's nonlinear static columns as well (`sign(v)`,
    /// `s³`, …): their states are instruments that carry each column's own information
    /// (see [`plan::RootDriver`]). Off (the default): chains of positions and inputs
    /// only. What it gains and costs is measured in docs/method.md §2.
    pub column_chains: bool,
    /// Keep the rests in the moments. By default the intervals where a body with a
    /// `sign` of its own velocity stands still are left out (see [`super::rests`]): at rest
    /// its friction force is anywhere in `±r` and the model does not hold.
    pub keep_rests: bool,
    /// Run even when the estimated memory ([`memory::estimate`]) is above
    /// [`crate::limits::MAX_BYTES`]; refused before any sample is read otherwise.
    pub allow_large: bool,
    /// Solve a second time with every level's rows whitened by their estimated covariance
    /// (two-step weighting of the moment rows, docs/method.md §5; the CLI's
    /// `--weighted-rows`). Off (the default): on the servo axis it lowers the RMS errors of
    /// mass, damping, friction and offset with `column_chains` but its standard errors come
    /// out 1.7–2.7 times too small (bench `servo_precision`). On a
    /// many-body structure measured by noisy accelerometers it removes the shrinkage the
    /// unit-norm rows give (`tests/accel_structure.rs`).
    pub efficient: bool,
    /// With `efficient`: weight each row by its own estimated error alone (the rows'
    /// estimated covariance shrunk fully to its diagonal) instead of by the covariance
    /// shrunk halfway ([`super::stats::SHRINKAGE`]). What `identify` chooses for
    /// accelerations ([`super::identify::accel_rows`]): halfway is more precise on the
    /// five-body structure at 5 % noise but its standard errors come out 2–10 times too
    /// small on the SDOF and two-mass records and at lower noise (docs/method.md §5).
    pub diagonal_weights: bool,
    /// With `efficient`: re-estimate the weighting at each new estimate and solve again
    /// until no parameter moves by more than a thousandth of its first-step standard error
    /// (iterated weighting, docs/method.md §5). What `identify` chooses, with
    /// `diagonal_weights`, for accelerations ([`super::identify::accel_rows`]). Off
    /// (the default): the two-step estimate, weights read once at the unit-norm rows'
    /// estimate. Not with the covariance shrunk halfway: on the servo axis's records
    /// (bench `servo_precision`, rows `chains, 2-step`, measured once iterated) the
    /// standard errors covered the errors less often (mass 75 % → 46 % of the seeds) and on
    /// planned moves at the noise floor the damping and friction errors grew 2.7–2.8-fold;
    /// nor in detection's per-level fits, whose constancy test it made flag more (χ²/dof
    /// 1.8 against 0.91 away from the joint of `detection_over_seeds`, measured once;
    /// docs/detection.md, "Noisy accelerations").
    pub iterate_weights: bool,
    /// Rows of the filtered equation instead of the instrument rows: at one corner, the
    /// equation passed through the bank's low-pass chain `F` is multiplied by each filtered
    /// regressor `F φⱼ` and averaged (the normal equations of regressing the filtered
    /// equation sample by sample, as moments; see [`plan`] and docs/method.md §2). Needs one
    /// corner (given, or designed); the chains of the nonlinear static columns are added.
    pub filtered: bool,
    /// Estimate a delay `τ` of each measured input against its record: the force that acts
    /// is `u(t − τ) ≈ u(t) − τ u̇(t)`, one more unknown per input (named `u.delay`, in
    /// seconds; [`super::input_delay::extend`]), whose column is the input's derivative taken on
    /// the instruments. What it models: a force that reaches the structure later than it
    /// is recorded, and a force that changes between samples in a way the first-order hold
    /// of the filters does not follow (a current loop updated faster than the record, a
    /// sample-and-hold); on the servo bench it removes the damping bias of the filtered
    /// rows (docs/method.md §2, "The input between samples"). With `filtered` the chain has
    /// six sections unless an order is given, and a designed corner is also tried halved and
    /// quartered (`identify`'s corner search, reported in
    /// [`FilterSummary::corners_tried`]).
    pub input_delay: bool,
    /// Let `identify` choose the rows where the options leave them open (none of the
    /// row choices above set, corners, order and drivers not given): on a record of a servo
    /// axis's kind — a `sign` of a velocity (rests looked for), a measured input,
    /// velocities estimated from measured positions, no noise worth a correction in any
    /// term — the rows of the filtered equation with the inputs' delays (`filtered` and
    /// `input_delay`). On the servo bench (`servo_precision`, 48 seeds) they are 50–500
    /// times more precise than the instrument rows on random set points, 2.7–3.7 times on
    /// planned moves (the offset level), and 10–200 times for mass, damping and friction where the
    /// model lacks a Stribeck term ([`super::identify::servo_rows`]). On a record of
    /// measured accelerations, the instrument rows each weighted by its own estimated error
    /// (`efficient` with `diagonal_weights` and `iterate_weights`,
    /// [`super::identify::accel_rows`]): on a five-body structure at 1 % noise its masses
    /// and stiffnesses 0.15 % off instead of 3.3 % (docs/method.md §2, "Rows for
    /// accelerations"). Said in [`FilterSummary::auto_rows`]. Off: the instrument rows
    /// at unit norm unless asked otherwise (the CLI's `--instrument-rows`). On by default.
    pub auto_rows: bool,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            corners: None,
            n_corners: 6,
            order: None,
            drivers: None,
            balance: false,
            n_blocks: None,
            chunk_len: 8192,
            rcond: 1e-10,
            hold: Hold::FirstOrder,
            noise_correction: true,
            column_chains: false,
            keep_rests: false,
            allow_large: false,
            efficient: false,
            diagonal_weights: false,
            iterate_weights: false,
            filtered: false,
            input_delay: false,
            auto_rows: true,
        }
    }
}

impl IdentifyOptions {
    /// The defaults with the instrument rows kept wherever `identify` would choose others
    /// ([`IdentifyOptions::auto_rows`] off; the CLI's `--instrument-rows`).
    pub fn instrument_rows() -> IdentifyOptions {
        IdentifyOptions {
            auto_rows: false,
            ..IdentifyOptions::default()
        }
    }

    /// The options `id` was identified with: these, or the rows `identify` chose
    /// ([`FilterSummary::auto_rows`]: the filtered equation with the inputs' delays, or the
    /// weighted rows). For further identifications of the same records (the corner check, a
    /// refinement).
    pub fn as_identified(&self, id: &Identification) -> IdentifyOptions {
        let chosen = id.filter.auto_rows;
        let filtered = chosen && id.filter.corners_from.filtered;
        IdentifyOptions {
            filtered: self.filtered || filtered,
            input_delay: self.input_delay || filtered,
            efficient: self.efficient || (chosen && id.filter.weighted_rows),
            diagonal_weights: self.diagonal_weights || (chosen && id.filter.weighted_rows),
            iterate_weights: self.iterate_weights || (chosen && id.filter.weighted_rows),
            auto_rows: self.auto_rows && !chosen,
            ..self.clone()
        }
    }
}

/// Errors of identification. Data errors pass through with their file and line.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum IdentifyError {
    #[error(
        "the term `{term}` of the equation of `{equation}` needs `{signal}`, which is not measured"
    )]
    #[diagnostic(
        code(dynid::identify::unmeasured),
        help("measure `{signal}`, or write the term so that it depends only on measured signals (terms linear in a velocity can be moved onto the filters)")
    )]
    UnmeasuredInTerm {
        equation: String,
        term: String,
        signal: String,
    },
    #[error("the filter bank is driven by `{signal}`, which is not measured")]
    #[diagnostic(
        code(dynid::identify::driver),
        help("drive the filters by measured positions and inputs")
    )]
    UnmeasuredDriver { signal: String },
    #[error("the model has no unknown parameters")]
    #[diagnostic(
        code(dynid::identify::no_unknowns),
        help("declare the parameters to identify without a value (e.g. `param k`)")
    )]
    NoUnknowns,
    #[error("no data: identification needs at least one record")]
    #[diagnostic(
        code(dynid::identify::no_data),
        help("pass one data file per excitation level")
    )]
    NoLevels,
    #[error("{origin}: {n} samples span {duration:.3} s, too short for the slowest filter (time constant {} s)", dynid_ir::num::sig(*.tau, 4, false))]
    #[diagnostic(code(dynid::identify::too_short), help("{advice}"))]
    TooShort {
        origin: String,
        n: usize,
        duration: f64,
        tau: f64,
        need: usize,
        /// What to do: the samples needed, and corners that fit this record where any do.
        advice: String,
    },
    #[error("{rows} equations for {cols} unknown parameters")]
    #[diagnostic(
        code(dynid::identify::too_few_rows),
        help("add filter corners or excitation levels")
    )]
    TooFewRows { rows: usize, cols: usize },
    #[error("invalid option: {message}")]
    #[diagnostic(code(dynid::identify::option), help("{help}"))]
    BadOption { message: String, help: String },
    #[error("the levels have different sample intervals: {fast} has Ts = {} s, {slow} has Ts = {} s; the filter corners designed for the faster level (up to {} rad/s) are above the Nyquist frequency π/Ts = {} rad/s of the slower one", dynid_ir::num::sig(*.ts_fast, 4, false), dynid_ir::num::sig(*.ts_slow, 4, false), dynid_ir::num::sig(*.corner, 4, false), dynid_ir::num::sig(std::f64::consts::PI / *.ts_slow, 4, false))]
    #[diagnostic(
        code(dynid::identify::sample_intervals),
        help("resample the levels to one sample interval (e.g. decimate {fast} to Ts = {} s after low-pass filtering), or give `--filter-corners` well below π/Ts of the slowest level", dynid_ir::num::sig(*.ts_slow, 4, false))
    )]
    MixedSampleIntervals {
        fast: String,
        ts_fast: f64,
        slow: String,
        ts_slow: f64,
        corner: f64,
    },
    #[error(
        "the model `{model}` has no measured input whose delay could be estimated (--input-delay)"
    )]
    #[diagnostic(
        code(dynid::identify::no_input_to_delay),
        help("a delay is estimated for the forces declared by `input u on BODY` and listed in `measure`; drop --input-delay for this model")
    )]
    NoInputToDelay { model: String },
    #[error(
        "{origin}: every measured signal is constant ({columns}): the level carries no excitation"
    )]
    #[diagnostic(
        code(dynid::data::no_excitation),
        help("check that this is the right file; a level without motion adds nothing to the fit — leave it out")
    )]
    NoExcitation { origin: String, columns: String },
    #[error("{origin}: {at}, column `{column}`: {detail}")]
    #[diagnostic(
        code(dynid::data::outlier),
        help("a sample this far out is a recording error (a glitch, a lost digit, a saturated channel): repair or remove it, or cut the record there — one such sample ruins every moment of the level")
    )]
    Outlier {
        origin: String,
        /// Where: the sample and its time.
        at: String,
        /// The sample's index in the level (from 0; `at` counts from 1).
        sample: usize,
        column: String,
        /// The value and how far out it lies.
        detail: String,
    },
    #[error("{origin}: the term `{term}` is {value} at {at}: it is not finite on the data")]
    #[diagnostic(code(dynid::identify::non_finite_term), help("{advice}"))]
    NonFiniteTerm {
        origin: String,
        term: String,
        at: String,
        value: f64,
        advice: String,
    },
    #[error("{origin}: the moments of `{term}` overflow double precision (the values on the data are too large)")]
    #[diagnostic(
        code(dynid::identify::overflow),
        help("rescale the data (e.g. millimetres → metres) or the term so that its values stay far below 1e150")
    )]
    Overflow { origin: String, term: String },
    #[error("{origin}: the values of column `{column}` are so small (about {size:.1e}) that their products underflow double precision")]
    #[diagnostic(
        code(dynid::identify::underflow),
        help("rescale the data (e.g. metres → micrometres) so that every column's values stay far above 1e-150")
    )]
    Underflow {
        origin: String,
        column: String,
        size: f64,
    },
    #[error("{what} would take {estimate}, above the limit of {limit}: {drivers}")]
    #[diagnostic(
        code(dynid::identify::too_large),
        help("the memory grows with the measured signals times the filter states (drivers × corners × sections) and with the rows times the unknowns: give the model a `filter corners [...]` line with fewer corners (or `--filter-corners` with fewer values), measure fewer signals (or drive the filters by fewer: `filter corners [...] driven by u`), or give `--allow-large` to run it anyway")
    )]
    TooLarge {
        what: String,
        estimate: String,
        limit: String,
        drivers: String,
    },
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
}

/// An identified parameter.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ParamEstimate {
    pub name: String,
    pub value: f64,
    /// Batch-means sandwich standard error (see the module doc).
    pub stderr: f64,
    /// `|value| > SIGNIFICANCE_T · stderr`. An insignificant estimate stays in the fit: the
    /// data do not show the term, but its column was not dropped and the others were not
    /// refitted without it.
    pub significant: bool,
}

/// A parameter the data cannot determine (a zero column, or collinear with others); no
/// value is reported for it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Unidentifiable {
    pub name: String,
    pub reason: String,
}

/// Relative residual `‖W (C p − c)‖ / ‖W c‖` over the rows of one equation, per level
/// (against the norm of its largest term where the equation has no known term, `c = 0`:
/// a body without an input and of unknown mass).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EquationResidual {
    pub equation: String,
    pub per_level: Vec<f64>,
    /// Per level, what the noise of the data alone would leave in the same measure: the
    /// square root of the summed variances of the equation's residual rows, estimated
    /// from the hat windows at the estimate (§6 of docs/method.md), over the same
    /// denominator. A residual near it is noise; well above it, a misfit. Empty where the
    /// windows were not formed (a failed solve).
    pub noise: Vec<f64>,
}

/// What was seen of one level.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct LevelInfo {
    pub origin: String,
    pub samples: usize,
    pub ts: f64,
    /// Standard deviation per measured signal.
    pub std: BTreeMap<String, f64>,
    /// Mean per measured signal.
    pub mean: BTreeMap<String, f64>,
    /// Estimated white measurement-noise standard deviation per measured signal.
    pub noise: BTreeMap<String, f64>,
    /// Time blocks of the standard errors over this level (those that count: rests left
    /// out are not among them).
    pub blocks: usize,
    /// Rests left out of this level's moments (`None`: the model has no `sign` of a
    /// velocity, or rests were kept on request).
    pub rests: Option<RestSummary>,
}

/// How the filter corners were chosen.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct CornerSource {
    /// Given by the caller (option or the model's filter block): nothing below applies
    /// to them but the information bandwidth, which is reported all the same.
    pub given: bool,
    /// What set the lowest designed corner.
    pub lower: Option<LowerBy>,
    /// What set the highest designed corner.
    pub upper: Option<UpperBy>,
    /// The measured driver with the narrowest band above its noise floor, and that band's
    /// upper edge in rad/s ([`super::first_pass::floor::BandFloor::info_bandwidth`]).
    pub info_signal: Option<String>,
    pub info_bandwidth: Option<f64>,
    /// The one corner of the filtered equation's rows ([`IdentifyOptions::filtered`]),
    /// designed as the information bandwidth, at most `0.5 / Tₛ` (`0.25 / Tₛ` with the
    /// inputs' delays, [`IdentifyOptions::input_delay`], on a chain given fewer than six
    /// sections).
    #[serde(default)]
    pub filtered: bool,
}

impl FilterSummary {
    /// How the weighted rows' estimate was reached, for reports: the weighting re-estimated
    /// at each new estimate until it settled, or the two-step estimate where it did not
    /// (`identify` iterates unless [`IdentifyOptions::iterate_weights`] is off).
    pub fn describe_weighting(&self) -> String {
        if self.weights_settled {
            format!(
                "weights re-estimated at each new estimate until it settled: {} solves",
                self.weight_steps
            )
        } else if self.weights_collapsed {
            "two-step: weights read once, at the unit-norm rows' estimate; re-estimated, \
             they drove a parameter to zero, as where the model lacks a force the data show"
                .into()
        } else {
            "two-step: weights read once, at the unit-norm rows' estimate".into()
        }
    }

    /// One line for the report: how the corners were chosen
    /// ([`CornerSource::describe`]) and, after a search, the corners tried.
    pub fn describe_corners(&self) -> String {
        let rule = self.corners_from.describe();
        if self.corners_tried.len() < 2 {
            return rule;
        }
        let tried: Vec<String> = self
            .corners_tried
            .iter()
            .map(|t| {
                format!(
                    "{} rad/s ×{:.2}",
                    dynid_ir::num::sig(t.corner, 3, false),
                    t.se_ratio
                )
            })
            .collect();
        format!(
            "{rule}; tried {} (the geometric mean of the standard errors against the kept \
             corner's; a lower corner is kept where they are {}× smaller and its estimates \
             lie within {} standard errors of the designed corner's)",
            tried.join(", "),
            super::identify::FILTERED_CORNER_GAIN,
            super::identify::FILTERED_CORNER_AGREE
        )
    }
}

/// One corner of the filtered equation's search ([`FilterSummary::corners_tried`]).
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct CornerTry {
    /// rad/s.
    pub corner: f64,
    /// The geometric mean of the parameters' standard errors at this corner against that
    /// at the kept one, from the determinant of their covariance:
    /// `(det Σ / det Σ_kept)^(1/2p)` (1 at the kept corner; a lower corner is kept only
    /// where it is at most 1/[`super::identify::FILTERED_CORNER_GAIN`] of the designed
    /// one's).
    pub se_ratio: f64,
}

impl CornerSource {
    /// One line for the report, e.g. "the record length (lowest) and the dominant
    /// frequencies (highest); m.x is above its noise floor up to 628 rad/s".
    pub fn describe(&self) -> String {
        let band = match (&self.info_signal, self.info_bandwidth) {
            (Some(s), Some(w)) => Some(format!(
                "{s} is above its noise floor up to {} rad/s",
                dynid_ir::num::sig(w, 3, false)
            )),
            _ => None,
        };
        if self.given {
            return match band {
                Some(b) => format!("given ({b})"),
                None => "given".into(),
            };
        }
        if self.filtered {
            let rule = format!(
                "one corner for the filtered equation, at most {}/Ts ({}/Ts with --input-delay \
                 on a chain given fewer than {} sections)",
                super::filtered::FILTERED_MAX_LT,
                super::filtered::FILTERED_DELAY_MAX_LT,
                super::filtered::FILTERED_DELAY_ORDER
            );
            return match band {
                Some(b) => format!("{rule}: {b}"),
                None => rule,
            };
        }
        let lower = match self.lower {
            Some(LowerBy::RecordLength) => "the record length (lowest)",
            Some(LowerBy::Spectrum) | None => "the dominant frequencies (lowest)",
        };
        let upper = match self.upper {
            Some(UpperBy::Nyquist) => "a tenth of the Nyquist frequency (highest)",
            Some(UpperBy::Spectrum) | None => "the dominant frequencies (highest)",
        };
        match band {
            Some(b) => format!("{lower} and {upper}; {b}"),
            None => format!("{lower} and {upper}"),
        }
    }
}

/// The filter bank that was used.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FilterSummary {
    pub corners: Vec<f64>,
    /// How they were chosen.
    pub corners_from: CornerSource,
    /// The filtered equation's designed corner and those below it that were tried, each
    /// with its standard errors' size against the kept one's (empty: no search; see
    /// [`super::identify::FILTERED_CORNER_STEPS`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub corners_tried: Vec<CornerTry>,
    /// The rows were chosen by `identify` ([`IdentifyOptions::auto_rows`]), not asked for:
    /// those of the filtered equation with the inputs' delays for a record of a servo
    /// axis's kind ([`super::identify::servo_rows`]; `corners_from.filtered` set), the
    /// instrument rows weighted by their estimated covariance for measured accelerations
    /// ([`super::identify::accel_rows`]; `weighted_rows` set).
    pub auto_rows: bool,
    /// The rows were weighted by their estimated covariance (the efficient two-step solve,
    /// [`IdentifyOptions::efficient`]); false where it was not asked for or could not be
    /// formed (the unit-norm rows' solve is kept then).
    #[serde(default)]
    pub weighted_rows: bool,
    /// Solves of the weighted rows behind the estimate: 1 for the two-step estimate, more
    /// where the weighting was re-estimated at each new estimate until it settled
    /// (`weights_settled`); 0 where the rows were not weighted.
    #[serde(default)]
    pub weight_steps: usize,
    /// The iterated weighting settled (no parameter moved by more than a thousandth of its
    /// first-step standard error); false where it did not (the two-step estimate is kept),
    /// where it was not iterated ([`IdentifyOptions::iterate_weights`] off) or the rows were
    /// not weighted.
    #[serde(default)]
    pub weights_settled: bool,
    /// The iterated weighting stopped where an estimate collapsed onto the trivial solution
    /// of an equation without a known term (a body's mass the unit-norm rows found
    /// significant lost more than nine tenths of its magnitude: a model that lacks a force
    /// the data show); the two-step estimate is kept.
    #[serde(default)]
    pub weights_collapsed: bool,
    /// Parameters whose estimates move by more than their standard errors when the highest
    /// corner is moved a factor 4 down or up ([`super::corner_moves`]; filled in by the
    /// command line, empty otherwise).
    pub corner_moves: Vec<CornerMove>,
    pub order: usize,
    pub drivers: Vec<String>,
    /// Nonlinear static columns that drive chains of their own (filtered regressors as
    /// instruments); a column with an estimated velocity drives its chains a velocity
    /// window late.
    pub column_drivers: Vec<String>,
    /// Relative degrees of the states used as instruments.
    pub instrument_degrees: Vec<usize>,
    pub balance_rows: bool,
}

/// Result of an identification.
#[derive(Clone, Debug, Serialize)]
pub struct Identification {
    pub params: Vec<ParamEstimate>,
    /// The covariance of the estimates `params` (row-major, `params.len()²` entries; the
    /// batch-means sandwich with `stderr²` on its diagonal, see [`super::stats`]); read it
    /// by [`Identification::covariance`].
    #[serde(skip)]
    pub covariance: Vec<f64>,
    pub unidentifiable: Vec<Unidentifiable>,
    /// Estimates that are unphysical for their kind of term (negative mass, damping,
    /// friction coefficient or stiffness).
    pub warnings: Vec<Warning>,
    /// Residuals the model cannot explain (a large relative residual, a pooled estimate
    /// outside every level's), each with its likely cause (see [`guard`]).
    pub fit_warnings: Vec<FitWarning>,
    /// Condition number of the row-normalised, column-scaled matrix.
    pub condition: f64,
    pub residual: Vec<EquationResidual>,
    pub levels: Vec<LevelInfo>,
    pub filter: FilterSummary,
    /// Unmeasured velocities estimated from measured positions for nonlinear terms.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub estimated: Vec<VelocityEstimate>,
    /// Rows of the stacked system.
    pub rows: usize,
    /// Estimated measurement noise and the terms de-biased for it.
    pub noise: NoiseSummary,
    /// Shape parameters (unknown gaps and limits), profiled; the estimates above are
    /// those at the profile's minimum.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub shapes: Vec<ShapeEstimate>,
    /// Sum of squares of the weighted (unit-norm) rows' residuals: what a profile over
    /// shape parameters minimises.
    #[serde(skip)]
    pub ssr: f64,
    #[serde(skip)]
    pub times: PhaseTimes,
}

/// A shape parameter estimated by profiling the least squares over it.
#[derive(Clone, Debug, Serialize)]
pub struct ShapeEstimate {
    pub name: String,
    pub value: f64,
    /// From the curvature of the residual profile at its minimum (classical least-squares
    /// scaling); `None` when the profile is flat or the minimum lies on the search edge.
    pub stderr: Option<f64>,
    /// `(value, weighted residual sum of squares)` of every trial, in search order.
    #[serde(skip)]
    pub profile: Vec<(f64, f64)>,
    /// `∂p̂/∂g` of every linear estimate along the profile (in `params` order).
    #[serde(skip)]
    pub slopes: Vec<f64>,
    /// The value profiled with each level left out in turn (level order); empty when the
    /// jackknife did not run (fewer than three levels) or one of its profiles failed.
    #[serde(skip)]
    pub leave_out: Vec<f64>,
}

impl Identification {
    /// Whether this identification leaves no more parameters unidentified than `other`
    /// (the same model, other rows or corners: a comparison of like with like).
    pub(crate) fn identifies_as_much_as(&self, other: &Identification) -> bool {
        self.unidentifiable.len() <= other.unidentifiable.len()
    }

    pub fn param(&self, name: &str) -> Option<&ParamEstimate> {
        self.params.iter().find(|p| p.name == name)
    }

    /// The covariance of the estimates of `params[i]` and `params[j]`.
    pub fn covariance(&self, i: usize, j: usize) -> f64 {
        self.covariance[i * self.params.len() + j]
    }

    /// Add the spread `var · d dᵀ` of a profiled shape parameter to the estimates' (delta
    /// method: `d` the estimates' slopes along the profile, in `params` order, non-finite
    /// ones counting as zero), standard errors and covariance alike.
    pub(crate) fn widen(&mut self, slopes: &[f64], var: f64) {
        let n = self.params.len();
        let d = |j: usize| {
            slopes
                .get(j)
                .copied()
                .filter(|d| d.is_finite())
                .unwrap_or(0.0)
        };
        if self.covariance.len() == n * n {
            for i in 0..n * n {
                self.covariance[i] += d(i / n) * d(i % n) * var;
            }
        }
        for (j, p) in self.params.iter_mut().enumerate() {
            p.stderr = (p.stderr * p.stderr + d(j) * d(j) * var).sqrt();
            p.significant = p.value.abs() > SIGNIFICANCE_T * p.stderr;
        }
    }
}

/// The assembled system `C p = c` (before weighting), for parity checks between evaluators.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearSystem {
    /// Row-major `rows × cols`; columns are `ir.unknowns()` in order.
    pub c_matrix: Vec<f64>,
    pub rhs: Vec<f64>,
    pub rows: usize,
    pub cols: usize,
    /// `level i: instrument → equation` per row.
    pub row_labels: Vec<String>,
}

/// What a parameter is physically, where the IR says so.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Quantity {
    Mass,
    Damping,
    Friction,
    Stiffness,
}

impl std::fmt::Display for Quantity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Quantity::Mass => "mass",
            Quantity::Damping => "damping coefficient",
            Quantity::Friction => "friction coefficient",
            Quantity::Stiffness => "spring stiffness",
        })
    }
}

/// A negative estimate of a quantity that must be non-negative.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Warning {
    pub param: String,
    pub quantity: Quantity,
    /// The coefficient as it enters the equation (`scale · value`) and its standard error.
    pub coefficient: f64,
    pub stderr: f64,
    /// More than [`super::SIGNIFICANCE_T`] standard errors below zero: the fit contradicts physics
    /// (else the estimate is consistent with zero).
    pub unphysical: bool,
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// What the guard saw.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FitCheck {
    /// An equation's relative residual above [`super::guard::RESIDUAL_WARN`] at every level.
    LargeResidual,
    /// A pooled estimate outside every level's own.
    LevelsDisagree,
    /// Two levels with the same record.
    DuplicateLevel,
}

/// The likely cause the guard names.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum LikelyCause {
    /// A constant force explains the residual: a position sensor's zero offset, or an
    /// unmodelled constant force.
    SensorOffset,
    /// A constant force explains the residual, and no force of the model depends on a
    /// position (so a sensor's zero offset enters no equation): an unmodelled constant
    /// force (gravity on an inclined axis, a cable, an amplifier's bias).
    ConstantForce,
    /// A body or an element that the data show is not in the model.
    MissingBody,
    /// The equation's mass is fixed in the model (not identified) and likely wrong, or a
    /// body or element is missing.
    WrongMass,
    /// The levels do not share one set of parameters (a level from another set-up, other
    /// units, or an effect that changes with the amplitude).
    LevelsInconsistent,
    /// One record given as two levels: it counts twice, and the standard errors come out
    /// √2 too small.
    SameRecordTwice,
}

/// A residual the model cannot explain, with its likely cause and what to do.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FitWarning {
    pub check: FitCheck,
    pub cause: LikelyCause,
    /// The equation (body) or parameter concerned.
    pub subject: String,
    /// The largest relative residual of the equation over the levels, or, for levels that
    /// disagree, the pooled estimate's distance from the nearest level's in that level's
    /// standard errors.
    pub value: f64,
    pub message: String,
}

impl std::fmt::Display for FitWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// One parameter's estimates with the highest filter corner a factor
/// [`super::CORNER_CHECK_FACTOR`] below and above the one used (the lowest corner kept: the
/// record length or the dominant frequencies bound it), see [`super::corner_moves`].
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CornerMove {
    pub param: String,
    /// The estimate with the highest corner lowered, as used, raised.
    pub values: [f64; 3],
    /// Their standard errors.
    pub stderrs: [f64; 3],
    /// The highest corner of each (rad/s).
    pub upper: [f64; 3],
    /// The smallest move that counts ([`CornerMove::moved`]):
    /// [`super::CORNER_CHECK_MIN_REL`] of the value, or for an input's delay (whose value
    /// may be near zero) of the sample interval.
    #[serde(skip)]
    pub min_move: f64,
}
