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
use super::types::SIGNIFICANCE_T;
use super::types::{ParamEstimate, Quantity, Warning};
use dynid_ir::ir::{ElementKind, ExprNode, ModelIr, UnaryOp};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use std::sync::Arc;

/// The centred window contributions of one level's residual rows (see the module doc):
/// `d_j = M W (h_j − w_j e)`, `nh × n` row-major (`n` rows after the mixing `M`, where
/// one is given), with the level's degrees-of-freedom factor `B/(B−1)`.
pub(crate) struct LevelWindows {
    pub d: Vec<f64>,
    pub nh: usize,
    pub dof: f64,
}

impl LevelWindows {
    /// The estimated variance of each of the level's `nr` rows, `B/(B−1) Σ_j (d_jr² +
    /// d_jr d_(j+1)r)`: the unbiased lag-one weight of the batch-means sandwich (module
    /// doc), at least zero.
    pub fn row_variances(&self, nr: usize) -> Vec<f64> {
        // shape: `d` holds `nh × nr` entries (see `covariance`).
        (0..nr)
            .map(|r| {
                let at = |j: usize| self.d[j * nr + r];
                let s0: f64 = (0..self.nh).map(|j| at(j) * at(j)).sum();
                let s1: f64 = (1..self.nh).map(|j| at(j - 1) * at(j)).sum();
                self.dof * (s0 + s1).max(0.0)
            })
            .collect()
    }

    /// The long-run covariance of the level's rows, `B/(B−1) Σ_j (d_j d_jᵀ + ½ (d_j
    /// d_{j+1}ᵀ + d_{j+1} d_jᵀ))` (`nr × nr`): the Bartlett weight ½ on the lag-one terms
    /// keeps it positive semi-definite, as a weighting matrix must be.
    pub fn covariance(&self, nr: usize) -> Mat<f64> {
        // shape: `d` holds `nh × nr` entries — `level_windows` builds it with the `nr` rows
        // per level its callers pass here too; `s` and `c` are `nr × nr`.
        let dm = MatRef::from_row_major_slice(&self.d[..], self.nh, nr);
        let mut s = Mat::<f64>::zeros(nr, nr);
        matmul(
            s.as_mut(),
            Accum::Replace,
            dm.transpose(),
            dm,
            self.dof,
            Par::Seq,
        );
        if self.nh > 1 {
            let lo = dm.subrows(0, self.nh - 1);
            let hi = dm.subrows(1, self.nh - 1);
            let mut c = Mat::<f64>::zeros(nr, nr);
            matmul(
                c.as_mut(),
                Accum::Replace,
                lo.transpose(),
                hi,
                0.5 * self.dof,
                Par::Seq,
            );
            for i in 0..nr {
                for j in 0..nr {
                    s[(i, j)] += c[(i, j)] + c[(j, i)];
                }
            }
        }
        s
    }
}

/// The window contributions of every level of `which` (moments `levels`) to the weighted
/// residual rows at the estimate `x` of the `active` columns, with the `held` columns at
/// their values; `weights` are the row weights of the stacked problem (`nr` rows per
/// level) and `mix`, where given, one `nr × nr` row-major matrix per level applied after
/// them (the whitening of the efficient step, [`efficient_mix`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn level_windows(
    x: &[f64],
    active: &[usize],
    held: &[(usize, f64)],
    nr: usize,
    weights: &[f64],
    mix: Option<&[Vec<f64>]>,
    columns: &[Arc<Column>],
    which: &[usize],
    levels: &[LevelMoments],
) -> Vec<LevelWindows> {
    let rhs = columns.len() - 1;
    let terms: Vec<(usize, f64)> = active
        .iter()
        .zip(x)
        .map(|(&c, &v)| (c, v))
        .chain(held.iter().copied())
        .chain([(rhs, -1.0)])
        .collect();
    which
        .iter()
        .enumerate()
        .map(|(pos, &i)| {
            let w = &weights[pos * nr..(pos + 1) * nr];
            let m = mix.map(|m| &m[pos][..]);
            centred_windows(&terms, nr, w, m, columns, i, &levels[i])
        })
        .collect()
}

