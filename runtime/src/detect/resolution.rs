//! Levels too alike to resolve a nonlinearity: a "linear" verdict that only means the
//! levels could not tell.
//!
//! Detection sees a nonlinearity only through the drift of an equivalent-linear parameter
//! over the levels' intensities. On levels of nearly equal σ every template is nearly
//! constant, so even a large effect passes the constancy test. Whether the level set can
//! resolve one is a question about the test itself, asked of every curve that did not
//! drift:
//!
//! * Take an effect whose equivalent-linear part scales like σ or 1/σ — quadratic damping
//!   (∝ σ_v), Coulomb friction (∝ 1/σ_v), prestress (∝ 1/σ_s). These are the built-ins
//!   whose drift over a σ range is smallest for their size (a cubic spring drifts ∝ σ²,
//!   twice as steeply), so a level set that resolves them resolves the others.
//! * Let it contribute a fraction `f` of the curve's mean at the level where it is largest.
//!   Across levels whose σ spans a factor `r` it changes the parameter by `f·(1 − 1/r)` of
//!   the mean, shaped `σ_l/σ_max` or `σ_min/σ_l`.
//! * Without noise, that curve gives the constancy statistic `f²·χ²₁` (χ²₁: the weighted
//!   squared deviation of the shape from its weighted mean, with the curve's own standard
//!   errors). The test flags it when this reaches the critical value of the test at
//!   [`DetectOptions::alpha`] (χ² or F with [`DetectOptions::se_dof`], as in
//!   [`super::constancy_test`]) — even odds of detection — and when `f·(1 − 1/r)` exceeds
//!   [`DetectOptions::min_rel_change`].
//!
//! The smallest `f` meeting both, for the harder of the two shapes, is the smallest visible
//! effect. When it exceeds [`MAX_INVISIBLE`] (an effect a quarter the size of the linear
//! value would go unseen), the levels are too alike: the curve is reported with a warning
//! instead of a silent "linear". With the recommended factor of 3 in σ, `1 − 1/r = 2/3`
//! and the 2 % minimum change alone needs only `f = 3 %`; at a factor 1.1 it needs 22 %
//! before any noise.

use super::from_data::level_fits;
use super::stats::{chi2_sf, f_sf};
use super::types::{DetectOptions, Detection, FromDataError, Role, Verdict};
use serde::Serialize;

/// Largest effect (fraction of the curve's mean at the level where the effect is largest)
/// that a level set may fail to reveal before it is reported as too alike.
pub const MAX_INVISIBLE: f64 = 0.25;

/// A curve that did not drift although its levels could not have shown a drift.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelsTooAlike {
    pub element: String,
    pub param: String,
    /// `σ_s` or `σ_v`.
    pub sigma_name: String,
    /// Largest over smallest σ of the levels.
    pub sigma_ratio: f64,
    /// The smallest visible effect, a fraction of the parameter (see the module docs).
    pub smallest_visible: f64,
    /// The warning as one sentence.
    pub message: String,
}

