//! What the diagnosis returns and how it is configured: options, errors and result types.

use super::effects::{Effect, Location};
use crate::data::DataError;
use crate::ident::{IdentifyError, IdentifyOptions};
use crate::sim::{SimError, DEFAULT_SUBSTEPS};
use serde::Serialize;

/// Errors of the diagnosis.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum DiagnoseError {
    #[error("diagnosis needs at least 2 excitation levels, got {0}")]
    #[diagnostic(
        code(dynid::diagnose::levels),
        help("pass one data file per excitation level; the gap is scored on a level withheld from fitting")
    )]
    TooFewLevels(usize),
    #[error("the model has no nominal value for `{0}`, so it cannot be simulated")]
    #[diagnostic(
        code(dynid::diagnose::nominal),
        help("give every unknown parameter a nominal value (`k ~ 4.0`)")
    )]
    MissingNominal(String),
    #[error("the model measures no position or velocity, so there is no response to compare")]
    #[diagnostic(
        code(dynid::diagnose::no_response),
        help("measure at least one body signal")
    )]
    NoResponse,
    #[error("no measured response signal varies on any level, so there is no gap to measure")]
    #[diagnostic(
        code(dynid::diagnose::no_variance),
        help("check that the levels are excited: every position and velocity column is constant after the first 10 % of each record")
    )]
    NoVariance,
    #[error(transparent)]
    #[diagnostic(transparent)]
    Identify(#[from] IdentifyError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Sim(#[from] SimError),
}

/// Choices of the diagnosis; `Default` gives the documented settings.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    pub ident: IdentifyOptions,
    /// Fraction of each record discarded before comparing responses (the transient from rest).
    pub discard: f64,
    /// RK4 sub-steps per sample in the free-run simulations.
    pub substeps: usize,
    /// How many candidates (best covariance score first) get the free-run score.
    pub top_k: usize,
    /// Most effects added one after the other.
    pub max_effects: usize,
    /// A coefficient counts as significant when |p| > `t_min` · stderr.
    pub t_min: f64,
    /// Required shrink of the withheld gap: relative and absolute (percentage points).
    pub min_rel_shrink: f64,
    pub min_abs_shrink: f64,
    /// Measure the moments of all candidates of a search step in one pass over the data
    /// (one model holding every candidate term) and solve each candidate from its columns;
    /// `false` measures every candidate on its own (one pass each: the reference the shared
    /// pass is tested against). The shared pass falls back to one pass per candidate when
    /// the model with every candidate cannot be measured (e.g. more columns than rows).
    pub shared_pass: bool,
    /// Profile the gap of an accepted backlash over the covariance least squares (its
    /// standard error included); `false` keeps the search's grid value (for comparison).
    pub profile_shapes: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            // 20 time blocks, not chosen from the record: a structure search holds every
            // candidate's hat-window rows (memory in proportion to the blocks), and its
            // pruning and verdicts were measured with 20. Their standard errors run up to
            // about a fifth low on long records (see `ident::design::blocks`).
            ident: IdentifyOptions {
                n_blocks: Some(20),
                ..IdentifyOptions::default()
            },
            discard: 0.1,
            substeps: DEFAULT_SUBSTEPS,
            top_k: 6,
            max_effects: 2,
            t_min: 4.0,
            min_rel_shrink: 0.2,
            min_abs_shrink: 1.0,
            shared_pass: true,
            profile_shapes: true,
        }
    }
}

/// Response gap of one signal on one level. A signal whose measured response has no
/// variance on the level has no gap (the metrics divide by its spread): it is not listed.
#[derive(Clone, Debug, Serialize)]
pub struct SignalGap {
    pub signal: String,
    /// Free-run NRMSE in % (pathwise).
    pub nrmse: f64,
    /// (std(sim) − std(meas)) / std(meas) in %.
    pub std_error: f64,
    /// Mean |log10| PSD ratio over the band holding 99 % of the measured power.
    pub psd_gap: f64,
    /// The PSD gap as an amplitude error: `100 · (10^(psd_gap/2) − 1)`, in %.
    pub spectral: f64,
    /// Statistical gap of the signal: `(spectral + |std_error|) / 2`, in %.
    pub statistical: f64,
    /// The signal's unit (models are written in SI units): `m` for a position, `m/s` for
    /// a velocity, `N` for an input force.
    pub unit: String,
    /// Free-run RMS error (simulated − measured) in the signal's unit: the pathwise gap
    /// before it is divided by the measured std.
    pub rms_error: f64,
    /// std(sim) − std(meas) in the signal's unit.
    pub std_diff: f64,
}

