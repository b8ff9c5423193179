//! The data of detection: what it takes (curves, intensities, options), what it returns
//! (the constancy test of every curve, the template fits and the verdict of every element)
//! and its errors. All of it is plain data that round-trips through JSON.

use super::candidate::Distribution;
use super::format::{fmt_g, fmt_pm};
use crate::data::DataError;
use crate::ident::IdentifyError;
use serde::{Deserialize, Serialize};

/// Non-finite numbers (an undetermined standard error, the AICc of a saturated fit) are
/// written to JSON as `null` and read back as NaN, since JSON has no NaN or ∞.
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        if x.is_finite() {
            s.serialize_f64(*x)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// What a linear parameter stands for; only stiffness and damping curves get templates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Role {
    Stiffness,
    Damping,
    Mass,
    Other,
}

/// One linear parameter's estimates over the excitation levels (index = level).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamCurve {
    /// Parameter name, e.g. `k1`.
    pub param: String,
    /// The element the parameter belongs to; must match an [`ElementIntensity`] for
    /// stiffness and damping curves.
    pub element: String,
    pub role: Role,
    pub values: Vec<f64>,
    /// Standard errors (e.g. batch means over time blocks), same length, all > 0.
    pub stderrs: Vec<f64>,
}

/// The measured intensities of one element at every level (index = level): standard
/// deviations of its relative displacement s and relative velocity v.
///
/// Templates act jointly on an element's stiffness and damping curve, so put the spring
/// and the damper that connect the same two nodes under one element name: a Coulomb
/// friction hiding there shows on the damper's curve, a prestress on the spring's.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ElementIntensity {
    pub element: String,
    pub sigma_s: Vec<f64>,
    pub sigma_v: Vec<f64>,
    /// Measured distributions of s and v per level (empty: not measured, the Gaussian
    /// forms are used). Not written to JSON: they are histograms of the data.
    #[serde(default, skip_serializing)]
    pub s_dist: Vec<Distribution>,
    #[serde(default, skip_serializing)]
    pub v_dist: Vec<Distribution>,
}

/// Everything detection needs from the per-level identification.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DetectionInput {
    /// Optional labels of the levels (for tables); empty = `1, 2, …`.
    pub level_labels: Vec<String>,
    pub elements: Vec<ElementIntensity>,
    pub curves: Vec<ParamCurve>,
    /// Parameters held at one value at every level (no curve), e.g. an unknown mass at
    /// the weighted mean of its free per-level estimates.
    #[serde(default)]
    pub held: Vec<HeldParam>,
}

/// A parameter held fixed over the levels, with the estimate it was held at.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldParam {
    pub param: String,
    pub value: f64,
    #[serde(with = "nan_as_null")]
    pub stderr: f64,
}

/// Thresholds of the tests. The defaults are what the false-positive measurement in the
/// tests was made with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DetectOptions {
    /// Significance of the constancy test. 1e-3: a report lists many parameters, and a
    /// false "nonlinear" costs the user a wrong model, so the test must be strict.
    pub alpha: f64,
    /// A curve drifts only if also (max − min)/|mean| exceeds this. On long records the
    /// standard errors get so small that the ~1 % bias of any linear fit to a real rig
    /// would be "significant"; 2 % is below what the templates are needed for.
    pub min_rel_change: f64,
    /// Degrees of freedom of the standard errors (batch means over B blocks: B − 1).
    /// When set, the constancy statistic χ²/(L−1) is referred to F(L−1, ν) instead of
    /// χ²_(L−1)/(L−1): a batch-means variance from 10 blocks is itself uncertain by ~±45 %,
    /// and treating it as exact inflates false alarms several-fold. F with the dof of one
    /// level is conservative when the levels' errors are estimated independently.
    pub se_dof: Option<f64>,
    /// Each standard error is raised to at least this fraction of the curve's median
    /// standard error, so that one level whose error was underestimated by chance cannot
    /// dominate the weights.
    pub se_floor_rel: f64,
    /// Templates within this ΔAICc of the best (after dropping supersets of simpler
    /// members) make the verdict ambiguous.
    pub ambiguity_delta: f64,
    /// A drifting element whose best template explains less than this fraction of the
    /// drift (1 − χ²_template/χ²_constant) is reported as unexplained.
    pub min_explained: f64,
    /// An inverse pair whose coefficients correlate above this cannot be separated: the
    /// verdict is ambiguous between its two effects.
    pub max_pair_corr: f64,
    /// Also try the built-in effects ([`Candidate::builtins`]).
    pub builtins: bool,
    /// [`detect_from_data`]: hold unknown masses at one value (the weighted mean of their
    /// free per-level estimates) in the
    /// per-level fits instead of fitting them freely at each level.
    #[serde(default = "yes")]
    pub hold_inertia: bool,
    /// Over which distributions of s and v the templates are linearised.
    #[serde(default)]
    pub linearisation: Linearisation,
    /// [`detect_from_data`]: samples per level of the simulated levels that predict each
    /// candidate's drift for this estimator (`detect::estimator`); 0 turns that off and
    /// leaves the statistical-linearisation verdicts.
    #[serde(default = "sim_samples")]
    pub sim_samples: usize,
}