/// The critical value `c` of the constancy statistic χ² over `dof` degrees of freedom:
/// its p-value at `c` is `alpha` (bisection on the monotone tail probability).
fn critical(alpha: f64, dof: usize, se_dof: Option<f64>) -> f64 {
    let d = dof as f64;
    let p = |c: f64| match se_dof {
        Some(nu) => f_sf(c / d, d, nu),
        None => chi2_sf(c, d),
    };
    let mut hi = 1.0;
    while p(hi) > alpha && hi < 1e12 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if p(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The stiffness and damping curves of `det` that stayed constant on levels too alike to
/// reveal an effect of [`MAX_INVISIBLE`] of their value. `opts` must be the options the
/// detection ran with (`se_dof` included: [`super::detect_from_data`] sets it to the
/// batch-means blocks minus one).
pub fn levels_too_alike(det: &Detection, opts: &DetectOptions) -> Vec<LevelsTooAlike> {
    let mut out = Vec::new();
    for r in &det.params {
        if r.drifting || !matches!(r.curve.role, Role::Stiffness | Role::Damping) {
            continue;
        }
        // Only a "linear" verdict can be silently wrong: an element found nonlinear has
        // shown its effect on another curve.
        let linear = det
            .elements
            .iter()
            .find(|e| e.element == r.curve.element)
            .is_none_or(|e| e.verdict == Verdict::Linear);
        if !linear {
            continue;
        }
        let (sig, se) = (&r.sigma, &r.stderrs_used);
        let (lo, hi) = sig
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
        let mean = r.mean.abs();
        if sig.len() < 2
            || !(lo > 0.0 && hi.is_finite() && mean > 0.0)
            || !se.iter().all(|s| s.is_finite() && *s > 0.0)
        {
            continue;
        }
        let ratio = hi / lo;
        let f = smallest_visible(sig, se, mean, opts);
        if f > MAX_INVISIBLE {
            let element = r.curve.element.clone();
            let message = too_alike_message(&r.curve.param, &element, &r.sigma_name, ratio, f);
            out.push(LevelsTooAlike {
                element,
                param: r.curve.param.clone(),
                sigma_name: r.sigma_name.clone(),
                sigma_ratio: ratio,
                smallest_visible: f,
                message,
            });
        }
    }
    out
}

/// The smallest visible effect (a fraction of `mean`, see the module docs) on a curve of
/// mean `mean` with standard errors `se` at levels of intensity `sig` (at least two, all
/// positive and finite, as are `se` and `mean`): infinite when the levels do not differ.
pub(crate) fn smallest_visible(sig: &[f64], se: &[f64], mean: f64, opts: &DetectOptions) -> f64 {
    let (lo, hi) = sig
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    let span = 1.0 - lo / hi;
    let crit = critical(opts.alpha, sig.len().saturating_sub(1).max(1), opts.se_dof);
    let smallest = |shape: &dyn Fn(f64) -> f64| {
        let g: Vec<f64> = sig.iter().map(|&s| mean * shape(s)).collect();
        let w: Vec<f64> = se.iter().map(|s| 1.0 / (s * s)).collect();
        let gm = g.iter().zip(&w).map(|(g, w)| g * w).sum::<f64>() / w.iter().sum::<f64>();
        let chi2: f64 = g.iter().zip(se).map(|(g, s)| ((g - gm) / s).powi(2)).sum();
        let by_test = if chi2 > 0.0 {
            (crit / chi2).sqrt()
        } else {
            f64::INFINITY
        };
        let by_change = if span > 0.0 {
            opts.min_rel_change / span
        } else {
            f64::INFINITY
        };
        by_test.max(by_change)
    };
    smallest(&|s| s / hi).max(smallest(&|s| lo / s))
}

/// The warnings of [`levels_too_alike`] that `dynid detect` gives on `levels` for the model
/// `ir`: its per-level fits with the default detection settings (the batch-means errors' degrees
/// of freedom filled in as [`super::detect_from_data`] does), without the search for
/// constant forces. For a front end that does not run the detection itself (the diagnosis).
pub fn levels_too_alike_in(
    ir: &dynid_ir::ir::ModelIr,
    levels: &[&dyn crate::data::LevelSource],
    ident_opts: &crate::ident::IdentifyOptions,
) -> Result<Vec<LevelsTooAlike>, FromDataError> {
    let mut opts = DetectOptions::default();
    let fits = level_fits(ir, levels, ident_opts, opts.hold_inertia)?;
    opts.se_dof.get_or_insert(fits.n_blocks as f64 - 1.0);
    let det = super::detect(&fits.input, &[], &opts)?;
    Ok(levels_too_alike(&det, &opts))
}

/// The span in σ below which the levels themselves are too alike (the recommendation of
/// the detection's help: a factor ≥ 3).
const WIDE_SPAN: f64 = 3.0;

/// The warning for a curve whose smallest visible effect is `f` (a fraction) with its σ
/// spanning a factor `ratio`: blamed on the levels' span when it is below [`WIDE_SPAN`],
/// on the standard errors otherwise (more span would not help then).
fn too_alike_message(param: &str, element: &str, sigma: &str, ratio: f64, f: f64) -> String {
    let size = if f > 10.0 {
        // Beyond ten times the parameter the figure carries no information.
        "over 1000 %".to_string()
    } else if f.is_finite() {
        format!("{} %", dynid_ir::num::sig(100.0 * f, 2, false))
    } else {
        "any size".into()
    };
    let effect = format!(
        "an effect that scales with σ or 1/σ (friction, prestress, quadratic damping) would \
         have to reach {size} of `{param}` to show as a drift (at most {:.0} % is needed); \
         `linear` here only rules out larger effects",
        100.0 * MAX_INVISIBLE
    );
    let factor = dynid_ir::num::sig(ratio, 3, false);
    // Decide on the printed factor, so that "only a factor 3" never meets "≥ 3".
    if dynid_ir::num::round_sig(ratio, 3) < WIDE_SPAN {
        format!(
            "levels too alike for `{param}` of {element}: its {sigma} spans only a factor \
             {factor} over the levels, so {effect} — add levels that span a wider range of \
             amplitude (a factor ≥ {WIDE_SPAN} in {sigma}), or record longer levels"
        )
    } else {
        format!(
            "standard errors too large for `{param}` of {element}: its {sigma} spans a \
             factor {factor} over the levels, but with the standard errors of `{param}` \
             {effect} — record longer levels or less noisy data (a wider span would not \
             help)"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::{detect, DetectionInput, ElementIntensity, ParamCurve};

    fn detection(sigma: &[f64], rel_se: f64) -> (Detection, DetectOptions) {
        let n = sigma.len();
        let input = DetectionInput {
            level_labels: Vec::new(),
            elements: vec![ElementIntensity {
                element: "k (ground, m)".into(),
                sigma_s: sigma.to_vec(),
                sigma_v: sigma.iter().map(|s| 2.0 * s).collect(),
                ..Default::default()
            }],
            curves: vec![ParamCurve {
                param: "k".into(),
                element: "k (ground, m)".into(),
                role: Role::Stiffness,
                values: vec![4.0; n],
                stderrs: vec![4.0 * rel_se; n],
            }],
            held: Vec::new(),
        };
        let opts = DetectOptions {
            se_dof: Some(19.0),
            ..Default::default()
        };
        (detect(&input, &[], &opts).unwrap(), opts)
    }

    #[test]
    fn the_critical_value_inverts_the_test() {
        // P(χ²_4 > 18.4668) = 0.001.
        assert!((critical(1e-3, 4, None) - 18.466_826_952_903_15).abs() < 1e-6);
        let c = critical(1e-3, 2, Some(19.0));
        assert!((f_sf(c / 2.0, 2.0, 19.0) - 1e-3).abs() < 1e-9);
    }

    #[test]
    fn alike_levels_warn_and_spread_levels_do_not() {
        // Three levels spanning a factor 3 with 1 % errors: the 2 % minimum change
        // decides (f = 0.02 / (2/3) = 3 %) or the test (a few %): no warning.
        let (d, o) = detection(&[0.1, 0.17, 0.3], 0.01);
        assert!(levels_too_alike(&d, &o).is_empty());
        // A factor 1.1: the minimum change alone needs 22 %, the test more.
        let (d, o) = detection(&[0.1, 0.105, 0.11], 0.01);
        let w = levels_too_alike(&d, &o);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!((w[0].sigma_ratio - 1.1).abs() < 1e-12);
        assert!(w[0].smallest_visible > 0.25, "{w:?}");
        assert!(
            w[0].message.contains("spans only a factor 1.1 "),
            "{}",
            w[0].message
        );
        assert!(w[0].message.contains("a factor ≥ 3"), "{}", w[0].message);
        // The same factor 3 with 20 % errors cannot resolve a quarter either: the
        // warning blames the standard errors, not the span, which it must not ask to
        // widen to a factor it already exceeds.
        let (d, o) = detection(&[0.1, 0.17, 0.3], 0.2);
        let w = levels_too_alike(&d, &o);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].message.starts_with("standard errors too large"),
            "{}",
            w[0].message
        );
        assert!(!w[0].message.contains("≥ 3"), "{}", w[0].message);
        // A span of millions is printed as a number a reader can take in.
        let (d, o) = detection(&[1e-6, 0.5, 3.871641], 40.0);
        let w = levels_too_alike(&d, &o);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].message.contains("a factor 3.87e6 "),
            "{}",
            w[0].message
        );
    }
}
