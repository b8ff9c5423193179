//! Least squares by orthogonal transformations only: a row-by-row Givens QR of the
//! Jacobian (the Jacobian is never stored and `JᵀJ` never formed), and the damped
//! Levenberg–Marquardt step of a problem whose unknowns are shared parameters plus local
//! unknowns of each sub-record (eliminated sub-record by sub-record, again by QR).

use nalgebra::{DMatrix, DVector};

/// `R` (upper triangular, `n × n`) and `z = Qᵀ r` of the rows pushed so far, so that
/// `‖J δ + r‖² = ‖R δ + z‖² + const`.
#[derive(Clone, Debug)]
pub(super) struct RowQr {
    pub(super) n: usize,
    pub(super) r: Vec<f64>,
    pub(super) z: Vec<f64>,
    /// Σ r² of the rows pushed (the cost at the current point).
    pub(super) cost: f64,
    pub(super) rows: usize,
}

impl RowQr {
    pub(super) fn new(n: usize) -> Self {
        RowQr {
            n,
            r: vec![0.0; n * n],
            z: vec![0.0; n],
            cost: 0.0,
            rows: 0,
        }
    }

    /// Add the row `j` (destroyed) with residual `res`.
    pub(super) fn push(&mut self, j: &mut [f64], mut res: f64) {
        let n = self.n;
        self.cost += res * res;
        self.rows += 1;
        for i in 0..n {
            let b = j[i];
            if b == 0.0 {
                continue;
            }
            let a = self.r[i * n + i];
            let h = a.hypot(b);
            let (c, s) = (a / h, b / h);
            self.r[i * n + i] = h;
            let row = &mut self.r[i * n + i + 1..(i + 1) * n];
            for (rk, jk) in row.iter_mut().zip(&mut j[i + 1..n]) {
                let (r0, j0) = (*rk, *jk);
                *rk = c * r0 + s * j0;
                *jk = c * j0 - s * r0;
            }
            let zi = self.z[i];
            self.z[i] = c * zi + s * res;
            res = c * res - s * zi;
        }
    }

    pub(super) fn matrix(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(self.n, self.n, &self.r)
    }