fn sim_samples() -> usize {
    SIM_SAMPLES
}

/// Default of [`DetectOptions::sim_samples`]: 1000 s at the models' 10 ms.
pub const SIM_SAMPLES: usize = 100_000;

/// The distributions statistical linearisation averages over.
///
/// The per-level fits follow the *measured* distribution of s (a hardening spring makes s
/// light-tailed) but the *Gaussian* form of v: hence the default (measured on simulated data
/// with known truth: docs/performance.md, "Measurements behind defaults").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Linearisation {
    /// Gaussian s and v (the closed forms of the table).
    Gaussian,
    /// The measured distribution of s for effects of s; Gaussian v.
    #[default]
    MeasuredS,
    /// The measured distributions of both s and v (where v is measured).
    Measured,
}

fn yes() -> bool {
    true
}

impl Default for DetectOptions {
    fn default() -> Self {
        Self {
            alpha: 1e-3,
            min_rel_change: 0.02,
            se_dof: None,
            se_floor_rel: 0.25,
            ambiguity_delta: 2.0,
            min_explained: 0.8,
            max_pair_corr: 0.9,
            builtins: true,
            hold_inertia: true,
            linearisation: Linearisation::default(),
            sim_samples: SIM_SAMPLES,
        }
    }
}

/// A fitted quantity with its standard error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub name: String,
    pub value: f64,
    #[serde(with = "nan_as_null")]
    pub stderr: f64,
}

impl std::fmt::Display for Estimate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {}", self.name, fmt_pm(self.value, self.stderr))
    }
}

/// A template's curve sampled along the level path, for plots.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    pub param: String,
    /// σ_s for a stiffness curve, σ_v for a damping curve.
    pub sigma: Vec<f64>,
    pub value: Vec<f64>,
}

