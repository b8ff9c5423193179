//! The χ² consistency test of a machine against its fleet, and the parameters that moved
//! (see the module doc of [`super`]).

use super::machine::{MachineEstimate, Ordered};
use super::spread::FleetModel;
use super::{MachineParam, MAX_CONDITION};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

/// A machine's test statistic.
pub(super) struct Test {
    pub d2: f64,
    pub dof: usize,
    pub p_value: f64,
    pub condition: f64,
}

/// `P(χ²(dof) > x)`, the upper tail (1 for `dof = 0`).
pub fn chi2_upper_tail(x: f64, dof: usize) -> f64 {
    match ChiSquared::new(dof as f64) {
        Ok(d) if x > 0.0 => d.sf(x),
        _ => 1.0,
    }
}

/// The `q` quantile of χ²(dof) (0 for `dof = 0`).
pub fn chi2_quantile(q: f64, dof: usize) -> f64 {
    match ChiSquared::new(dof as f64) {
        Ok(d) => d.inverse_cdf(q),
        Err(_) => 0.0,
    }
}

/// The `q` quantile of the standard normal distribution.
pub fn normal_quantile(q: f64) -> f64 {
    Normal::standard().inverse_cdf(q)
}

/// `d² = rᵀ (Σ + C)⁻¹ r`, `r = p − p̄`, by a Cholesky factorisation of `Σ + C` scaled to unit
/// diagonal; in its well-determined eigen-directions where it is ill-conditioned.
pub(super) fn test(m: &Ordered, model: &FleetModel) -> Test {
    let k = m.values.len();
    let total = &model.between + &m.covariance;
    let scale: Vec<f64> = (0..k)
        .map(|j| {
            let v = total[(j, j)].sqrt();
            if v > 0.0 && v.is_finite() {
                v
            } else {
                1.0
            }
        })
        .collect();
    let a = DMatrix::from_fn(k, k, |i, j| {
        0.5 * (total[(i, j)] + total[(j, i)]) / (scale[i] * scale[j])
    });
    let r = DVector::from_fn(k, |j, _| (m.values[j] - model.centre[j]) / scale[j]);
    let eig = SymmetricEigen::new(a.clone());
    let top = eig.eigenvalues.iter().fold(0.0_f64, |x, &l| x.max(l));
    let low = eig.eigenvalues.iter().fold(f64::INFINITY, |x, &l| x.min(l));
    let condition = if low > 0.0 { top / low } else { f64::MAX };
    let chol = (condition <= MAX_CONDITION)
        .then(|| nalgebra::Cholesky::new(a))
        .flatten();
    let (d2, dof) = match chol {
        Some(c) => {
            let y = c
                .l()
                .solve_lower_triangular(&r)
                .expect("invariant: a Cholesky factor has a positive diagonal");
            (y.norm_squared(), k)
        }
        None => {
            let tol = top / MAX_CONDITION;
            let mut d2 = 0.0;
            let mut dof = 0;
            for (l, v) in eig.eigenvalues.iter().zip(eig.eigenvectors.column_iter()) {
                if *l > tol {
                    d2 += v.dot(&r).powi(2) / l;
                    dof += 1;
                }
            }
            (d2, dof)
        }
    };
    Test {
        d2,
        dof,
        p_value: chi2_upper_tail(d2, dof),
        condition: condition.min(f64::MAX),
    }
}

/// One parameter against the fleet's: ratio and `z`.
fn param(name: &str, value: f64, var: f64, model: &FleetModel, j: usize) -> MachineParam {
    let centre = model.centre[j];
    let sd = (model.between[(j, j)] + var).max(0.0).sqrt();
    MachineParam {
        name: name.into(),
        value,
        stderr: var.max(0.0).sqrt(),
        ratio: (centre != 0.0).then(|| value / centre),
        z: if sd > 0.0 { (value - centre) / sd } else { 0.0 },
    }
}

/// A tested machine's parameters against the fleet, in the fleet's order.
pub(super) fn machine_params(
    m: &Ordered,
    names: &[String],
    model: &FleetModel,
) -> Vec<MachineParam> {
    (0..m.values.len())
        .map(|j| param(&names[j], m.values[j], m.covariance[(j, j)], model, j))
        .collect()
}

/// The identified parameters of a machine that is not tested, in the fleet's order.
pub(super) fn partial_params(
    e: &MachineEstimate,
    names: &[String],
    model: &FleetModel,
) -> Vec<MachineParam> {
    let k = e.names.len();
    names
        .iter()
        .enumerate()
        .filter_map(|(j, n)| {
            let at = e.names.iter().position(|m| m == n)?;
            (j < model.centre.len())
                .then(|| param(n, e.values[at], e.covariance[at * k + at], model, j))
        })
        .collect()
}

/// The parameters that moved: `|z| > critical`, largest first; the largest alone where none
/// passes.
pub(super) fn moved(params: &[MachineParam], critical: f64) -> Vec<MachineParam> {
    let mut sorted = params.to_vec();
    sorted.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
    let n = sorted.iter().filter(|p| p.z.abs() > critical).count();
    sorted.truncate(n.max(1));
    sorted
}
