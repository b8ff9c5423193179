//! Detection of hidden nonlinearities from per-level linear fits (paper §2).
//!
//! A linear model fitted separately at each excitation level gives, for every linear
//! parameter, a curve over the levels. A linear element gives a constant; an element that
//! hides a nonlinearity gives an equivalent-linear parameter that drifts with the level's
//! intensity, and the shape of the drift names the effect (statistical linearisation; the
//! closed forms below are for Gaussian s, v, and effects of s are by default linearised
//! over the measured distribution of s instead, see [`Linearisation`] and [`Candidate`]):
//!
//! | effect            | force          | equivalent linear parameter           |
//! |-------------------|----------------|---------------------------------------|
//! | cubic stiffness   | k3·s³          | k_eq = k + 3 k3 σ_s²                  |
//! | Coulomb friction  | r·sign(v)      | d_eq = d + r √(2/π)/σ_v               |
//! | quadratic damping | c·v\|v\|       | d_eq = d + c √(8/π) σ_v               |
//! | backlash, gap g   | kb·dz(s, g)    | k_eq = k + kb·erfc(g/(σ_s√2))         |
//! | prestress         | f0·sign(s)     | k_eq = k + f0 √(2/π)/σ_s              |
//!
//! [`detect`] takes the curves ([`ParamCurve`]) and the intensities of each element
//! ([`ElementIntensity`]), tests each curve for constancy, fits every applicable template
//! to each element's stiffness and damping curves jointly, ranks the templates and returns
//! a [`Detection`] with a verdict per element. The core does not know how the curves were
//! obtained; [`from_data`] fills those two types from measured levels (per-level
//! identification, element grouping, measured intensities) for the CLI.

mod candidate;
mod fit;
pub mod from_data;
mod quad;
pub mod stats;

#[cfg(test)]
mod tests;

pub use candidate::{Candidate, Dependence, Distribution, ShapeParam};
pub use from_data::{
    detect_from_data, held_inertia, level_fits, FromDataError, LevelFits, SigmaVSource,
};
pub use quad::NormalRule;

use dynid_ir::num;
use dynid_ir::print::aligned;
use serde::{Deserialize, Serialize};

use fit::{CurveData, ElementData};

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
    /// Standard errors (e.g. block jackknife), same length, all > 0.
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
    /// Degrees of freedom of the standard errors (block jackknife with B blocks: B − 1).
    /// When set, the constancy statistic χ²/(L−1) is referred to F(L−1, ν) instead of
    /// χ²_(L−1)/(L−1): a jackknife variance from 10 blocks is itself uncertain by ~±45 %,
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
}

/// The distributions statistical linearisation averages over.
///
/// Measured on simulated data with known truth (4 seeds, tests/detect_models.rs
/// `linearisation_bias`), the per-level fits follow the *measured* distribution of s —
/// a hardening spring makes s light-tailed, and the Gaussian form puts the implied k3
/// 24 % low, the measured one 1 % — but the *Gaussian* form of v: with the measured
/// distribution of v the implied Coulomb r and quadratic c came out 4–5 % high instead of
/// within 1–3 %. Hence the default.
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

fn check_len(what: &str, got: usize, expected: usize) -> Result<(), DetectError> {
    if got == expected {
        Ok(())
    } else {
        Err(DetectError::LengthMismatch {
            what: what.to_string(),
            got,
            expected,
        })
    }
}

fn check_positive(what: &str, v: &[f64]) -> Result<(), DetectError> {
    for (level, &value) in v.iter().enumerate() {
        if !(value.is_finite() && value > 0.0) {
            return Err(DetectError::BadValue {
                what: what.to_string(),
                level: level + 1,
                value,
            });
        }
    }
    Ok(())
}

/// The constancy test of one curve (see [`DetectOptions`]).
pub fn constancy_test(
    curve: &ParamCurve,
    sigma: Vec<f64>,
    sigma_name: &str,
    opts: &DetectOptions,
) -> ParamCurveResult {
    let mut med = curve.stderrs.clone();
    med.sort_by(f64::total_cmp);
    let med = med[med.len() / 2];
    let se: Vec<f64> = curve
        .stderrs
        .iter()
        .map(|s| s.max(opts.se_floor_rel * med))
        .collect();
    let (mean, mean_se) = fit::weighted_mean(&curve.values, &se);
    let chi2: f64 = curve
        .values
        .iter()
        .zip(&se)
        .map(|(y, s)| ((y - mean) / s).powi(2))
        .sum();
    let dof = curve.values.len() - 1;
    let p_value = match opts.se_dof {
        Some(nu) => stats::f_sf(chi2 / dof as f64, dof as f64, nu),
        None => stats::chi2_sf(chi2, dof as f64),
    };
    let (lo, hi) = curve
        .values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| {
            (a.min(y), b.max(y))
        });
    let rel_change = if mean != 0.0 {
        (hi - lo) / mean.abs()
    } else {
        f64::INFINITY
    };
    ParamCurveResult {
        curve: curve.clone(),
        sigma,
        sigma_name: sigma_name.to_string(),
        stderrs_used: se,
        mean,
        mean_stderr: mean_se,
        chi2,
        dof,
        p_value,
        rel_change,
        drifting: p_value < opts.alpha && rel_change > opts.min_rel_change,
    }
}