/// One template fitted to an element's curves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TemplateFit {
    /// e.g. `cubic stiffness` or `cubic stiffness + Coulomb friction`.
    pub name: String,
    pub effects: Vec<String>,
    /// e.g. `k3·s³`.
    pub formula: String,
    /// Linear parts first (one per curve), then the effect coefficients, then shapes.
    pub estimates: Vec<Estimate>,
    /// How many trailing `estimates` belong to the effects (coefficients and shapes).
    pub n_effect_estimates: usize,
    /// Weighted sum of squared residuals over both curves.
    pub chi2: f64,
    pub dof: usize,
    pub n_params: usize,
    pub n_points: usize,
    #[serde(with = "nan_as_null")]
    pub reduced_chi2: f64,
    /// P(χ²_dof > chi2): goodness of fit, taking the standard errors at face value.
    #[serde(with = "nan_as_null")]
    pub gof_p_value: f64,
    /// Fraction of the drift explained: 1 − χ²/χ²_constant.
    #[serde(with = "nan_as_null")]
    pub explained: f64,
    /// Quasi-AICc: χ²/ĉ + 2K + 2K(K+1)/(N−K−1), ĉ = the element's over-dispersion
    /// ([`ElementFinding::c_hat`]); ∞ for a saturated fit.
    #[serde(with = "nan_as_null")]
    pub aicc: f64,
    /// χ² + K ln N (not over-dispersion corrected).
    #[serde(with = "nan_as_null")]
    pub bic: f64,
    /// aicc − the best aicc of the element.
    #[serde(with = "nan_as_null")]
    pub delta_aicc: f64,
    /// Condition number of the column-scaled, whitened design.
    #[serde(with = "nan_as_null")]
    pub cond: f64,
    /// Largest |correlation| between two effect coefficients (0 for a single effect).
    #[serde(with = "nan_as_null")]
    pub coef_corr: f64,
    /// Two effects on the same curve with opposite trends ("inverse" behaviour).
    pub inverse_pair: bool,
    pub predictions: Vec<Prediction>,
}

impl TemplateFit {
    /// The implied effect parameters, e.g. `k3 = 2.05 ± 0.04`.
    pub fn effect_estimates(&self) -> &[Estimate] {
        &self.estimates[self.estimates.len() - self.n_effect_estimates..]
    }

    /// e.g. `k3 = 2.05 ± 0.04; explains 99.1 % of the drift, χ²/dof = 1.1`.
    pub fn summary(&self) -> String {
        let est: Vec<String> = self
            .effect_estimates()
            .iter()
            .map(|e| e.to_string())
            .collect();
        format!(
            "{}; explains {:.1} % of the drift, χ²/dof = {}",
            est.join(", "),
            100.0 * self.explained,
            fmt_g(self.reduced_chi2)
        )
    }
}

/// What detection concludes about one element.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Verdict {
    /// No curve of the element drifts.
    Linear,
    /// One template stands out.
    Nonlinear { best: String, summary: String },
    /// Several templates explain the drift equally well (ΔAICc below the threshold):
    /// reported rather than guessed.
    Ambiguous { candidates: Vec<String> },
    /// The element drifts but no template explains enough of it.
    Unexplained { best_explained: f64 },
    /// The element drifts, but its curves have too few points for any template to be
    /// ranked (a template needs at least two points more than it has parameters): `levels`
    /// were given, `need` would let the smallest template be ranked.
    TooFewLevels { levels: usize, need: usize },
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Verdict::Linear => write!(f, "linear"),
            Verdict::Nonlinear { best, .. } => write!(f, "nonlinear: {best}"),
            Verdict::Ambiguous { candidates } => {
                write!(f, "ambiguous between {}", candidates.join(" and "))
            }
            Verdict::Unexplained { best_explained } => write!(
                f,
                "drifts, unexplained (best template explains {:.0} %)",
                100.0 * best_explained
            ),
            Verdict::TooFewLevels { levels, need } => write!(
                f,
                "drifts, but {levels} levels are too few to rank any template: \
                 give at least {need} levels"
            ),
        }
    }
}

