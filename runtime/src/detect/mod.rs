//! Detection of hidden nonlinearities from per-level linear fits (Schiehlen & Krause §2;
//! docs/method.md, References).
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
//!
//! Files: `types` holds the input and result types and the errors, `render` the text
//! report (`format` its number formats); this file is the pipeline from the curves to the
//! verdicts ([`detect`]) and from measured levels to them ([`detect_from_data`]: the level
//! fits of `from_data`, then the estimator's refinement and the unexplained means).

mod candidate;
mod estimator;
mod fit;
mod format;
pub mod from_data;
pub mod offset;
mod quad;
mod render;
pub mod resolution;
pub mod stats;
mod types;

#[cfg(test)]
mod tests;

pub use candidate::{Candidate, Dependence, Distribution, ShapeParam};
pub use format::{fmt_g, fmt_pm};
pub use from_data::{held_inertia, level_fits, DetectRows, LevelFits, SigmaVSource};
pub use offset::unexplained_means;
pub use quad::NormalRule;
pub use resolution::{levels_too_alike, levels_too_alike_in, LevelsTooAlike};
pub use types::{
    ConstantForceFinding, DetectError, DetectOptions, Detection, DetectionInput, ElementFinding,
    ElementIntensity, Estimate, EstimatorFit, FromDataError, HeldParam, Linearisation, ParamCurve,
    ParamCurveResult, Prediction, Role, Suspected, TemplateFit, Verdict,
};

use crate::data::LevelSource;
use crate::ident::IdentifyOptions;
use dynid_ir::ir::ModelIr;
use fit::{CurveData, ElementData};

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
        rows: Default::default(),
        elements,
        params,
        held: input.held.clone(),
        measured_s,
        measured_v,
        constant_forces: Vec::new(),
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
        estimator: Vec::new(),
        explained_by: None,
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
    if !finding.ranking.iter().any(|f| f.aicc.is_finite()) {
        // Every template is saturated (points ≤ parameters + 1): say how many levels
        // would let the smallest one be ranked, rather than call the drift unexplained.
        let curves = data.n_bases().max(1);
        let need = finding
            .ranking
            .iter()
            .map(|f| (f.n_params + 2).div_ceil(curves))
            .min()
            .unwrap_or(0);
        finding.verdict = Verdict::TooFewLevels {
            levels: data.sigma_s.len(),
            need: need.max(data.sigma_s.len() + 1),
        };
        return finding;
    }
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

/// [`level_fits`] followed by [`detect`], with the batch-means errors' degrees of freedom filled in
/// when `detect_opts.se_dof` is `None`, and the means the linear model cannot explain
/// ([`unexplained_means`]).
pub fn detect_from_data(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    ident_opts: &IdentifyOptions,
    detect_opts: &DetectOptions,
    extra: &[Candidate],
) -> Result<(Detection, LevelFits), FromDataError> {
    detect_from_data_with_progress(ir, levels, ident_opts, detect_opts, extra, &|_, _| {})
}

/// [`detect_from_data`], calling `progress(done, total)` as the estimator's template
/// simulations finish — the step that takes time on long records (`total` grows as
/// drifting elements are reached; called from worker threads).
pub fn detect_from_data_with_progress(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    ident_opts: &IdentifyOptions,
    detect_opts: &DetectOptions,
    extra: &[Candidate],
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Detection, LevelFits), FromDataError> {
    let fits = level_fits(ir, levels, ident_opts, detect_opts.hold_inertia)?;
    let mut opts = detect_opts.clone();
    if opts.se_dof.is_none() {
        opts.se_dof = Some(fits.n_blocks as f64 - 1.0);
    }
    let mut det = detect(&fits.input, extra, &opts)?;
    det.rows = fits.rows;
    estimator::refine(ir, levels, ident_opts, &opts, &fits, &mut det, progress);
    det.constant_forces = unexplained_means(ir, levels, ident_opts)?;
    Ok((det, fits))
}