/// Test every curve for constancy and explain the drifting elements by templates.
///
/// `extra` are user-declared candidate effects, tried besides the built-ins (unless
/// [`DetectOptions::builtins`] is off).
pub fn detect(
    input: &DetectionInput,
    extra: &[Candidate],
    opts: &DetectOptions,
) -> Result<Detection, DetectError> {
    let n_levels = input
        .curves
        .first()
        .map(|c| c.values.len())
        .or_else(|| input.elements.first().map(|e| e.sigma_s.len()))
        .unwrap_or(0);
    if n_levels < 2 {
        return Err(DetectError::TooFewLevels(n_levels));
    }
    for e in &input.elements {
        check_len(&format!("σ_s of {}", e.element), e.sigma_s.len(), n_levels)?;
        check_len(&format!("σ_v of {}", e.element), e.sigma_v.len(), n_levels)?;
        check_positive(&format!("σ_s of {}", e.element), &e.sigma_s)?;
        check_positive(&format!("σ_v of {}", e.element), &e.sigma_v)?;
    }
    for c in &input.curves {
        check_len(&c.param, c.values.len(), n_levels)?;
        check_len(
            &format!("stderrs of {}", c.param),
            c.stderrs.len(),
            n_levels,
        )?;
        check_positive(&format!("stderr of {}", c.param), &c.stderrs)?;
        if let Some(level) = c.values.iter().position(|v| !v.is_finite()) {
            return Err(DetectError::BadValue {
                what: c.param.clone(),
                level: level + 1,
                value: c.values[level],
            });
        }
    }
    let intensity = |name: &str| input.elements.iter().find(|e| e.element == name);

    let mut params = Vec::with_capacity(input.curves.len());
    for c in &input.curves {
        let (sigma, name) = match (c.role, intensity(&c.element)) {
            (Role::Stiffness, Some(e)) => (e.sigma_s.clone(), "σ_s"),
            (Role::Damping, Some(e)) => (e.sigma_v.clone(), "σ_v"),
            (Role::Stiffness | Role::Damping, None) => {
                return Err(DetectError::UnknownElement {
                    param: c.param.clone(),
                    element: c.element.clone(),
                })
            }
            _ => ((1..=n_levels).map(|l| l as f64).collect(), "level"),
        };
        params.push(constancy_test(c, sigma, name, opts));
    }

    let builtins = if opts.builtins {
        Candidate::builtins()
    } else {
        Vec::new()
    };
    let mut elements = Vec::new();
    let (mut measured_s, mut measured_v) = (Vec::new(), Vec::new());
    for e in &input.elements {
        let mut data = ElementData {
            stiffness: None,
            damping: None,
            sigma_s: e.sigma_s.clone(),
            sigma_v: e.sigma_v.clone(),
            s_dist: Vec::new(),
            v_dist: Vec::new(),
        };
        if opts.linearisation != Linearisation::Gaussian && e.s_dist.len() == n_levels {
            data.s_dist = e.s_dist.clone();
        }
        if opts.linearisation == Linearisation::Measured && e.v_dist.len() == n_levels {
            data.v_dist = e.v_dist.clone();
        }
        let mut drifting = Vec::new();
        for r in params.iter().filter(|r| r.curve.element == e.element) {
            let slot = match r.curve.role {
                Role::Stiffness => &mut data.stiffness,
                Role::Damping => &mut data.damping,
                _ => continue,
            };
            if let Some(prev) = slot {
                return Err(DetectError::DuplicateRole {
                    element: e.element.clone(),
                    role: r.curve.role,
                    first: prev.param.clone(),
                    second: r.curve.param.clone(),
                });
            }
            *slot = Some(CurveData {
                param: r.curve.param.clone(),
                y: r.curve.values.clone(),
                se: r.stderrs_used.clone(),
            });
            if r.drifting {
                drifting.push(r.curve.param.clone());
            }
        }
        if data.stiffness.is_none() && data.damping.is_none() {
            continue;
        }
        if !data.s_dist.is_empty() {
            measured_s.push(e.element.clone());
        }
        if !data.v_dist.is_empty() {
            measured_v.push(e.element.clone());
        }
        elements.push(explain_element(
            &e.element,
            &data,
            drifting,
            &params,
            builtins.iter().chain(extra.iter()).collect(),
            opts,
        ));
    }
    let level_labels = if input.level_labels.len() == n_levels {
        input.level_labels.clone()
    } else {
        (1..=n_levels).map(|l| l.to_string()).collect()
    };
    Ok(Detection {
        n_levels,
        level_labels,
        elements,
        params,
        held: input.held.clone(),
        measured_s,
        measured_v,
    })
}

