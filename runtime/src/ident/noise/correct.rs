//! The noise correction applied: fixes attached to the plan for the terms that can be
//! corrected, the kernel widths of the extra columns per level, and the accumulated moments
//! de-biased block by block (see the module documentation of [`super`]).

use super::fix::{
    form_variance, linear_form, split_factor, ColumnCombination, ColumnFix, ExtraColumn, FixKind,
};
use crate::ident::filter::{ChainDisc, Hold};
use crate::ident::moments::LevelMoments;
use crate::ident::plan::{BasisMoment, Plan};
use dynid_ir::ir::{ExprNode, ModelIr, SignalId, UnaryOp};

/// Kernel widths (relative to the noise std) and weights of the sign correction: the
/// Richardson combination `2 E(σ/2) − E(σ)` (see the module documentation).
const SIGN_WIDTHS: [(f64, f64); 2] = [(0.5, 2.0), (1.0, -1.0)];
/// `n!`.
fn factorial(n: i32) -> f64 {
    (1..=n).map(f64::from).product()
}

/// Add the noise corrections to a plan: the fixes per static column and the extra
/// columns they need. The snapshot columns of the end-point velocities (after `w`) are
/// shifted by the number of extra columns.
///
/// Long: one walk over the static roots builds each fix together with the extra columns it
/// needs, whose indices the later fixes read.
///
/// Rows of the filtered equation take a nonlinear column only through the chain it drives
/// (`F g`, not `g` in a product), which these fixes of `g`'s products do not reach: none is
/// attached there, and the report names such terms uncorrected. Their linear terms are
/// freed of the noise in [`debias`].
pub(crate) fn attach(plan: &mut Plan, ir: &ModelIr) {
    if plan.filtered {
        return;
    }
    let n_g = plan.roots.len();
    let ny = plan.y.len();
    let to_y = |lin: &[(SignalId, f64)]| -> Option<Vec<(usize, f64)>> {
        lin.iter()
            .map(|&(s, a)| plan.y_of[s.index()].map(|k| (k, a)))
            .collect()
    };
    // Roots that are (factor ·) a power of a linear form: (root, factor, form, power).
    let mut powers = Vec::new();
    for (j, &r) in plan.roots.iter().enumerate() {
        let (f, core) = split_factor(ir, r);
        if let ExprNode::Powi(a, p) = ir.exprs[core.index()] {
            if let Some(lin) = linear_form(ir, a).and_then(|l| to_y(&l)) {
                powers.push((j, f, lin, p));
            }
        }
    }
    let same = |a: &[(usize, f64)], b: &[(usize, f64)]| {
        a.len() == b.len()
            && a.iter().all(|(k, c)| {
                b.iter()
                    .any(|(l, d)| l == k && (c - d).abs() <= 1e-12 * c.abs())
            })
    };
    let mut fixes = Vec::new();
    let mut extra: Vec<ExtraColumn> = Vec::new();
    let extra_col = |e: ExtraColumn, extra: &mut Vec<ExtraColumn>| {
        let k = match extra.iter().position(|x| *x == e) {
            Some(k) => k,
            None => {
                extra.push(e);
                extra.len() - 1
            }
        };
        n_g + ny + k
    };
    for (j, &r) in plan.roots.iter().enumerate() {
        let label = dynid_ir::print::render_expr(ir, r);
        let (f, core) = split_factor(ir, r);
        match ir.exprs[core.index()] {
            ExprNode::Powi(_, p) if p >= 2 => {
                let Some((_, _, lin, _)) = powers.iter().find(|(c, ..)| *c == j).cloned() else {
                    continue;
                };
                let mut terms = Vec::new();
                let mut ok = true;
                for m in 1..=p / 2 {
                    let q = p - 2 * m;
                    let coef = f * (-1f64).powi(m) * factorial(p)
                        / (factorial(m) * factorial(q) * 2f64.powi(m));
                    let comb: ColumnCombination = match q {
                        0 => vec![(extra_col(ExtraColumn::One, &mut extra), 1.0)],
                        1 => lin.iter().map(|&(k, a)| (n_g + k, a)).collect(),
                        _ => match powers
                            .iter()
                            .find(|(_, _, l, pp)| *pp == q && same(l, &lin))
                        {
                            Some(&(c, fc, _, _)) => vec![(c, 1.0 / fc)],
                            None => {
                                ok = false;
                                break;
                            }
                        },
                    };
                    terms.push((m, coef, comb));
                }
                if ok {
                    fixes.push(ColumnFix {
                        col: j,
                        lin,
                        kind: FixKind::Hermite(terms),
                        label,
                    });
                }
            }
            ExprNode::Unary(UnaryOp::Sign, a) => {
                if let Some(lin) = linear_form(ir, a).and_then(|l| to_y(&l)) {
                    let slopes = SIGN_WIDTHS
                        .iter()
                        .map(|&(h, c)| {
                            let col = extra_col(ExtraColumn::SignSlope(lin.clone(), h), &mut extra);
                            (col, c)
                        })
                        .collect();
                    fixes.push(ColumnFix {
                        col: j,
                        lin,
                        kind: FixKind::Sign { factor: f, slopes },
                        label,
                    });
                }
            }
            _ => {}
        }
    }
    let shift = extra.len();
    for eq in &mut plan.equations {
        for t in eq.iter_mut() {
            if let BasisMoment::D2Pos(x, q) = t.basis {
                t.basis = BasisMoment::D2Pos(x, q + shift);
            }
        }
    }
    plan.extra = extra;
    plan.fixes = fixes;
    plan.linear_roots = plan
        .roots
        .iter()
        .enumerate()
        .filter_map(|(j, &r)| {
            let (f, core) = split_factor(ir, r);
            let lin = linear_form(ir, core).and_then(|l| to_y(&l))?;
            Some((j, lin.into_iter().map(|(k, a)| (k, f * a)).collect()))
        })
        .collect();
}

