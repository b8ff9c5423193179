//! Shape parameters by variable projection: unknowns that enter nonlinearly (the gap of a
//! `deadzone`, the limit of a `saturate`) are profiled instead of gridded.
//!
//! For a trial value `g` of the shape parameters every linear parameter is a weighted
//! least-squares solve of the covariance equations (the columns of the terms that use `g`
//! are filtered anew), which leaves the residual sum of squares `S(g)` of the unit-norm
//! rows. The estimate minimises `S`: per shape parameter (coordinate-wise, two sweeps when
//! there are several) a log-spaced bracket of factors 1/16 … 16 around the current value
//! (factor 2 apart), then a golden-section search on the logarithm inside the best
//! bracket. The linear estimates are those of the solve at the minimum; their standard
//! errors add to the solve's own (which holds the shape fixed) the shape's error carried
//! along the profile, `(∂p̂/∂g)² se(g)²`, with `∂p̂/∂g` by the same central difference.
//!
//! The standard error of a shape parameter comes from the profile's curvature, with the
//! classical least-squares scaling: `se² = 2 σ² / S''(ĝ)`, `σ² = S(ĝ) / (rows − unknowns −
//! shapes)`, `S''` by a central difference over ±1 % of `ĝ`. It is not reported when the
//! profile is not convex there or the minimum lies at the edge of the search. That scaling
//! treats the rows' residuals as independent, which they are not, and the profile of a gap
//! is flat where the gap trades against the stiffnesses: on noise-free backlash data the
//! curvature gave 0.5–2.5 % of the gap while the estimates spread over −12 % … +4.3 %
//! across seeds 1–8. [`profile`] therefore also profiles every leave-one-level-out subset
//! (with three levels or more) and reports the larger of the curvature and the jackknife
//! error; even so one seed of eight lies 6.7 reported errors off (`tests/shape_profile.rs`,
//! `DYNID_SEED_OFFSET=k … -- --nocapture` prints the figures).

use super::measure::measure;
use super::types::Identification;
use super::types::{IdentifyError, IdentifyOptions, ShapeEstimate};
use crate::data::LevelSource;
use crate::tape::Tape;
use dynid_ir::ir::ModelIr;

/// Bracket factors around the current value (log-spaced, factor 2 apart).
const BRACKET: [f64; 9] = [1.0 / 16.0, 1.0 / 8.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0];
/// Golden-section iterations inside the best bracket (each shrinks it by 0.618).
const GOLDEN_STEPS: usize = 14;

/// Identify `ir` with its shape parameters profiled. Returns the model at the estimated
/// shape values and the identification there (with [`Identification::shapes`] filled).
pub fn profile(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<(ModelIr, Identification), IdentifyError> {
    let (at, mut id) = profile_with(ir, &Search::default(), &|at: &ModelIr| {
        fit_on(at, levels, opts)
    })?;
    if levels.len() < 3 {
        return Ok((at, id));
    }
    // Jackknife over levels: the profile is flat along the direction in which a gap trades
    // against the stiffnesses, so small systematic equation errors move its minimum more
    // than the curvature's classical scaling says; the spread of the leave-one-level-out
    // estimates measures that. The larger of the two errors is reported.
    let n = levels.len() as f64;
    let local = Search {
        bracket: vec![0.5, 0.71, 1.0, 1.41, 2.0],
        steps: 10,
    };
    let start = ir.with_shapes(&id.shapes.iter().map(|s| s.value).collect::<Vec<_>>());
    let mut leave_out: Vec<Vec<f64>> = Vec::new();
    for i in 0..levels.len() {
        let rest: Vec<&dyn LevelSource> = levels
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, l)| *l)
            .collect();
        if let Ok((_, sub)) = profile_with(&start, &local, &|at: &ModelIr| fit_on(at, &rest, opts))
        {
            leave_out.push(sub.shapes.iter().map(|s| s.value).collect());
        }
    }
    if leave_out.len() == levels.len() {
        for k in 0..id.shapes.len() {
            let mean = leave_out.iter().map(|v| v[k]).sum::<f64>() / n;
            let var = (n - 1.0) / n * leave_out.iter().map(|v| (v[k] - mean).powi(2)).sum::<f64>();
            let jack = var.sqrt();
            let sh = &mut id.shapes[k];
            sh.leave_out = leave_out.iter().map(|v| v[k]).collect();
            let before = sh.stderr.unwrap_or(0.0);
            if jack.is_finite() && jack > before {
                // Carry the larger error into the linear estimates as well.
                sh.stderr = Some(jack);
                let slopes = sh.slopes.clone();
                id.widen(&slopes, jack * jack - before * before);
            }
        }
    }
    Ok((at, id))
}

/// The pooled identification of `at` on `levels`.
fn fit_on(
    at: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let tape = Tape::compile(at, &at.eval_roots());
    Ok(measure(at, &tape, levels, opts)?.identify_pooled())
}

/// How widely and how finely a profile searches.
#[derive(Clone, Debug)]
pub struct Search {
    /// Factors of the starting value tried first (ascending); the minimum's neighbours
    /// bracket the golden-section search.
    pub bracket: Vec<f64>,
    /// Golden-section iterations.
    pub steps: usize,
}