/// Response gap of a model on one level.
#[derive(Clone, Debug, Serialize)]
pub struct LevelGap {
    pub level: usize,
    pub origin: String,
    /// Statistical gap: mean over response signals of [`SignalGap::statistical`], in %;
    /// infinite if the run diverged, `None` when no response signal varies on this level.
    pub gap: Option<f64>,
    /// Pathwise gap: mean over response signals of the free-run NRMSE, in %; infinite if the
    /// run diverged, `None` as for `gap`.
    pub pathwise: Option<f64>,
    pub signals: Vec<SignalGap>,
    /// The simulation diverged (the model is unstable with these parameters).
    pub diverged: bool,
}

/// A model's gap on the levels it was scored on.
#[derive(Clone, Debug, Serialize)]
pub struct ModelGap {
    pub label: String,
    /// Mean of the per-level statistical gaps in % (the headline number), over the levels
    /// where it is available; infinite if a run diverged.
    pub gap: f64,
    /// Mean of the per-level pathwise gaps (free-run NRMSE) in %, over the same levels.
    pub pathwise: f64,
    pub levels: Vec<LevelGap>,
}

/// Covariance-equation residual of the nominal model, per equation and level.
#[derive(Clone, Debug, Serialize)]
pub struct EquationGap {
    pub equation: String,
    /// Relative RMS of `C p − c` over the (row-normalised) rows of that equation, in %;
    /// `None` on a level where those rows are all zero.
    pub per_level: Vec<Option<f64>>,
}

/// A parameter of the corrected model (the model as given plus every found effect),
/// identified on all levels: what the corrected model's source holds, unrounded.
#[derive(Clone, Debug, Serialize)]
pub struct CorrectedParam {
    pub name: String,
    pub value: f64,
    /// Batch-means sandwich standard error of the pooled fit.
    pub stderr: f64,
    /// The nominal value of the model as given; `None` for a found effect's coefficient
    /// and for a parameter without a nominal.
    pub nominal: Option<f64>,
    /// `model` (a parameter of the model as given) or `found effect`.
    pub kind: &'static str,
}

/// A parameter identified separately at each level.
#[derive(Clone, Debug, Serialize)]
pub struct ParamDrift {
    pub name: String,
    pub nominal: Option<f64>,
    pub pooled: Option<f64>,
    pub per_level: Vec<Option<f64>>,
    pub stderr: Vec<Option<f64>>,
    /// Why a level has no value (`None` where it has one): the parameter is unidentifiable
    /// on that level alone (its term never acts there, or collinear with others).
    pub missing: Vec<Option<String>>,
    /// (max − min) / |mean| of the per-level values, in %.
    pub drift: f64,
    /// Whether the spread exceeds 4 combined standard errors.
    pub significant: bool,
}

/// One candidate of the search.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateScore {
    pub effect: Effect,
    pub location: Location,
    /// The coefficient identified on all levels, its standard error and t-ratio.
    pub value: f64,
    pub stderr: f64,
    pub t_ratio: f64,
    pub sign_ok: bool,
    /// Cross-validated covariance residual on the withheld levels, in %.
    pub cv_residual: f64,
    /// Cross-validated statistical gap in % (only for the best few by covariance score).
    pub gap: Option<f64>,
    /// Cross-validated pathwise gap in %, for the same candidates.
    pub pathwise_gap: Option<f64>,
    pub accepted: bool,
    pub note: String,
}

/// A parameter of the model as given: its nominal value and the value identified on all
/// levels.
#[derive(Clone, Debug, Serialize)]
pub struct MovedParam {
    pub name: String,
    pub nominal: f64,
    pub identified: f64,
    /// (identified − nominal) / |nominal| in %; `None` for a nominal value of 0.
    pub change: Option<f64>,
}

/// An effect the diagnosis adds to the model.
#[derive(Clone, Debug, Serialize)]
pub struct FoundEffect {
    pub effect: Effect,
    pub location: Location,
    pub element: String,
    pub param: String,
    pub value: f64,
    pub stderr: f64,
    /// The unit of `value` where it is a force (`"N"` for a constant force).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<&'static str>,
    /// A backlash's gap is profiled once the backlash is accepted (the value is in
    /// `effect`): its standard error, `None` when the profile is flat at its minimum.
    pub shape_stderr: Option<f64>,
    /// Withheld statistical gap before and after adding this effect (in %).
    pub gap_before: f64,
    pub gap_after: f64,
    /// Withheld pathwise gap (free-run NRMSE) before and after adding this effect (in %).
    pub pathwise_gap_before: f64,
    pub pathwise_gap_after: f64,
}

/// What kind of gap the data shows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// An effect of the library explains the gap.
    MissingEffect,
    /// Re-identifying the model's own parameters removes most of the gap.
    MistunedParameters,
    /// The model matches the data (small gap, nothing significant to add).
    Consistent,
    /// A gap remains that no library effect removes.
    Unexplained,
}