/// Static roots that are nonlinear in some signal of `noisy` and have no fix: their labels.
pub(crate) fn uncorrected(plan: &Plan, ir: &ModelIr, noisy: &[SignalId]) -> Vec<String> {
    plan.roots
        .iter()
        .enumerate()
        .filter(|(j, _)| !plan.fixes.iter().any(|f| f.col == *j))
        .filter(|(_, &r)| linear_form(ir, split_factor(ir, r).1).is_none())
        .filter(|(_, &r)| ir.expr_signals(r).iter().any(|s| noisy.contains(s)))
        .map(|(_, &r)| dynid_ir::print::render_expr(ir, r))
        .collect()
}
/// Kernel widths of the extra columns at one level: the noise std of the linear form, or
/// for a signal without significant noise a small fraction of its spread (the column is
/// then unused).
pub(crate) fn extra_widths(plan: &Plan, var_y: &[f64], std_y: &[f64]) -> Vec<f64> {
    plan.extra
        .iter()
        .map(|e| match e {
            ExtraColumn::One => 1.0,
            ExtraColumn::SignSlope(lin, rel) => {
                let s = rel * form_variance(lin, var_y).sqrt();
                let spread =
                    form_variance(lin, &std_y.iter().map(|s| s * s).collect::<Vec<_>>()).sqrt();
                if s > 0.0 && s.is_finite() {
                    s
                } else if spread > 0.0 {
                    0.01 * spread
                } else {
                    1.0
                }
            }
        })
        .collect()
}