/// The centred window contributions `M W (h_j − w_j e)` at level `i` of the combination
/// `Σ v · column` of `terms` (`(column, v)`), `w` the level's row weights and `mix` its
/// mixing matrix `M` (`nr × nr` row-major), where given.
pub(crate) fn centred_windows(
    terms: &[(usize, f64)],
    nr: usize,
    w: &[f64],
    mix: Option<&[f64]>,
    columns: &[Arc<Column>],
    i: usize,
    lm: &LevelMoments,
) -> LevelWindows {
    let nh = lm.n_blocks() + 1;
    let mut d = vec![0.0; nh * nr];
    for (j, dj) in d.chunks_exact_mut(nr).enumerate() {
        for &(c, v) in terms {
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
    if let Some(mix) = mix {
        // shape: every mixing matrix is `nr × nr` (made by `efficient_mix` from this
        // level's `nr` rows), `d` is `nh × nr`: D Mᵀ is again `nh × nr`.
        let mut md = vec![0.0; nh * nr];
        matmul(
            MatMut::from_row_major_slice_mut(&mut md[..], nh, nr),
            Accum::Replace,
            MatRef::from_row_major_slice(&d[..], nh, nr),
            MatRef::from_row_major_slice(mix, nr, nr).transpose(),
            1.0,
            Par::Seq,
        );
        d = md;
    }
    let nb = lm.kept_blocks() as f64;
    LevelWindows {
        d,
        nh,
        dof: nb / (nb - 1.0).max(1.0),
    }
}

/// The standard errors of an estimate and its covariance as reported.
pub(crate) struct Spread {
    pub se: Vec<f64>,
    /// Row-major `na × na`: the sandwich covariance with `se²` on its diagonal (where a
    /// variance fell back to the Bartlett weight, its row keeps the sandwich's covariances).
    pub cov: Vec<f64>,
}

impl Spread {
    /// The spread of an estimate of no parameters.
    pub fn none() -> Spread {
        Spread {
            se: Vec::new(),
            cov: Vec::new(),
        }
    }

    /// The spread of the sandwich `cov` (`na × na`) with the Bartlett variances `bartlett`
    /// standing in for variances that are not positive.
    fn new(cov: &Mat<f64>, bartlett: &[f64]) -> Spread {
        let na = bartlett.len();
        // shape: `cov` is `na × na` and `bartlett` has `na` entries (`sandwich_cov`), so
        // `k, l < na` index both.
        let se: Vec<f64> = (0..na)
            .map(|k| {
                let v = cov[(k, k)];
                if v > 0.0 {
                    v.sqrt()
                } else {
                    bartlett[k].max(0.0).sqrt()
                }
            })
            .collect();
        let cov = (0..na * na)
            .map(|i| {
                let (k, l) = (i / na, i % na);
                if k == l {
                    se[k] * se[k]
                } else {
                    0.5 * (cov[(k, l)] + cov[(l, k)])
                }
            })
            .collect();
        Spread { se, cov }
    }
}

/// Standard errors and covariance of the active columns of `sol` from the window
/// contributions of its residual rows (see the module doc and [`level_windows`]; `nr` rows
/// per level).
pub(crate) fn sandwich_stderr(sol: &LsSolution, nr: usize, windows: &[LevelWindows]) -> Spread {
    let (cov, bartlett) = sandwich_cov(&sol.pinv, sol.x.len(), nr, windows);
    Spread::new(&cov, &bartlett)
}

/// The sandwich covariance `Σ_l B/(B−1) Σ_j (u_j u_jᵀ + u_j u_{j+1}ᵀ + u_{j+1} u_jᵀ)` of an
/// estimate whose pseudo-inverse is `pinv` (`na × rows`, `nr` rows per level), with
/// `u_j = A⁺_l d_j`; and per parameter the variance with the Bartlett weight ½ on the
/// lag-one terms, which is never negative.
pub(crate) fn sandwich_cov(
    pinv: &[f64],
    na: usize,
    nr: usize,
    windows: &[LevelWindows],
) -> (Mat<f64>, Vec<f64>) {
    let rows = windows.len() * nr;
    let mut cov = Mat::<f64>::zeros(na, na);
    let mut bartlett = vec![0.0; na];
    for (pos, lw) in windows.iter().enumerate() {
        let nh = lw.nh;
        // u_j = A⁺_l d_j for every window at once: U = D A⁺_lᵀ (`nh × na`).
        // shape: `u` is created here as `nh × na` and read for `j < nh`, `k < na`; `pinv`
        // is `na × rows` with `rows = windows.len() · nr`.
        let mut u = Mat::<f64>::zeros(nh, na);
        if na > 0 && nr > 0 {
            let dm = MatRef::from_row_major_slice(&lw.d[..], nh, nr);
            let pl = MatRef::from_row_major_slice_with_stride(&pinv[pos * nr..], na, nr, rows);
            matmul(
                u.as_mut(),
                Accum::Replace,
                dm,
                pl.transpose(),
                1.0,
                Par::Seq,
            );
        }
        for k in 0..na {
            for l in 0..na {
                let s0: f64 = (0..nh).map(|j| u[(j, k)] * u[(j, l)]).sum();
                let s1: f64 = (1..nh)
                    .map(|j| u[(j - 1, k)] * u[(j, l)] + u[(j, k)] * u[(j - 1, l)])
                    .sum();
                cov[(k, l)] += lw.dof * (s0 + s1);
                if k == l {
                    bartlett[k] += lw.dof * (s0 + 0.5 * s1);
                }
            }
        }
    }
    (cov, bartlett)
}

/// Shrinkage of the estimated row covariance towards its diagonal in the efficient step
/// (see [`efficient_mix`]): halfway, since the rows can outnumber the windows.
pub(crate) const SHRINKAGE: f64 = 0.5;

/// The whitening of one level's rows for the efficient (two-step) solve: `M = Λ^{−½} Qᵀ`
/// with `Q Λ Qᵀ = (1 − α) Ŝ + α diag(Ŝ)`, `Ŝ` the long-run covariance of the level's
/// weighted rows at the first-step estimate ([`LevelWindows::covariance`]) and `α` the
/// shrinkage towards its diagonal (the rows outnumber the windows that estimate `Ŝ`, so
/// `Ŝ` alone is singular). Rows of weight zero keep a unit diagonal (they are zero).
/// `None` when the decomposition fails or the covariance has no positive scale.
pub(crate) fn efficient_mix(lw: &LevelWindows, nr: usize, alpha: f64) -> Option<Vec<f64>> {
    // shape: `s`, `shrunk` and the eigenvectors are `nr × nr` and `lam` has `nr` entries, by
    // construction; every index below is `< nr`.
    // The diagonal of `Ŝ` ([`LevelWindows::row_variances`]: a negative variance, which
    // the floor below lifts, read as zero).
    let diag = lw.row_variances(nr);
    let top = diag.iter().copied().fold(0.0, f64::max);
    if !(top > 0.0 && top.is_finite()) {
        return None;
    }
    let floor = top * 1e-12;
    if alpha >= 1.0 {
        // Shrunk all the way: `S` is its diagonal, and `M` the diagonal of its inverse
        // square roots (no decomposition; the same floor as the eigenvalues' below).
        let mut m = vec![0.0; nr * nr];
        for (i, d) in diag.iter().enumerate() {
            m[i * nr + i] = 1.0 / d.max(floor).sqrt();
        }
        return Some(m);
    }
    let s = lw.covariance(nr);
    let shrunk = Mat::<f64>::from_fn(nr, nr, |i, j| {
        if i == j {
            diag[i].max(floor)
        } else {
            (1.0 - alpha) * s[(i, j)]
        }
    });
    let evd = shrunk.self_adjoint_eigen(faer::Side::Lower).ok()?;
    let (q, lam) = (evd.U(), evd.S().column_vector());
    let lmax = (0..nr).map(|k| lam[k]).fold(0.0, f64::max);
    let mut m = vec![0.0; nr * nr];
    for k in 0..nr {
        let l = lam[k].max(lmax * 1e-12);
        if !(l > 0.0 && l.is_finite()) {
            return None;
        }
        let f = 1.0 / l.sqrt();
        for j in 0..nr {
            m[k * nr + j] = f * q[(j, k)];
        }
    }
    Some(m)
}

/// `∂S/∂p_k · v` for the shrunk covariance `S = (1 − α) Ŝ + α diag(Ŝ)` of
/// [`efficient_mix`], where `Ŝ` is [`LevelWindows::covariance`] of the windows `d` and
/// `g` the windows of column `k` (`∂d_j/∂p_k = g_j`: the windows are linear in the
/// parameters).
fn covariance_derivative_times(
    d: &LevelWindows,
    g: &LevelWindows,
    v: &[f64],
    nr: usize,
    alpha: f64,
) -> Vec<f64> {
    let nh = d.nh;
    let dot = |x: &[f64]| x.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
    let dj = |j: usize| &d.d[j * nr..(j + 1) * nr];
    let gj = |j: usize| &g.d[j * nr..(j + 1) * nr];
    let dv: Vec<f64> = (0..nh).map(|j| dot(dj(j))).collect();
    let gv: Vec<f64> = (0..nh).map(|j| dot(gj(j))).collect();
    let mut full = vec![0.0; nr];
    let mut diag = vec![0.0; nr];
    for j in 0..nh {
        let (dd, gg) = (dj(j), gj(j));
        for r in 0..nr {
            full[r] += gg[r] * dv[j] + dd[r] * gv[j];
            diag[r] += 2.0 * gg[r] * dd[r];
        }
        if j + 1 < nh {
            let (dn, gn) = (dj(j + 1), gj(j + 1));
            for r in 0..nr {
                full[r] +=
                    0.5 * (gg[r] * dv[j + 1] + dd[r] * gv[j + 1] + gn[r] * dv[j] + dn[r] * gv[j]);
                diag[r] += gg[r] * dn[r] + gn[r] * dd[r];
            }
        }
    }
    (0..nr)
        .map(|r| d.dof * ((1.0 - alpha) * full[r] + alpha * diag[r] * v[r]))
        .collect()
}

/// Standard errors of the efficient (two-step) estimate, corrected for the weighting
/// having been estimated at the first step's estimate (Windmeijer 2005):
///
/// ```text
/// V = V₂ + D V₂ + V₂ Dᵀ + D V₁ Dᵀ,   D_k = H Σ_l A_lᵀ W_l (∂S_l/∂p_k) W_l (A_l p̂₂ − b_l),
/// ```
///
/// `V₁`, `V₂` the sandwich covariances of the two steps, `W_l = M_lᵀ M_l` the weighting of
/// level `l` ([`efficient_mix`]), `A_l`, `b_l` its rows with the first step's weights
/// (`a`, `b`, row-major, `na` columns) and `H = (Σ A_lᵀ W_l A_l)⁻¹ = P Pᵀ` (`P` the second
/// step's pseudo-inverse). Without the correction the standard errors come out low: the
/// weighting is estimated from the same residuals whose noise it then down-weights.
/// `first` is the estimate the weighting was read at: the unit-norm rows' (two-step) or,
/// iterated, the weighted estimate before `second`; `first_windows` are its windows
/// unweighted (for `∂S`), `first_cov_windows` its windows as it was solved (for `V₁`; the
/// same windows for the unit-norm rows).
///
/// Long: the formula above computed term by term; split, its intermediate matrices would
/// pass between the pieces.
#[allow(clippy::too_many_arguments)]
pub(crate) fn efficient_stderr(
    first: &LsSolution,
    second: &LsSolution,
    a: &[f64],
    b: &[f64],
    mixes: &[Vec<f64>],
    alpha: f64,
    active: &[usize],
    nr: usize,
    weights: &[f64],
    first_windows: &[LevelWindows],
    first_cov_windows: &[LevelWindows],
    second_windows: &[LevelWindows],
    columns: &[Arc<Column>],
    which: &[usize],
    levels: &[LevelMoments],
) -> Spread {
    let na = second.x.len();
    let rows = which.len() * nr;
    // T[q, k] = Σ_l (A_lᵀ W_l ∂S_l/∂p_k W_l r_l)_q
    let mut t = Mat::<f64>::zeros(na, na);
    let mvec = |m: &[f64], x: &[f64], transpose: bool| -> Vec<f64> {
        (0..nr)
            .map(|r| {
                (0..nr)
                    .map(|c| {
                        let e = if transpose {
                            m[c * nr + r]
                        } else {
                            m[r * nr + c]
                        };
                        e * x[c]
                    })
                    .sum()
            })
            .collect()
    };
    for (pos, &i) in which.iter().enumerate() {
        let al = &a[pos * nr * na..(pos + 1) * nr * na];
        let r2: Vec<f64> = (0..nr)
            .map(|r| (0..na).map(|k| al[r * na + k] * second.x[k]).sum::<f64>() - b[pos * nr + r])
            .collect();
        let m = &mixes[pos][..];
        let v = mvec(m, &mvec(m, &r2, false), true);
        let w = &weights[pos * nr..(pos + 1) * nr];
        for k in 0..na {
            let g = centred_windows(&[(active[k], 1.0)], nr, w, None, columns, i, &levels[i]);
            let dsv = covariance_derivative_times(&first_windows[pos], &g, &v, nr, alpha);
            let y = mvec(m, &mvec(m, &dsv, false), true);
            for q in 0..na {
                t[(q, k)] += (0..nr).map(|r| al[r * na + q] * y[r]).sum::<f64>();
            }
        }
    }
    // shape: both pseudo-inverses are `na × rows` (the same active columns and rows).
    let p = MatRef::from_row_major_slice(&second.pinv[..], na, rows);
    let mut h = Mat::<f64>::zeros(na, na);
    matmul(h.as_mut(), Accum::Replace, p, p.transpose(), 1.0, Par::Seq);
    let mut dm = Mat::<f64>::zeros(na, na);
    matmul(
        dm.as_mut(),
        Accum::Replace,
        h.as_ref(),
        t.as_ref(),
        1.0,
        Par::Seq,
    );
    let (v1, _) = sandwich_cov(&first.pinv, na, nr, first_cov_windows);
    let (v2, b2) = sandwich_cov(&second.pinv, na, nr, second_windows);
    let mut v = v2.clone();
    let mut tmp = Mat::<f64>::zeros(na, na);
    matmul(
        v.as_mut(),
        Accum::Add,
        dm.as_ref(),
        v2.as_ref(),
        1.0,
        Par::Seq,
    );
    matmul(
        v.as_mut(),
        Accum::Add,
        v2.as_ref(),
        dm.transpose(),
        1.0,
        Par::Seq,
    );
    matmul(
        tmp.as_mut(),
        Accum::Replace,
        dm.as_ref(),
        v1.as_ref(),
        1.0,
        Par::Seq,
    );
    matmul(
        v.as_mut(),
        Accum::Add,
        tmp.as_ref(),
        dm.transpose(),
        1.0,
        Par::Seq,
    );
    Spread::new(&v, &b2)
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