fn explain_element(
    element: &str,
    data: &ElementData,
    drifting: Vec<String>,
    params: &[ParamCurveResult],
    candidates: Vec<&Candidate>,
    opts: &DetectOptions,
) -> ElementFinding {
    let (constant_chi2, k_const) = fit::constant_chi2(data);
    let n = data.n_points();
    let mut finding = ElementFinding {
        element: element.to_string(),
        verdict: Verdict::Linear,
        drifting,
        ranking: Vec::new(),
        constant_chi2,
        constant_aicc: fit::aicc(constant_chi2, k_const, n),
        c_hat: 1.0,
        suspected: None,
    };
    if finding.drifting.is_empty() {
        return finding;
    }
    let cands: Vec<&Candidate> = candidates
        .into_iter()
        .filter(|c| c.applies_to(element))
        .collect();
    let mut fits: Vec<TemplateFit> = cands
        .iter()
        .filter_map(|c| fit::fit_template(data, &[c], constant_chi2))
        .collect();
    // When both curves drift, one effect per curve may be at work (a hardening spring
    // together with friction): try every pair of a stiffness-only and a damping-only
    // effect. Pairs acting on the same curve are not formed: "inverse" effects on one
    // curve cancel and are to be reported as ambiguous, not fitted as a sum.
    let drifts = |role: Role| {
        params
            .iter()
            .any(|r| r.curve.element == element && r.curve.role == role && r.drifting)
    };
    if drifts(Role::Stiffness) && drifts(Role::Damping) {
        for a in cands.iter().filter(|c| c.dependence == Dependence::S) {
            for b in cands.iter().filter(|c| c.dependence == Dependence::V) {
                if let Some(f) = fit::fit_template(data, &[a, b], constant_chi2) {
                    fits.push(f);
                }
            }
        }
    }
    // Effects with opposite trends on one drifting curve (prestress and backlash, Coulomb
    // friction and quadratic damping) can partly cancel; fit them together to see whether
    // the curve shows both, and whether the data can tell their sizes apart.
    for (dep, role) in [
        (Dependence::S, Role::Stiffness),
        (Dependence::V, Role::Damping),
    ] {
        if !drifts(role) {
            continue;
        }
        let on: Vec<&&Candidate> = cands
            .iter()
            .filter(|c| c.dependence == dep && c.positive)
            .collect();
        for (i, a) in on.iter().enumerate() {
            for b in &on[..i] {
                if trend(a, data) * trend(b, data) < 0.0 {
                    if let Some(mut f) = fit::fit_template(data, &[a, b], constant_chi2) {
                        f.inverse_pair = true;
                        fits.push(f);
                    }
                }
            }
        }
    }
    if fits.is_empty() {
        finding.verdict = Verdict::Unexplained {
            best_explained: 0.0,
        };
        return finding;
    }
    let c_hat = fits
        .iter()
        .filter(|f| f.reduced_chi2.is_finite())
        .map(|f| f.reduced_chi2)
        .fold(f64::INFINITY, f64::min);
    let c_hat = if c_hat.is_finite() {
        c_hat.max(1.0)
    } else {
        1.0
    };
    for f in &mut fits {
        f.aicc = fit::aicc(f.chi2 / c_hat, f.n_params, f.n_points);
    }
    finding.constant_aicc = fit::aicc(constant_chi2 / c_hat, k_const, n);
    finding.c_hat = c_hat;
    fits.sort_by(|a, b| a.aicc.total_cmp(&b.aicc).then(a.chi2.total_cmp(&b.chi2)));
    let best_aicc = fits[0].aicc;
    for f in &mut fits {
        f.delta_aicc = f.aicc - best_aicc;
    }
    finding.ranking = fits;
    let best = &finding.ranking[0];
    if !best.aicc.is_finite() || best.explained < opts.min_explained {
        // Only fits that can be ranked count: a template with as many parameters as levels
        // explains everything and proves nothing.
        finding.verdict = Verdict::Unexplained {
            best_explained: finding
                .ranking
                .iter()
                .filter(|f| f.aicc.is_finite())
                .map(|f| f.explained)
                .fold(0.0, f64::max),
        };
        return finding;
    }
    let near: Vec<&TemplateFit> = finding
        .ranking
        .iter()
        .filter(|f| f.delta_aicc < opts.ambiguity_delta)
        .collect();
    // A pair that contains a near-equal single adds nothing: keep the simpler one.
    let tied: Vec<&TemplateFit> = near
        .iter()
        .copied()
        .filter(|f| {
            !near.iter().any(|g| {
                g.effects.len() < f.effects.len() && g.effects.iter().all(|e| f.effects.contains(e))
            })
        })
        .collect();
    let top = tied.first().copied().unwrap_or(best);
    finding.verdict = if top.inverse_pair && top.coef_corr > opts.max_pair_corr {
        Verdict::Ambiguous {
            candidates: top.effects.clone(),
        }
    } else if tied.len() > 1 {
        Verdict::Ambiguous {
            candidates: tied.iter().map(|f| f.name.clone()).collect(),
        }
    } else {
        let f = tied.first().copied().unwrap_or(best);
        Verdict::Nonlinear {
            best: f.name.clone(),
            summary: f.summary(),
        }
    };
    finding.suspected = suspected_second(&finding, &cands, params, element);
    finding
}

