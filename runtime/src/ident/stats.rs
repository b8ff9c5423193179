//! Standard errors of the pooled estimate and physical plausibility of the estimates.
//!
//! # Batch-means sandwich
//!
//! The estimate solves `min ‖A p − b‖` with `A = W C`, `b = W c` (row weights `W`), so a
//! perturbation `δr` of the residual rows at fixed `p` moves it by `−A⁺ δr`. The residual
//! rows of level `l` are the sum of the contributions `h_lj` of its hat windows `φ_j`
//! (see the `moments` module; every `h_lj` is the residual of an exact estimating equation
//! on its window, with no interior point values of a velocity). With `d_lj = h_lj − w_lj e_l`
//! (`w_lj = ∫ φ_j / T`, `e_l = Σ_j h_lj`) and `u_lj = A⁺_l d_lj` (`A⁺_l` the columns of `A⁺`
//! of level `l`'s rows),
//!
//! ```text
//! Var p̂_k = Σ_l B/(B−1) · ( Σ_j u_ljk² + 2 Σ_j u_ljk u_l(j+1)k ).
//! ```
//!
//! Levels are independent (block-diagonal `Ŝ`). Neighbouring hats overlap by one block, so
//! their contributions are correlated (for a short-memory integrand the covariance is ¼ of
//! the variance); the lag-one cross terms with weight one make the estimate unbiased for
//! that, and no other pair overlaps. Should a parameter's sum come out negative (a very
//! short record), the Bartlett weight ½, which is never negative, is used for it instead.
//! The expression is a sum of per-level terms, so duplicating every level halves every
//! variance exactly.
//!
//! # Physical plausibility
//!
//! A parameter's physical meaning is read from the IR: the coefficient of a body's mass, of
//! the relative velocity `v` of a damper or force element (damping), of `sign(v)`
//! (friction) or of the relative displacement `s` of a spring or force element (stiffness).
//! Each must be non-negative (its `scale · value`, the coefficient as it enters the
//! equation). A negative one is reported: as unphysical when it lies more than
//! [`SIGNIFICANCE_T`] standard errors below zero, else as a negative estimate consistent
//! with zero — the term is not shown by the data, which is not a contradiction.

use super::columns::Column;
use super::moments::LevelMoments;
use super::solve::LsSolution;
use super::{ParamEstimate, SIGNIFICANCE_T};
use dynid_ir::ir::{ElementKind, ExprNode, ModelIr, UnaryOp};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use serde::Serialize;
use std::sync::Arc;