impl Default for Search {
    fn default() -> Self {
        Search {
            bracket: BRACKET.to_vec(),
            steps: GOLDEN_STEPS,
        }
    }
}

/// [`profile`] with any pooled fit: `fit(model at trial shape values)`.
///
/// Long: sweeps over the shape values, each a one-dimensional search, share the trials and
/// the best fit so far.
pub fn profile_with<E>(
    ir: &ModelIr,
    search: &Search,
    fit_at: &(dyn Fn(&ModelIr) -> Result<Identification, E> + Sync),
) -> Result<(ModelIr, Identification), E> {
    let n = ir.shapes.len();
    let mut values: Vec<f64> = ir.shapes.iter().map(|s| s.nominal).collect();
    let mut trials: Vec<Vec<(f64, f64)>> = vec![Vec::new(); n];
    let mut edge = vec![false; n];
    // The first solve at the starting values: its error (bad data) is the caller's error.
    let fit = |values: &[f64]| fit_at(&ir.with_shapes(values));
    let start = fit(&values)?;
    let mut best = start.ssr;
    let sweeps = if n > 1 { 2 } else { 1 };
    for _ in 0..sweeps {
        for k in 0..n {
            let mut cost = |v: f64, values: &[f64]| -> f64 {
                let mut trial = values.to_vec();
                trial[k] = v;
                let s = fit(&trial).map(|f| f.ssr).unwrap_or(f64::INFINITY);
                let s = if s.is_finite() { s } else { f64::INFINITY };
                trials[k].push((v, s));
                s
            };
            let centre = values[k];
            let grid: Vec<(f64, f64)> = search
                .bracket
                .iter()
                .map(|f| {
                    let v = centre * f;
                    (v, cost(v, &values))
                })
                .collect();
            let i = (0..grid.len())
                .min_by(|&a, &b| grid[a].1.total_cmp(&grid[b].1))
                .unwrap_or(grid.len() / 2);
            edge[k] = i == 0 || i + 1 == grid.len();
            let (mut lo, mut hi) = (
                grid[i.saturating_sub(1)].0.ln(),
                grid[(i + 1).min(grid.len() - 1)].0.ln(),
            );
            let phi = 0.5 * (5f64.sqrt() - 1.0);
            let mut x1 = hi - phi * (hi - lo);
            let mut x2 = lo + phi * (hi - lo);
            let mut f1 = cost(x1.exp(), &values);
            let mut f2 = cost(x2.exp(), &values);
            for _ in 0..search.steps {
                if f1 <= f2 {
                    hi = x2;
                    x2 = x1;
                    f2 = f1;
                    x1 = hi - phi * (hi - lo);
                    f1 = cost(x1.exp(), &values);
                } else {
                    lo = x1;
                    x1 = x2;
                    f1 = f2;
                    x2 = lo + phi * (hi - lo);
                    f2 = cost(x2.exp(), &values);
                }
            }
            // The best value seen (a grid point may beat the golden-section ends).
            let (v, s) = trials[k]
                .iter()
                .copied()
                .filter(|t| t.1.is_finite())
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((centre, f64::INFINITY));
            if s < best {
                best = s;
                values[k] = v;
            }
        }
    }
    let at = ir.with_shapes(&values);
    let mut id = fit(&values)?;
    let unknowns = id.params.len();
    let dof = id.rows.saturating_sub(unknowns + n).max(1) as f64;
    let sigma2 = id.ssr / dof;
    let mut slopes: Vec<Vec<f64>> = Vec::with_capacity(n);
    id.shapes = (0..n)
        .map(|k| {
            let v = values[k];
            let h = 0.01 * v.abs();
            let side = |d: f64| {
                let mut t = values.clone();
                t[k] = v + d;
                fit(&t).ok()
            };
            let (up, down) = (side(h), side(-h));
            let ssr = |f: &Option<Identification>| f.as_ref().map_or(f64::NAN, |f| f.ssr);
            let curvature = (ssr(&up) - 2.0 * id.ssr + ssr(&down)) / (h * h);
            let stderr = (!edge[k] && curvature.is_finite() && curvature > 0.0 && h > 0.0)
                .then(|| (2.0 * sigma2 / curvature).sqrt())
                .filter(|s| s.is_finite());
            // How each linear estimate moves with the shape value along the profile.
            slopes.push(
                id.params
                    .iter()
                    .map(|p| {
                        let at = |f: &Option<Identification>| {
                            f.as_ref()
                                .and_then(|f| f.param(&p.name))
                                .map_or(f64::NAN, |e| e.value)
                        };
                        (at(&up) - at(&down)) / (2.0 * h)
                    })
                    .collect(),
            );
            ShapeEstimate {
                name: ir.shapes[k].name.clone(),
                value: v,
                stderr,
                profile: std::mem::take(&mut trials[k]),
                slopes: slopes.last().cloned().unwrap_or_default(),
                leave_out: Vec::new(),
            }
        })
        .collect();
    // The linear estimates' errors include the shape's (delta method along the profile):
    // the solve's own standard error is conditional on the shape value.
    let spreads: Vec<f64> = id
        .shapes
        .iter()
        .map(|sh| sh.stderr.unwrap_or(0.0))
        .collect();
    for (e, sl) in spreads.iter().zip(&slopes) {
        id.widen(sl, e * e);
    }
    Ok((at, id))
}