/// A force-channel gap of one model: the mean over the levels of the RMS equation residual
/// (in N) and of that as % of the recorded force's std.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ForceGapValue {
    pub rms: f64,
    pub percent: f64,
}

/// The force channel of a recorded force that drives an open-loop model: the equation
/// residual of the body it acts on (the force the model needs for the measured motion
/// minus the recorded force), low-passed below `band_hz`, on the motion (rests and the
/// filter's edges left out). See `runtime/src/diagnose/force.rs`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ForceGap {
    /// The recorded force (the model's input).
    pub input: String,
    /// The body it acts on (whose equation is scored).
    pub equation: String,
    /// Unit of the RMS values: "N".
    pub unit: String,
    /// The zero-phase low-pass corner, Hz (of the first level).
    pub band_hz: f64,
    /// The nominal model on every level.
    pub nominal: Option<ForceGapValue>,
    /// The model as given re-identified without each level, on that level.
    pub reidentified: Option<ForceGapValue>,
    /// The corrected model likewise (absent when nothing was found).
    pub corrected: Option<ForceGapValue>,
}

/// The result of [`diagnose`].
#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    pub model: String,
    pub levels: Vec<String>,
    pub response_signals: Vec<String>,
    pub verdict: Verdict,
    /// Headline (statistical) gaps in %: the nominal model (all levels), the model as given
    /// re-identified (withheld levels), and the corrected model (withheld levels; the
    /// re-identified one when nothing was found). Never capped: a worse model says so.
    pub gap_before: f64,
    pub gap_reidentified: f64,
    pub gap_after: f64,
    /// Overall: 1 − gap_after / gap_before (nominal → corrected); negative when worse;
    /// `None` when a gap is infinite (a run diverged) or the nominal gap is 0.
    pub shrink: Option<f64>,
    /// What the effect(s) add: 1 − gap_after / gap_reidentified; 0 when nothing was found,
    /// `None` as for `shrink`.
    pub effect_shrink: Option<f64>,
    /// The same three gaps, pathwise (free-run NRMSE), in %.
    pub pathwise_gap_before: f64,
    pub pathwise_gap_reidentified: f64,
    pub pathwise_gap_after: f64,
    pub nominal: ModelGap,
    /// The model as given, re-identified on the training levels, scored on the withheld one.
    pub reidentified: ModelGap,
    /// The corrected model, cross-validated likewise (same as `reidentified` if nothing found).
    pub corrected: ModelGap,
    pub equations: Vec<EquationGap>,
    /// The force channel of every recorded force that drives the model (open loop): the
    /// equation residual in N beside the free-run gaps. Empty for a closed-loop model (its
    /// force is a response, scored among the signals) or where a body's position is not
    /// measured.
    pub force_gaps: Vec<ForceGap>,
    pub drift: Vec<ParamDrift>,
    /// Parameters of the model as given: nominal → re-identified on all levels *without*
    /// any found effect (what re-identification alone does; biased where an effect is
    /// missing). The corrected model's values are [`Diagnosis::parameters`].
    pub moved: Vec<MovedParam>,
    /// The corrected model's parameters, identified on all levels with every found effect
    /// (the model as given re-identified when nothing was found).
    pub parameters: Vec<CorrectedParam>,
    pub found: Vec<FoundEffect>,
    /// Candidates of the first search step, best first.
    pub ranking: Vec<CandidateScore>,
    /// Candidates of the last search step, the one that added nothing (on top of the found
    /// effects), best first; empty when the first step found nothing or the search stopped at
    /// `max_effects`. What else the data hints at, below the acceptance threshold.
    pub residual_ranking: Vec<CandidateScore>,
    pub notes: Vec<String>,
    /// The corrected model's source (identified values as nominals).
    pub fixed_source: String,
    /// Spectra for the report (not serialised).
    #[serde(skip)]
    pub spectra: Vec<Spectrum>,
    /// Free runs for the report, on the level of [`Diagnosis::spectra`] (not serialised).
    #[serde(skip)]
    pub traces: Vec<Trace>,
}

/// One response signal on one level in time: measured, and the free run of each model
/// (after the discarded start).
#[derive(Clone, Debug)]
pub struct Trace {
    pub signal: String,
    /// The signal's unit (see [`SignalGap::unit`]).
    pub unit: String,
    pub level: usize,
    /// Time of the first sample and the sample interval (s).
    pub t0: f64,
    pub ts: f64,
    pub measured: Vec<f64>,
    pub models: Vec<(String, Vec<f64>)>,
}

/// Power spectra of one response signal on one level: measured and per model.
#[derive(Clone, Debug)]
pub struct Spectrum {
    pub signal: String,
    pub level: usize,
    pub freqs: Vec<f64>,
    pub measured: Vec<f64>,
    pub models: Vec<(String, Vec<f64>)>,
}
