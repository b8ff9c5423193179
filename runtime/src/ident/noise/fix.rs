//! The noise corrections as the plan stores them: the extra columns of `w` they need
//! ([`ExtraColumn`], filled per sample by [`fill_extra`]) and the fix of each static column
//! ([`ColumnFix`]); with the reading of a term as a constant times a linear form in
//! signals, which decides whether a term can be corrected.
//!
//! This module depends on the model alone, so that the plan can hold its types without
//! depending on the rest of the correction.

use dynid_ir::ir::{BinaryOp, ExprId, ExprNode, ModelIr, SignalId, UnaryOp};

/// A combination `Σ aⱼ wⱼ` of columns of `w`: pairs `(column, aⱼ)`.
pub(crate) type ColumnCombination = Vec<(usize, f64)>;

/// An extra column of `w` (after the static roots and the measured signals), computed per
/// sample from the measured signals.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum ExtraColumn {
    /// The constant 1 (for `s⁰` in an even Hermite polynomial).
    One,
    /// `v φ_h(v)/h²` with `v = Σ aₖ yₖ` (pairs of index into `y` and coefficient) and the
    /// kernel width `h` given per level as this multiple of the noise std of `v`.
    SignSlope(Vec<(usize, f64)>, f64),
}

/// How one static column's moments are corrected.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ColumnFix {
    /// The column of `w`.
    pub col: usize,
    /// The linear form inside the term: (index into `y`, coefficient).
    pub lin: Vec<(usize, f64)>,
    pub kind: FixKind,
    /// The term as written, for the report.
    pub label: String,
}

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum FixKind {
    /// Add `Σₘ coef(m) σ²ᵐ ⟨ι · comb⟩` for each `(m, coef, comb over w)`.
    Hermite(Vec<(i32, f64, ColumnCombination)>),
    /// Add `factor σ² Σ cⱼ ⟨ι · w[slopeⱼ]⟩` for the `(slope column, cⱼ)` pairs.
    Sign {
        factor: f64,
        slopes: Vec<(usize, f64)>,
    },
}
/// `e` as a constant factor times a core expression.
pub(crate) fn split_factor(ir: &ModelIr, e: ExprId) -> (f64, ExprId) {
    match ir.exprs[e.index()] {
        ExprNode::Unary(UnaryOp::Neg, a) => {
            let (f, c) = split_factor(ir, a);
            (-f, c)
        }
        ExprNode::Binary(BinaryOp::Mul, a, b) => match (ir.exprs[a.index()], ir.exprs[b.index()]) {
            (ExprNode::Const(c), _) => {
                let (f, core) = split_factor(ir, b);
                (f64::from_bits(c) * f, core)
            }
            (_, ExprNode::Const(c)) => {
                let (f, core) = split_factor(ir, a);
                (f64::from_bits(c) * f, core)
            }
            _ => (1.0, e),
        },
        _ => (1.0, e),
    }
}

/// `e` as a linear form `Σ aₖ sₖ` in signals (no constant offset), if it is one.
pub(crate) fn linear_form(ir: &ModelIr, e: ExprId) -> Option<Vec<(SignalId, f64)>> {
    let scale = |v: Vec<(SignalId, f64)>, f: f64| v.into_iter().map(|(s, a)| (s, a * f)).collect();
    match ir.exprs[e.index()] {
        ExprNode::Signal(s) => Some(vec![(s, 1.0)]),
        ExprNode::Unary(UnaryOp::Neg, a) => Some(scale(linear_form(ir, a)?, -1.0)),
        ExprNode::Binary(op, a, b) => {
            let (na, nb) = (ir.exprs[a.index()], ir.exprs[b.index()]);
            match op {
                BinaryOp::Add | BinaryOp::Sub => {
                    let mut out = linear_form(ir, a)?;
                    let sign = if op == BinaryOp::Add { 1.0 } else { -1.0 };
                    for (s, c) in linear_form(ir, b)? {
                        match out.iter_mut().find(|(t, _)| *t == s) {
                            Some(e) => e.1 += sign * c,
                            None => out.push((s, sign * c)),
                        }
                    }
                    out.retain(|(_, c)| *c != 0.0);
                    Some(out)
                }
                BinaryOp::Mul => match (na, nb) {
                    (ExprNode::Const(c), _) => Some(scale(linear_form(ir, b)?, f64::from_bits(c))),
                    (_, ExprNode::Const(c)) => Some(scale(linear_form(ir, a)?, f64::from_bits(c))),
                    _ => None,
                },
                BinaryOp::Div => match nb {
                    ExprNode::Const(c) if f64::from_bits(c) != 0.0 => {
                        Some(scale(linear_form(ir, a)?, 1.0 / f64::from_bits(c)))
                    }
                    _ => None,
                },
            }
        }
        _ => None,
    }
}
/// Noise variance of each fix's linear form, from the per-signal variances of `y`.
pub(crate) fn form_variance(lin: &[(usize, f64)], var_y: &[f64]) -> f64 {
    lin.iter().map(|&(k, a)| a * a * var_y[k]).sum()
}

/// Fill the extra columns for `len` samples: `out[k * len + i]` is extra column `k` at
/// sample `i`; `ys[k]` is measured signal `k`; `width[k]` is the kernel width of extra
/// column `k` (unused for the constant).
pub(crate) fn fill_extra(
    extra: &[ExtraColumn],
    width: &[f64],
    ys: &[&[f64]],
    len: usize,
    out: &mut [f64],
) {
    let c = 1.0 / (2.0 * std::f64::consts::PI).sqrt();
    for (k, e) in extra.iter().enumerate() {
        let dst = &mut out[k * len..(k + 1) * len];
        match e {
            ExtraColumn::One => dst.fill(1.0),
            ExtraColumn::SignSlope(lin, _) => {
                let h = width[k];
                let (a, b) = (c / (h * h * h), -0.5 / (h * h));
                dst.fill(0.0);
                for &(j, coef) in lin {
                    for (d, y) in dst.iter_mut().zip(&ys[j][..len]) {
                        *d += coef * y;
                    }
                }
                for d in dst.iter_mut() {
                    *d *= a * (b * *d * *d).exp();
                }
            }
        }
    }
}