/// The constancy test of one parameter curve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamCurveResult {
    pub curve: ParamCurve,
    /// The x-axis of the curve: σ_s (stiffness), σ_v (damping), else the level number.
    pub sigma: Vec<f64>,
    /// `σ_s`, `σ_v` or `level`.
    pub sigma_name: String,
    /// The standard errors after the floor ([`DetectOptions::se_floor_rel`]).
    pub stderrs_used: Vec<f64>,
    /// Weighted mean (the constant fit) and its standard error.
    pub mean: f64,
    pub mean_stderr: f64,
    pub chi2: f64,
    pub dof: usize,
    #[serde(with = "nan_as_null")]
    pub p_value: f64,
    /// (max − min)/|mean|.
    #[serde(with = "nan_as_null")]
    pub rel_change: f64,
    pub drifting: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ElementFinding {
    pub element: String,
    pub verdict: Verdict,
    /// The element's curves that drift.
    pub drifting: Vec<String>,
    /// Applicable templates, best first (empty when nothing drifts).
    pub ranking: Vec<TemplateFit>,
    /// χ² and quasi-AICc of the constant (linear) model on the same curves.
    #[serde(with = "nan_as_null")]
    pub constant_chi2: f64,
    #[serde(with = "nan_as_null")]
    pub constant_aicc: f64,
    /// Over-dispersion used for the quasi-AICc: max(1, smallest χ²/dof of any template).
    pub c_hat: f64,
    /// A second effect suspected besides a single-effect verdict (see [`Suspected`]).
    #[serde(default)]
    pub suspected: Option<Suspected>,
    /// The element's single effects tried through the estimator itself (simulated and
    /// refitted per level, see `detect::estimator`), the explaining ones first, then by χ².
    #[serde(default)]
    pub estimator: Vec<EstimatorFit>,
    /// Why a drifting element is reported linear: another element's effect predicts its drift.
    #[serde(default)]
    pub explained_by: Option<String>,
}

impl ElementFinding {
    /// For an unexplained drift: the template that explains the most of it where that is
    /// not the first-ranked one — it fits, but its parameters cost more quasi-AICc than the
    /// element's few curve points repay (at four levels a clearance with friction, five
    /// parameters on eight points, ranks below the clearance alone). `None` otherwise.
    pub fn unranked_explanation(&self) -> Option<String> {
        let Verdict::Unexplained { .. } = self.verdict else {
            return None;
        };
        let first = self.ranking.first()?;
        let (rank, most) = self
            .ranking
            .iter()
            .enumerate()
            .filter(|(_, f)| f.aicc.is_finite() && f.explained.is_finite())
            .max_by(|a, b| a.1.explained.total_cmp(&b.1.explained))?;
        if rank == 0 || most.explained <= first.explained {
            return None;
        }
        Some(format!(
            "the first-ranked template ({}) explains {:.0} %; {} explains {:.0} % (χ²/dof {}) \
             but ranks #{} (ΔAICc {}): its {} parameters on {} curve points cost more than \
             its better fit repays — more levels can rank it",
            first.name,
            100.0 * first.explained,
            most.name,
            100.0 * most.explained,
            fmt_g(most.reduced_chi2),
            rank + 1,
            fmt_g(most.delta_aicc),
            most.n_params,
            most.n_points
        ))
    }
}

/// A single effect tried through the estimator: its coefficient fitted so that the
/// measured curves of the element and its neighbours, minus the drift the effect predicts
/// for this fit on these inputs, are as constant as possible.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatorFit {
    /// e.g. `cubic stiffness`.
    pub effect: String,
    /// e.g. `k3`.
    pub coef_name: String,
    #[serde(with = "nan_as_null")]
    pub value: f64,
    /// From the χ² profile in the coefficient (Δχ² = 1).
    #[serde(with = "nan_as_null")]
    pub stderr: f64,
    /// χ² about each curve's mean after the predicted drift is removed, summed over the
    /// element's and its neighbours' curves, with `dof` degrees of freedom.
    #[serde(with = "nan_as_null")]
    pub chi2: f64,
    pub dof: usize,
    /// The element's curves that still drift once the predicted drift is removed.
    pub still_drifting: Vec<String>,
    /// None does: the effect alone explains the element.
    pub explains: bool,
}

/// A second effect in an element whose verdict names one: another curve of the element
/// drifts, which the verdict's effect cannot explain, but the pair of both effects does
/// not win the ranking (at three levels a pair has as many parameters as the curves have
/// degrees of freedom to spare). More levels separate the two.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Suspected {
    /// e.g. `Coulomb friction`.
    pub effect: String,
    /// The drifting curve the verdict leaves unexplained, and its constancy p-value.
    pub curve: String,
    #[serde(with = "nan_as_null")]
    pub curve_p_value: f64,
    /// The best pair of the verdict's effect with this one, its rank and ΔAICc.
    pub pair: String,
    pub pair_rank: usize,
    #[serde(with = "nan_as_null")]
    pub pair_delta_aicc: f64,
    pub pair_summary: String,
}