/// Apply the fixes to the accumulated moments of one level, with the noise variance of each
/// measured signal (zero for signals left uncorrected). Returns the labels of the fixes that
/// changed something.
pub(crate) fn debias(plan: &Plan, lm: &mut LevelMoments, var_y: &[f64], hold: Hold) -> Vec<String> {
    let (n_row_signals, n_col_signals, n_snap_cols) =
        (lm.n_row_signals, lm.n_col_signals, lm.n_snap_cols);
    let n_g = plan.roots.len();
    // Per noisy driver and corner, two corrections of the products with the driver's chain:
    // - first-order hold: a filter state holds its driver's current sample with weight Γ₁,
    //   so its product with a column linear in that driver gains Γ₁ σ² per sample;
    // - rows of the filtered equation (`plan.state_cols`): products of two states of one
    //   chain gain σ² Pᵢⱼ per sample (P: [`ChainDisc::noise_covariance`]), whatever the
    //   signal does.
    let noisy = |sig: SignalId| plan.y_of[sig.index()].filter(|&k| var_y[k] > 0.0);
    if plan.drivers.iter().any(|&sig| noisy(sig).is_some()) {
        let discs: Vec<ChainDisc> = plan
            .corners
            .iter()
            .map(|&lam| ChainDisc::new(lam, plan.order, lm.ts, hold))
            .collect();
        let covs: Vec<Vec<f64>> = if plan.state_cols.is_empty() {
            Vec::new()
        } else {
            discs.iter().map(ChainDisc::noise_covariance).collect()
        };
        for (d, &sig) in plan.drivers.iter().enumerate() {
            let Some(k) = noisy(sig) else {
                continue;
            };
            let mut cols = vec![(n_g + k, 1.0)];
            for (j, lin) in &plan.linear_roots {
                if let Some(&(_, a)) = lin.iter().find(|(y, _)| *y == k) {
                    cols.push((*j, a));
                }
            }
            for (c, disc) in discs.iter().enumerate() {
                for (i, g) in disc.g1.iter().enumerate() {
                    let row = plan.state(d, c, i);
                    for &(col, a) in &cols {
                        for (sum, &len) in lm.sums.iter_mut().zip(&lm.lens) {
                            sum[row * n_col_signals + col] -= a * g * var_y[k] * len as f64;
                        }
                    }
                }
                let Some(p) = covs.get(c) else {
                    continue;
                };
                for i in 0..plan.order {
                    for j in 0..plan.order {
                        let Some(col) = plan.state_col(plan.state(d, c, j)) else {
                            continue;
                        };
                        let row = plan.state(d, c, i);
                        let bias = p[i * plan.order + j] * var_y[k];
                        for (sum, &len) in lm.sums.iter_mut().zip(&lm.lens) {
                            sum[row * n_col_signals + col] -= bias * len as f64;
                        }
                    }
                }
            }
        }
    }
    let mut used = Vec::new();
    // (column, [(w column, weight)]) with all weights computed from the raw moments.
    let mut updates: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
    for f in &plan.fixes {
        let s2 = form_variance(&f.lin, var_y);
        if s2 <= 0.0 {
            continue;
        }
        let mut add = Vec::new();
        match &f.kind {
            FixKind::Hermite(terms) => {
                for (m, coef, comb) in terms {
                    let w = coef * s2.powi(*m);
                    add.extend(comb.iter().map(|&(c, a)| (c, a * w)));
                }
            }
            FixKind::Sign { factor, slopes } => {
                add.extend(slopes.iter().map(|&(c, w)| (c, w * factor * s2)))
            }
        }
        updates.push((f.col, add));
        used.push(f.label.clone());
    }
    if updates.is_empty() {
        return used;
    }
    let apply = |m: &mut [f64], stride: usize| {
        for i in 0..n_row_signals {
            let row = &mut m[i * stride..(i + 1) * stride];
            let raw: Vec<f64> = updates
                .iter()
                .map(|(col, add)| row[*col] + add.iter().map(|&(c, a)| a * row[c]).sum::<f64>())
                .collect();
            for ((col, _), v) in updates.iter().zip(raw) {
                row[*col] = v;
            }
        }
    };
    for s in &mut lm.sums {
        apply(s, n_col_signals);
    }
    for s in &mut lm.snaps {
        apply(s, n_snap_cols);
    }
    used
}
