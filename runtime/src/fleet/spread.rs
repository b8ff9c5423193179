//! The fleet's model: a robust centre and the between-machine covariance (see the module
//! doc of [`super`]).

use super::machine::Ordered;
use nalgebra::{DMatrix, SymmetricEigen};

/// The centre of the fleet and its spread.
pub(super) struct FleetModel {
    /// `p̄`: the mean of the held machines.
    pub centre: Vec<f64>,
    /// `√(S_jj / n_held)`.
    pub centre_se: Vec<f64>,
    /// `Σ = (S − W)₊`.
    pub between: DMatrix<f64>,
    /// Eigen-directions of `S − W` below zero, set to zero.
    pub clipped: usize,
    /// Root mean square of the held machines' standard errors.
    pub within: Vec<f64>,
}

/// The machines held at the start: those within `z` MAD scales of the coordinate-wise
/// median in every parameter.
pub(super) fn screen(machines: &[Ordered], z: f64) -> Vec<bool> {
    let k = machines.first().map_or(0, |m| m.values.len());
    let mut held = vec![true; machines.len()];
    for j in 0..k {
        let col: Vec<f64> = machines.iter().map(|m| m.values[j]).collect();
        let med = median(&col);
        let dev: Vec<f64> = col.iter().map(|v| (v - med).abs()).collect();
        let scale = 1.4826 * median(&dev);
        for (h, d) in held.iter_mut().zip(&dev) {
            // `d > z·scale` is false for d = 0 = scale: identical machines are held.
            if *d > z * scale {
                *h = false;
            }
        }
    }
    held
}

/// The median of `v` (not empty).
fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// The fleet's model on the `held` machines; with `between` off, `Σ = 0`.
pub(super) fn fit(machines: &[Ordered], held: &[bool], between: bool) -> FleetModel {
    let k = machines.first().map_or(0, |m| m.values.len());
    let kept: Vec<&Ordered> = machines
        .iter()
        .zip(held)
        .filter_map(|(m, &h)| h.then_some(m))
        .collect();
    let n = kept.len() as f64;
    let centre: Vec<f64> = (0..k)
        .map(|j| kept.iter().map(|m| m.values[j]).sum::<f64>() / n)
        .collect();
    let mut s = DMatrix::<f64>::zeros(k, k);
    let mut w = DMatrix::<f64>::zeros(k, k);
    for m in &kept {
        let d = nalgebra::DVector::from_fn(k, |j, _| m.values[j] - centre[j]);
        s += &d * d.transpose();
        w += &m.covariance;
    }
    s /= (n - 1.0).max(1.0);
    w /= n;
    let centre_se = (0..k).map(|j| (s[(j, j)] / n).max(0.0).sqrt()).collect();
    let within = (0..k).map(|j| w[(j, j)].max(0.0).sqrt()).collect();
    let (between, clipped) = if between {
        positive_part(&s, &w)
    } else {
        (DMatrix::zeros(k, k), 0)
    };
    FleetModel {
        centre,
        centre_se,
        between,
        clipped,
        within,
    }
}

/// The positive part of `s − w` (its eigenvalues below zero set to zero), taken in the
/// coordinates scaled by `√(s_jj + w_jj)` (so that parameters of any unit count alike, and
/// every scaled entry is at most 1 in size: a parameter on which all machines agree to
/// the last digit, `s_jj ≈ 0`, must not blow its `−w_jj` up beyond the others' precision);
/// and the number of eigenvalues set to zero.
fn positive_part(s: &DMatrix<f64>, w: &DMatrix<f64>) -> (DMatrix<f64>, usize) {
    let k = s.nrows();
    let d = s - w;
    let scale: Vec<f64> = (0..k)
        .map(|j| {
            let v = (s[(j, j)] + w[(j, j)]).sqrt();
            if v > 0.0 && v.is_finite() {
                v
            } else {
                1.0
            }
        })
        .collect();
    let scaled = DMatrix::from_fn(k, k, |i, j| {
        0.5 * (d[(i, j)] + d[(j, i)]) / (scale[i] * scale[j])
    });
    let eig = SymmetricEigen::new(scaled);
    let clipped = eig.eigenvalues.iter().filter(|&&l| l < 0.0).count();
    let lambda = DMatrix::from_diagonal(&eig.eigenvalues.map(|l| l.max(0.0)));
    let pos = &eig.eigenvectors * lambda * eig.eigenvectors.transpose();
    (
        DMatrix::from_fn(k, k, |i, j| pos[(i, j)] * scale[i] * scale[j]),
        clipped,
    )
}
