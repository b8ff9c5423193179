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

use super::moments::LevelMoments;
use super::solve::LsSolution;
use super::{ParamEstimate, SIGNIFICANCE_T};
use dynid_ir::ir::{ElementKind, ExprNode, ModelIr, UnaryOp};
use serde::Serialize;

/// Standard errors of the active columns of `sol` (see the module doc). `hats[pos]` holds
/// the unweighted rows `(C, c)` (all `ncol` columns, held ones already moved) of every hat
/// window of the `pos`-th level; `levels` are the matching moments.
pub(crate) fn sandwich_stderr<'a>(
    sol: &LsSolution,
    active: &[usize],
    ncol: usize,
    nr: usize,
    weights: &[f64],
    hats: &[Vec<(Vec<f64>, Vec<f64>)>],
    levels: impl Iterator<Item = &'a LevelMoments>,
) -> Vec<f64> {
    let na = active.len();
    let rows = weights.len();
    let mut var = vec![0.0; na];
    let mut var_bartlett = vec![0.0; na];
    for (pos, (lm, hat_rows)) in levels.zip(hats).enumerate() {
        let h: Vec<Vec<f64>> = hat_rows
            .iter()
            .map(|(c, r)| {
                (0..nr)
                    .map(|i| {
                        let fit: f64 = active
                            .iter()
                            .enumerate()
                            .map(|(k, &j)| c[i * ncol + j] * sol.x[k])
                            .sum();
                        weights[pos * nr + i] * (fit - r[i])
                    })
                    .collect()
            })
            .collect();
        let e: Vec<f64> = (0..nr).map(|i| h.iter().map(|hj| hj[i]).sum()).collect();
        let u: Vec<Vec<f64>> = h
            .iter()
            .enumerate()
            .map(|(j, hj)| {
                let wj = lm.hat_weight(j);
                (0..na)
                    .map(|k| {
                        let p = &sol.pinv[k * rows + pos * nr..k * rows + (pos + 1) * nr];
                        p.iter()
                            .zip(hj.iter().zip(&e))
                            .map(|(p, (h, e))| p * (h - wj * e))
                            .sum()
                    })
                    .collect()
            })
            .collect();
        let nb = lm.n_blocks() as f64;
        let dof = nb / (nb - 1.0).max(1.0);
        for k in 0..na {
            let s0: f64 = u.iter().map(|x| x[k] * x[k]).sum();
            let s1: f64 = u.windows(2).map(|w| w[0][k] * w[1][k]).sum();
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