/// A single-effect verdict that leaves a drifting curve of the element untouched (a
/// stiffness effect while the damping curve drifts too, or the reverse): the best pair
/// that adds an effect on that curve names what is suspected there. With few levels the
/// pair's extra parameter costs more AICc than its fit gains, so the second effect is
/// reported as suspected rather than dropped.
fn suspected_second(
    finding: &ElementFinding,
    cands: &[&Candidate],
    params: &[ParamCurveResult],
    element: &str,
) -> Option<Suspected> {
    let Verdict::Nonlinear { best, .. } = &finding.verdict else {
        return None;
    };
    let dep = cands.iter().find(|c| &c.name == best)?.dependence;
    let other = match dep {
        Dependence::S => Role::Damping,
        Dependence::V => Role::Stiffness,
        Dependence::SV => return None,
    };
    let curve = params
        .iter()
        .find(|r| r.curve.element == element && r.curve.role == other && r.drifting)?;
    let (rank, pair) = finding.ranking.iter().enumerate().find(|(_, f)| {
        f.effects.len() == 2 && !f.inverse_pair && f.effects.iter().any(|e| e == best)
    })?;
    let effect = pair.effects.iter().find(|e| *e != best)?.clone();
    Some(Suspected {
        effect,
        curve: curve.curve.param.clone(),
        curve_p_value: curve.p_value,
        pair: pair.name.clone(),
        pair_rank: rank + 1,
        pair_delta_aicc: pair.delta_aicc,
        pair_summary: pair.summary(),
    })
}

/// Direction of an effect's gain over the element's intensity range (+1 rises, −1 falls),
/// with a shape parameter at the middle of its range.
fn trend(c: &Candidate, el: &ElementData) -> f64 {
    let (lo, hi) = (0..el.sigma_s.len()).fold((0, 0), |(lo, hi), l| {
        (
            if el.sigma_s[l] < el.sigma_s[lo] {
                l
            } else {
                lo
            },
            if el.sigma_s[l] > el.sigma_s[hi] {
                l
            } else {
                hi
            },
        )
    });
    let theta = c.shape.as_ref().map_or(0.0, |s| {
        let mut sig = match s.scale_by {
            Dependence::V => el.sigma_v.clone(),
            _ => el.sigma_s.clone(),
        };
        sig.sort_by(f64::total_cmp);
        sig[sig.len() / 2] * (s.lo_rel * s.hi_rel).sqrt()
    });
    let h = |l: usize| {
        let (hk, hd) = c.gains(el.sigma_s[l], el.sigma_v[l], theta);
        hk + hd
    };
    (h(hi) - h(lo)).signum()
}

/// `value ± stderr` with the value rounded to the stderr's second significant digit.
pub fn fmt_pm(value: f64, stderr: f64) -> String {
    num::pm(value, stderr)
}

/// Four significant digits, plain notation where readable.
pub fn fmt_g(x: f64) -> String {
    num::sig(x, 4, true)
}

