//! The guards of a running simulation: divergence (a state that is not finite or beyond
//! `1e6 · (1 + largest input std)`) and under-resolution (a motion too fast for the sample
//! interval, which aliases). Both the excited and the driven runs call them once a sample.

use super::error::SimError;
use super::mech::Rk4;
use dynid_ir::ir::ModelIr;

/// Largest `ω·Ts` (ω = dominant angular frequency of a body's motion) accepted: about four
/// samples per period. Beyond it the record aliases and the integration is untrustworthy.
pub(super) const MAX_OMEGA_TS: f64 = 1.5;

/// Running moments of each body's position and its sample-to-sample change, to estimate
/// `ω·Ts ≈ std(Δx) / std(x)` without storing the trajectory.
pub(super) struct Resolution {
    prev: Vec<f64>,
    sum: Vec<f64>,
    sum2: Vec<f64>,
    dsum2: Vec<f64>,
    n: usize,
}

impl Resolution {
    pub(super) fn new(nb: usize) -> Self {
        Resolution {
            prev: vec![0.0; nb],
            sum: vec![0.0; nb],
            sum2: vec![0.0; nb],
            dsum2: vec![0.0; nb],
            n: 0,
        }
    }

    #[inline]
    pub(super) fn add(&mut self, x: &[f64]) {
        for (i, &x) in x.iter().enumerate() {
            if self.n > 0 {
                let d = x - self.prev[i];
                self.dsum2[i] += d * d;
            }
            self.prev[i] = x;
            self.sum[i] += x;
            self.sum2[i] += x * x;
        }
        self.n += 1;
    }

    pub(super) fn check(
        &self,
        ir: &ModelIr,
        ts: f64,
        context: impl Fn() -> String,
    ) -> Result<(), SimError> {
        if self.n < 2 {
            return Ok(());
        }
        let n = self.n as f64;
        for (i, body) in ir.bodies.iter().enumerate() {
            let mean = self.sum[i] / n;
            let var = (self.sum2[i] / n - mean * mean).max(0.0);
            let dvar = self.dsum2[i] / (n - 1.0);
            if dvar > MAX_OMEGA_TS * MAX_OMEGA_TS * var && dvar > 0.0 {
                return Err(SimError::UnderResolved {
                    context: context(),
                    body: body.name.clone(),
                    omega_ts: (dvar / var).sqrt(),
                    samples_per_period: 2.0 * std::f64::consts::PI * (var / dvar).sqrt(),
                    ts,
                });
            }
        }
        Ok(())
    }
}

/// Stop a run whose state is no longer finite or beyond `limit`, naming when.
pub(super) fn check_divergence(
    rk: &Rk4,
    limit: f64,
    context: impl Fn() -> String,
    when: impl Fn() -> String,
) -> Result<(), SimError> {
    let m = rk.magnitude();
    // An infinite limit (an input of infinite intensity) must not let `inf <= inf` pass.
    if m.is_finite() && m <= limit {
        return Ok(());
    }
    Err(SimError::Diverged {
        context: context(),
        when: when(),
        what: if m.is_finite() {
            format!("state magnitude {m:.3e} exceeds {limit:.1e}")
        } else {
            "the state is no longer finite".into()
        },
    })
}

/// The state magnitude beyond which a run has diverged: `1e6 · (1 + largest input std)`.
pub(super) fn divergence_limit(input_stds: impl Iterator<Item = f64>) -> f64 {
    1e6 * (1.0 + input_stds.fold(0.0, f64::max))
}