    /// Euclidean norm of column `k` of `R` (= of the Jacobian's column).
    pub(super) fn column_norm(&self, k: usize) -> f64 {
        (0..=k)
            .map(|i| self.r[i * self.n + k].powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

/// One sub-record's factor: columns `[local (nl), shared (np)]`.
pub(super) struct Block<'a> {
    pub(super) qr: &'a RowQr,
    pub(super) nl: usize,
}

/// The step `(δ shared, δ local per block)` minimising
/// `Σ_b ‖R_b [δl_b; δp] + z_b‖² + λ (Σ_b ‖D_l δl_b‖² + ‖D_p δp‖²)`, every factorisation by
/// QR and the shared system by SVD (singular values below `rcond · σ_max` dropped).
/// `d_local[b]` and `d_shared` are the scales `D`.
pub(super) fn lm_step(
    blocks: &[Block],
    np: usize,
    lambda: f64,
    d_local: &[Vec<f64>],
    d_shared: &[f64],
    rcond: f64,
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let sl = lambda.sqrt();
    // shape: the sizes come from the model, not the data: each block's `qr` is `n × n`
    // with `n = nl + np`, `d` has `nl` scales, `d_shared` has `np`.
    // Eliminate each block's local unknowns: QR of [R_b; √λ D_l (local columns)].
    let mut reduced: Vec<(DMatrix<f64>, DVector<f64>)> = Vec::with_capacity(blocks.len());
    let mut shared_rows: Vec<(DMatrix<f64>, DVector<f64>)> = Vec::new();
    for (b, d) in blocks.iter().zip(d_local) {
        let n = b.qr.n;
        let mut a = DMatrix::<f64>::zeros(n + b.nl, n);
        a.view_mut((0, 0), (n, n)).copy_from(&b.qr.matrix());
        for k in 0..b.nl {
            a[(n + k, k)] = sl * d[k];
        }
        let mut rhs = DVector::<f64>::zeros(n + b.nl);
        for k in 0..n {
            rhs[k] = -b.qr.z[k];
        }
        let qr = a.qr();
        let mut qtb = rhs;
        qr.q_tr_mul(&mut qtb);
        let r = qr.r();
        shared_rows.push((
            r.view((b.nl, b.nl), (np, np)).into_owned(),
            qtb.rows(b.nl, np).into_owned(),
        ));
        reduced.push((r, qtb.rows(0, n).into_owned()));
    }
    // The shared system: the stacked reduced rows and √λ D_p.
    let rows = shared_rows.len() * np + np;
    let mut g = DMatrix::<f64>::zeros(rows, np);
    let mut h = DVector::<f64>::zeros(rows);
    for (i, (r, z)) in shared_rows.iter().enumerate() {
        g.view_mut((i * np, 0), (np, np)).copy_from(r);
        h.rows_mut(i * np, np).copy_from(z);
    }
    for k in 0..np {
        g[(shared_rows.len() * np + k, k)] = sl * d_shared[k];
    }
    let dp = solve_svd(g, &h, rcond);
    // Back-substitution of the local steps.
    let locals = blocks
        .iter()
        .zip(&reduced)
        .map(|(b, (r, z))| {
            let nl = b.nl;
            let mut out = vec![0.0; nl];
            for i in (0..nl).rev() {
                let mut acc = z[i];
                for k in 0..np {
                    acc -= r[(i, nl + k)] * dp[k];
                }
                for k in i + 1..nl {
                    acc -= r[(i, k)] * out[k];
                }
                out[i] = if r[(i, i)] != 0.0 {
                    acc / r[(i, i)]
                } else {
                    0.0
                };
            }
            out
        })
        .collect();
    (dp.iter().copied().collect(), locals)
}

/// The shared parameters' factor after the local unknowns are eliminated (no damping):
/// `F` with `‖F δp + …‖²` the cost minimised over the local unknowns; `Fᵀ F` is the
/// information matrix of the shared parameters.
pub(super) fn shared_factor(blocks: &[Block], np: usize) -> DMatrix<f64> {
    let mut g = DMatrix::<f64>::zeros(blocks.len() * np, np);
    for (i, b) in blocks.iter().enumerate() {
        let r = b.qr.matrix();
        // R is upper triangular with the local columns first: its trailing block is
        // already the shared factor of this block.
        g.view_mut((i * np, 0), (np, np))
            .copy_from(&r.view((b.nl, b.nl), (np, np)));
    }
    g
}

/// Least-squares solution of `g x = h` by SVD, dropping singular values below
/// `rcond · σ_max`.
fn solve_svd(g: DMatrix<f64>, h: &DVector<f64>, rcond: f64) -> DVector<f64> {
    let svd = g.svd(true, true);
    let smax = svd.singular_values.max();
    let eps = (rcond * smax).max(f64::MIN_POSITIVE);
    svd.solve(h, eps)
        .unwrap_or_else(|_| DVector::zeros(svd.singular_values.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn givens_rows_give_the_least_squares_solution() {
        // Fit y = a + b t by rows; the solution of R δ = −z from zero is the LS fit.
        let mut qr = RowQr::new(2);
        for k in 0..50 {
            let t = k as f64 * 0.1;
            let y = 1.5 - 0.25 * t + if k % 2 == 0 { 0.01 } else { -0.01 };
            // Residual at (a, b) = 0 is −y; Jacobian row (1, t).
            qr.push(&mut [1.0, t], -y);
        }
        let blocks = [Block { qr: &qr, nl: 0 }];
        let (dp, _) = lm_step(&blocks, 2, 0.0, &[vec![]], &[1.0, 1.0], 1e-12);
        assert!(
            (dp[0] - 1.5).abs() < 0.01 && (dp[1] + 0.25).abs() < 0.01,
            "{dp:?}"
        );
    }

    #[test]
    fn local_unknowns_are_eliminated_exactly() {
        // Two blocks y = c_b + p t with an offset per block and a shared slope.
        let truth = [(2.0, 0.7), (-1.0, 0.7)];
        let mut qrs = [RowQr::new(2), RowQr::new(2)];
        for (qr, (c, p)) in qrs.iter_mut().zip(truth) {
            for k in 0..20 {
                let t = k as f64;
                qr.push(&mut [1.0, t], -(c + p * t));
            }
        }
        let blocks: Vec<Block> = qrs.iter().map(|qr| Block { qr, nl: 1 }).collect();
        let (dp, dl) = lm_step(&blocks, 1, 0.0, &[vec![1.0], vec![1.0]], &[1.0], 1e-12);
        assert!((dp[0] - 0.7).abs() < 1e-12, "{dp:?}");
        assert!((dl[0][0] - 2.0).abs() < 1e-10 && (dl[1][0] + 1.0).abs() < 1e-10);
    }
}