impl Detection {
    /// A plain-text report: the constancy test of every curve, then one block per element
    /// with its verdict and template ranking.
    pub fn render_table(&self) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let _ = writeln!(out, "Parameter curves over {} levels", self.n_levels);
        let mut rows = vec![vec![
            "param".to_string(),
            "element".into(),
            "role".into(),
            "weighted mean".into(),
            "change".into(),
            "χ²/dof".into(),
            "p".into(),
            "drifts".into(),
        ]];
        for p in &self.params {
            rows.push(vec![
                p.curve.param.clone(),
                p.curve.element.clone(),
                format!("{:?}", p.curve.role),
                fmt_pm(p.mean, p.mean_stderr),
                format!("{:.1} %", 100.0 * p.rel_change),
                fmt_g(p.chi2 / p.dof as f64),
                format!("{:.2e}", p.p_value),
                if p.drifting { "DRIFTS" } else { "-" }.into(),
            ]);
        }
        out.push_str(&aligned(
            &rows,
            &[false, false, false, true, true, true, true, false],
            "  ",
        ));
        let _ = writeln!(out, "Per level (value ± standard error):");
        let mut rows = vec![std::iter::once("param".to_string())
            .chain(self.level_labels.iter().cloned())
            .collect::<Vec<_>>()];
        for p in &self.params {
            rows.push(
                std::iter::once(p.curve.param.clone())
                    .chain(
                        p.curve
                            .values
                            .iter()
                            .zip(&p.curve.stderrs)
                            .map(|(v, s)| fmt_pm(*v, *s)),
                    )
                    .collect(),
            );
        }
        let mut right = vec![true; self.n_levels + 1];
        right[0] = false;
        out.push_str(&aligned(&rows, &right, "  "));
        if !self.held.is_empty() {
            let h: Vec<String> = self
                .held
                .iter()
                .map(|h| format!("{} = {}", h.param, fmt_pm(h.value, h.stderr)))
                .collect();
            let _ = writeln!(
                out,
                "Held at one value for all levels (a mass at the weighted mean of its free \
                 per-level estimates, a constant\n  force at its pooled estimate; linearisation \
                 changes neither): {}",
                h.join(", ")
            );
        }
        for e in &self.elements {
            let _ = writeln!(out);
            let _ = writeln!(out, "Element {}: {}", e.element, e.verdict);
            if let Verdict::Nonlinear { summary, .. } = &e.verdict {
                let _ = writeln!(out, "  {summary}");
            }
            if let Some(x) = &e.suspected {
                let _ = writeln!(
                    out,
                    "  also suspected: {} — `{}` drifts too (p = {:.1e}) and the verdict leaves \
                     that unexplained;\n  the pair is #{} in the ranking (ΔAICc {}): {};\n  more levels \
                     would separate the two",
                    x.effect,
                    x.curve,
                    x.curve_p_value,
                    x.pair_rank,
                    fmt_g(x.pair_delta_aicc),
                    x.pair_summary
                );
            }
            if e.ranking.is_empty() {
                continue;
            }
            let mut rows = vec![vec![
                "#".to_string(),
                "template".into(),
                "ΔAICc".into(),
                "explains".into(),
                "χ²/dof".into(),
                "implied parameters".into(),
            ]];
            for (i, f) in e.ranking.iter().take(6).enumerate() {
                let est: Vec<String> = f.effect_estimates().iter().map(|x| x.to_string()).collect();
                rows.push(vec![
                    (i + 1).to_string(),
                    f.name.clone(),
                    fmt_g(f.delta_aicc),
                    format!("{:.1} %", 100.0 * f.explained),
                    fmt_g(f.reduced_chi2),
                    est.join(", "),
                ]);
            }
            out.push_str(&aligned(
                &rows,
                &[true, false, true, true, true, false],
                "  ",
            ));
            let _ = writeln!(
                out,
                "  constant (linear) model: ΔAICc = {}, over-dispersion ĉ = {}",
                fmt_g(e.constant_aicc - e.ranking[0].aicc),
                fmt_g(e.c_hat)
            );
        }
        if !self.measured_s.is_empty() || !self.measured_v.is_empty() {
            let _ = writeln!(out);
            let what = |v: &[String], sig: &str| {
                if v.is_empty() {
                    String::new()
                } else {
                    format!("{sig}: {}; ", v.join(", "))
                }
            };
            let _ = writeln!(
                out,
                "Templates linearised over the measured distribution of {}{}Gaussian elsewhere.",
                what(&self.measured_s, "s"),
                what(&self.measured_v, "v")
            );
        }
        out
    }
}