/// Standard errors of the active columns of `sol` (see the module doc). The rows of the
/// hat windows are read from the model's `columns` (its unknowns, then the right-hand
/// side) at the levels `which` (moments `levels`), with the `held` columns at their
/// values; `weights` are the row weights of the stacked problem (`nr` rows per level).
#[allow(clippy::too_many_arguments)]
pub(crate) fn sandwich_stderr(
    sol: &LsSolution,
    active: &[usize],
    held: &[(usize, f64)],
    nr: usize,
    weights: &[f64],
    columns: &[Arc<Column>],
    which: &[usize],
    levels: &[LevelMoments],
) -> Vec<f64> {
    let na = active.len();
    let rows = weights.len();
    let rhs = &columns[columns.len() - 1];
    let mut var = vec![0.0; na];
    let mut var_bartlett = vec![0.0; na];
    let mut d = Vec::new();
    for (pos, &i) in which.iter().enumerate() {
        let lm = &levels[i];
        let nh = lm.n_blocks() + 1;
        let w = &weights[pos * nr..(pos + 1) * nr];
        // d_j = h_j − w_j e, h_j = W (C_j p − c_j): one row per hat window.
        d.clear();
        d.resize(nh * nr, 0.0);
        for (j, dj) in d.chunks_exact_mut(nr).enumerate() {
            dj.iter_mut()
                .zip(&rhs[i].hats[j])
                .for_each(|(x, c)| *x = -c);
            let terms = active
                .iter()
                .enumerate()
                .map(|(k, &c)| (c, sol.x[k]))
                .chain(held.iter().copied());
            for (c, v) in terms {
                dj.iter_mut()
                    .zip(&columns[c][i].hats[j])
                    .for_each(|(x, a)| *x += v * a);
            }
            dj.iter_mut().zip(w).for_each(|(x, w)| *x *= w);
        }
        let mut e = vec![0.0; nr];
        for dj in d.chunks_exact(nr) {
            e.iter_mut().zip(dj).for_each(|(e, h)| *e += h);
        }
        for (j, dj) in d.chunks_exact_mut(nr).enumerate() {
            let wj = lm.hat_weight(j);
            dj.iter_mut().zip(&e).for_each(|(x, e)| *x -= wj * e);
        }
        // u_j = A⁺_l d_j for every window at once: U = D A⁺_lᵀ (`nh × na`).
        // shape: `u` is created here as `nh × na` and read for `j < nh`, `k < na`; `sol` is
        // the solution of the `na` active columns over `which.len() · nr = rows` rows.
        let mut u = Mat::<f64>::zeros(nh, na);
        if na > 0 && nr > 0 {
            let dm = MatRef::from_row_major_slice(&d[..], nh, nr);
            let pl = MatRef::from_row_major_slice_with_stride(&sol.pinv[pos * nr..], na, nr, rows);
            matmul(
                u.as_mut(),
                Accum::Replace,
                dm,
                pl.transpose(),
                1.0,
                Par::Seq,
            );
        }
        let nb = lm.kept_blocks() as f64;
        let dof = nb / (nb - 1.0).max(1.0);
        for k in 0..na {
            let s0: f64 = (0..nh).map(|j| u[(j, k)] * u[(j, k)]).sum();
            let s1: f64 = (1..nh).map(|j| u[(j - 1, k)] * u[(j, k)]).sum();
            var[k] += dof * (s0 + 2.0 * s1);
            var_bartlett[k] += dof * (s0 + s1);
        }
    }
    var.iter()
        .zip(&var_bartlett)
        .map(|(&v, &vb)| {
            if v > 0.0 {
                v.sqrt()
            } else {
                vb.max(0.0).sqrt()
            }
        })
        .collect()
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
    /// More than [`SIGNIFICANCE_T`] standard errors below zero: the fit contradicts physics
    /// (else the estimate is consistent with zero).
    pub unphysical: bool,
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// The physical kind of parameter `name` and the scale it enters with, from the IR.
pub(crate) fn quantity_of(ir: &ModelIr, name: &str) -> Option<(Quantity, f64)> {
    let p = ir.params.iter().position(|q| q.name == name)?;
    let is_p = |c: &dynid_ir::ir::Coef| c.param.map(|q| q.index()) == Some(p);
    if let Some(b) = ir.bodies.iter().find(|b| is_p(&b.mass)) {
        return Some((Quantity::Mass, b.mass.scale));
    }
    for el in &ir.elements {
        for t in el.terms.iter().filter(|t| is_p(&t.coef)) {
            let q = if t.basis == el.v && el.kind != ElementKind::Spring {
                Quantity::Damping
            } else if t.basis == el.s && el.kind != ElementKind::Damper {
                Quantity::Stiffness
            } else if ir.expr(t.basis) == ExprNode::Unary(UnaryOp::Sign, el.v) {
                Quantity::Friction
            } else {
                continue;
            };
            return Some((q, t.coef.scale));
        }
    }
    None
}

/// Warnings for the estimates that are negative where physics says non-negative.
pub(crate) fn physical_warnings(ir: &ModelIr, params: &[ParamEstimate]) -> Vec<Warning> {
    params
        .iter()
        .filter_map(|p| {
            let (quantity, scale) = quantity_of(ir, &p.name)?;
            let coefficient = scale * p.value;
            let stderr = scale.abs() * p.stderr;
            // Non-negative (or NaN, which is never printed as a result): nothing to say.
            if coefficient >= 0.0 || coefficient.is_nan() {
                return None;
            }
            let unphysical = coefficient < -SIGNIFICANCE_T * stderr;
            let message = if unphysical {
                format!(
                    "`{}` = {:.4e} ± {:.1e} is a negative {quantity}, {:.1} standard errors \
                     below zero: unphysical — check the model's structure, sign conventions \
                     and units",
                    p.name,
                    p.value,
                    p.stderr,
                    -coefficient / stderr.max(f64::MIN_POSITIVE)
                )
            } else {
                format!(
                    "`{}` = {:.4e} ± {:.1e} is a negative {quantity} but within {} standard \
                     errors of zero: the data do not show this term",
                    p.name, p.value, p.stderr, SIGNIFICANCE_T
                )
            };
            Some(Warning {
                param: p.name.clone(),
                quantity,
                coefficient,
                stderr,
                unphysical,
                message,
            })
        })
        .collect()
}