/// The result of [`detect`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub n_levels: usize,
    pub level_labels: Vec<String>,
    /// How the per-level fits weighted their rows (filled by
    /// [`super::detect_from_data`]; unit norm for curves given directly).
    #[serde(default)]
    pub rows: super::from_data::DetectRows,
    pub elements: Vec<ElementFinding>,
    pub params: Vec<ParamCurveResult>,
    /// Parameters held fixed over the levels ([`DetectionInput::held`]).
    #[serde(default)]
    pub held: Vec<HeldParam>,
    /// Elements whose s (and v) gains used measured distributions; the rest are Gaussian.
    #[serde(default)]
    pub measured_s: Vec<String>,
    #[serde(default)]
    pub measured_v: Vec<String>,
    /// Means of the data that the linear model cannot explain: a constant force on a body
    /// ([`super::unexplained_means`], filled by [`super::detect_from_data`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constant_forces: Vec<ConstantForceFinding>,
}

#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum DetectError {
    #[error("detection needs at least 2 excitation levels, got {0}")]
    #[diagnostic(
        code(dynid::detect::too_few_levels),
        help("record the system at several excitation intensities (3 or more, spanning a factor ≥ 3 in σ)")
    )]
    TooFewLevels(usize),
    #[error("`{what}` has {got} values, expected one per level ({expected})")]
    #[diagnostic(
        code(dynid::detect::length_mismatch),
        help("every curve and every intensity vector must have one entry per excitation level")
    )]
    LengthMismatch {
        what: String,
        got: usize,
        expected: usize,
    },
    #[error("`{what}` at level {level} is {value}; it must be finite and > 0")]
    #[diagnostic(
        code(dynid::detect::bad_value),
        help("standard errors and intensities must be positive; a zero σ means the element was not excited at that level")
    )]
    BadValue {
        what: String,
        level: usize,
        value: f64,
    },
    #[error("curve `{param}` names element `{element}`, which has no intensities")]
    #[diagnostic(
        code(dynid::detect::unknown_element),
        help("add an ElementIntensity for `{element}` (σ of its relative displacement and velocity per level)")
    )]
    UnknownElement { param: String, element: String },
    #[error("element `{element}` has two {role:?} curves (`{first}` and `{second}`)")]
    #[diagnostic(
        code(dynid::detect::duplicate_role),
        help("an element carries at most one stiffness and one damping curve; give the parallel elements distinct names")
    )]
    DuplicateRole {
        element: String,
        role: Role,
        first: String,
        second: String,
    },
}

/// A constant force the data show on a body that the model gives none.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConstantForceFinding {
    pub body: String,
    /// The force as `force off (ground, body) = f0` writes it (it pushes the body by
    /// `−f0`), in N: the weighted mean of the levels' estimates, and its standard error.
    pub value: f64,
    pub stderr: f64,
    /// Each level's estimate and standard error (N).
    pub per_level: Vec<(f64, f64)>,
    /// The finding as one sentence.
    pub message: String,
}

/// Errors of detection from data: identification and data errors pass through.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum FromDataError {
    #[error(transparent)]
    #[diagnostic(transparent)]
    Identify(#[from] IdentifyError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Detect(#[from] DetectError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
    #[error("{origin}: the relative displacement of element `{element}` does not vary")]
    #[diagnostic(
        code(dynid::detect::no_motion),
        help("check that the element's signals are measured and the record is excited")
    )]
    NoMotion { origin: String, element: String },
    #[error("{origin}: `{param}` cannot be estimated at this level: {reason}")]
    #[diagnostic(
        code(dynid::detect::unidentifiable),
        help("detection compares every unknown's estimate across the levels: remove a term that duplicates another (two elements on the same bodies with the same law), give the parameter a value in the model, or excite the levels where it is missing")
    )]
    Unidentifiable {
        origin: String,
        param: String,
        reason: String,
    },
}
