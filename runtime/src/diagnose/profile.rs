//! The gap of an accepted backlash, profiled instead of gridded.
//!
//! The search scores backlash candidates on a grid of gaps (multiples of the location's
//! `σ_s`, refined once); the gap enters the model nonlinearly, so a grid point leaves the
//! backlash stiffness biased by however far it lies from the gap the data carry. Once a
//! backlash is accepted its gap becomes a shape parameter of the model
//! (`deadzone(s, g_fix ~ …)`) and is estimated by variable projection over the covariance
//! least squares ([`crate::ident::shape`]): on all levels for the corrected model, with a
//! standard error (the larger of the profile's curvature and the leave-one-level-out
//! spread), and, for the withheld scores, on each fold's training levels only — the
//! leave-one-level-out profiles of that jackknife — so the withheld level never informs
//! the gap it is scored with.

use super::fit::measure_all;
use super::levels::{sources, training, Data};
use super::score::cv_gap_by;
use super::types::{DiagnoseOptions, ModelGap};
use crate::data::LevelSource;
use crate::ident::{shape, Identification};
use dynid_ir::ir::{ExprId, ExprNode, ModelIr, ShapeIr};

/// An accepted backlash at its profiled gap.
pub(super) struct Profiled {
    /// The gap on all levels and its standard error.
    pub gap: f64,
    pub stderr: Option<f64>,
    /// The model with the gap as a shape parameter at its estimate.
    pub ir: ModelIr,
    /// The identification on all levels at that gap, as the search identifies (pruned).
    pub fit: Identification,
    /// The profile's own identification on all levels: its standard errors include the
    /// gap's, carried along the profile.
    pub profile_fit: Identification,
    /// Per withheld level: the fit on the training levels at their own profiled gap.
    pub fits: Vec<Identification>,
    /// The withheld free-run gap of those fits.
    pub model_gap: ModelGap,
}

/// Profile the gap of the backlash just added to `ir` (its newest `deadzone` node with the
/// grid gap `grid`). The model's unknowns stay as they are; the gap becomes the shape
/// parameter `g_fix` (or the next free name).
pub(super) fn profile_gap(
    ir: &ModelIr,
    grid: f64,
    data: &Data,
    opts: &DiagnoseOptions,
    label: &str,
) -> Result<Profiled, String> {
    let site = ir
        .exprs
        .iter()
        .rposition(|e| matches!(e, ExprNode::Deadzone(_, g) if *g == grid.to_bits()))
        .map(|k| ExprId(k as u32))
        .ok_or("the backlash term is not in the model")?;
    let mut shaped = ir.clone();
    shaped.shapes.push(ShapeIr {
        name: shaped.fresh_name("g_fix"),
        nominal: grid,
        sites: vec![site],
    });
    let k = shaped.shapes.len() - 1;
    let srcs = sources(&shaped, data).map_err(|e| e.to_string())?;
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let (_, all) = shape::profile(&shaped, &levels, &opts.ident).map_err(|e| e.to_string())?;
    let values = |k_value: f64| -> Vec<f64> {
        let mut v: Vec<f64> = all.shapes.iter().map(|s| s.value).collect();
        v[k] = k_value;
        v
    };
    let est = &all.shapes[k];
    let n = data.records.len();
    // The model at a gap, measured on every level (the search's own identification: pruning
    // as in the search, see `measure_all`).
    let fit_at = |g: f64, which: &[usize]| -> Result<(ModelIr, Identification), String> {
        let at = shaped.with_shapes(&values(g));
        let m = measure_all(&at, data, opts).map_err(|e| e.to_string())?;
        let fit = m.identify_levels(which);
        Ok((at, fit))
    };
    let (at, fit) = fit_at(est.value, &(0..n).collect::<Vec<_>>())?;
    // Each fold's gap from its training levels alone.
    let mut irs = Vec::with_capacity(n);
    let mut fits = Vec::with_capacity(n);
    for w in 0..n {
        let g = if est.leave_out.len() == n {
            est.leave_out[w]
        } else {
            let rest: Vec<&dyn LevelSource> = training(n, w).iter().map(|&i| levels[i]).collect();
            let (_, sub) =
                shape::profile(&shaped, &rest, &opts.ident).map_err(|e| e.to_string())?;
            sub.shapes[k].value
        };
        let (ir_w, fit_w) = fit_at(g, &training(n, w))?;
        irs.push(ir_w);
        fits.push(fit_w);
    }
    let model_gap = cv_gap_by(&|w| &irs[w], &fits, data, opts, label);
    Ok(Profiled {
        gap: est.value,
        stderr: est.stderr,
        ir: at,
        fit,
        profile_fit: all.clone(),
        fits,
        model_gap,
    })
}
