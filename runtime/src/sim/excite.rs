//! Form filters (Schiehlen & Krause eq. 2; docs/method.md, References): white noise of
//! intensity `level` shaped into an input.
//!
//! The linear part is an Ornstein–Uhlenbeck process `z' = A z + L level w`. It is
//! advanced at the sample rate with its exact discretisation: the transition `Φ = e^{A h}`
//! and the noise covariance `Q = ∫₀ʰ e^{Aτ} L Lᵀ e^{Aᵀτ} dτ`, both from one matrix
//! exponential (Van Loan 1978); draws use the Cholesky factor of `Q`. The first state is
//! drawn from the stationary distribution, so the record is stationary from sample 0.

use super::excitation::{SignalSampler, TestSignal};
use super::planned::{Moves, PlannedSampler};
use dynid_ir::ir::FormFilter;
use nalgebra::DMatrix;
use rand::Rng;
use rand_distr::StandardNormal;

/// Largest state dimension of a supported form filter.
const MAX_DIM: usize = 2;

/// A form filter discretised for one sample interval and one level.
#[derive(Clone, Debug)]
pub(crate) struct FormFilterSampler {
    dim: usize,
    /// `Φ`, row-major in the leading `dim × dim` block.
    phi: [[f64; MAX_DIM]; MAX_DIM],
    /// Lower Cholesky factor of the one-step noise covariance `Q` (level included).
    q_chol: [[f64; MAX_DIM]; MAX_DIM],
    /// Lower Cholesky factor of the stationary covariance (level included).
    p_chol: [[f64; MAX_DIM]; MAX_DIM],
    /// For `White`: the standard deviation of each held sample.
    white_std: f64,
    state: [f64; MAX_DIM],
}

impl FormFilterSampler {
    /// Discretise `filter` at sample interval `ts` for intensity `level`.
    /// `Err` carries the reason (the caller names the input).
    pub(crate) fn new(filter: &FormFilter, level: f64, ts: f64) -> Result<Self, String> {
        if !(level.is_finite() && level >= 0.0) {
            return Err(format!("level {level} is not a finite non-negative number"));
        }
        let (a, p_unit) = match *filter {
            FormFilter::White => {
                // Unit-intensity white noise averaged over one sample has variance 1/ts.
                return Ok(FormFilterSampler {
                    dim: 0,
                    phi: [[0.0; MAX_DIM]; MAX_DIM],
                    q_chol: [[0.0; MAX_DIM]; MAX_DIM],
                    p_chol: [[0.0; MAX_DIM]; MAX_DIM],
                    white_std: level / ts.sqrt(),
                    state: [0.0; MAX_DIM],
                });
            }
            FormFilter::Lowpass { corner } => {
                if !(corner.is_finite() && corner > 0.0) {
                    return Err(format!("low-pass corner {corner} must be positive"));
                }
                (
                    DMatrix::from_row_slice(1, 1, &[-corner]),
                    DMatrix::from_row_slice(1, 1, &[1.0 / (2.0 * corner)]),
                )
            }
            FormFilter::Moves { .. } => {
                return Err("planned moves are not a random form filter".into());
            }
            FormFilter::SecondOrder { freq, damping } => {
                if !(freq.is_finite() && freq > 0.0) {
                    return Err(format!("natural frequency {freq} must be positive"));
                }
                if !(damping.is_finite() && damping > 0.0) {
                    return Err(format!("damping ratio {damping} must be positive"));
                }
                let w2 = freq * freq;
                (
                    DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w2, -2.0 * damping * freq]),
                    DMatrix::from_row_slice(
                        2,
                        2,
                        &[
                            1.0 / (4.0 * damping * freq * w2),
                            0.0,
                            0.0,
                            1.0 / (4.0 * damping * freq),
                        ],
                    ),
                )
            }
        };
        let n = a.nrows();
        let mut l = DMatrix::zeros(n, 1);
        l[(n - 1, 0)] = 1.0;
        let (phi, q) = van_loan(&a, &(&l * l.transpose()), ts);
        let scale = level * level;
        let q_chol = cholesky(&(q * scale)).ok_or("one-step noise covariance is not positive")?;
        let p_chol = cholesky(&(p_unit * scale)).ok_or("stationary covariance is not positive")?;
        let mut s = FormFilterSampler {
            dim: n,
            phi: [[0.0; MAX_DIM]; MAX_DIM],
            q_chol,
            p_chol,
            white_std: 0.0,
            state: [0.0; MAX_DIM],
        };
        for i in 0..n {
            for j in 0..n {
                s.phi[i][j] = phi[(i, j)];
            }
        }
        Ok(s)
    }

    /// Draw the state from the stationary distribution.
    pub(crate) fn start(&mut self, rng: &mut impl Rng) {
        if self.dim == 0 {
            self.state[0] = self.white_std * rng.sample::<f64, _>(StandardNormal);
            return;
        }
        let e = draw(rng, self.dim);
        self.state = lower_mul(&self.p_chol, &e, self.dim);
    }

    /// Advance by one sample interval.
    pub(crate) fn step(&mut self, rng: &mut impl Rng) {
        if self.dim == 0 {
            self.state[0] = self.white_std * rng.sample::<f64, _>(StandardNormal);
            return;
        }
        let e = draw(rng, self.dim);
        let noise = lower_mul(&self.q_chol, &e, self.dim);
        let mut next = [0.0; MAX_DIM];
        for (i, nx) in next.iter_mut().enumerate().take(self.dim) {
            *nx = noise[i]
                + (0..self.dim)
                    .map(|j| self.phi[i][j] * self.state[j])
                    .sum::<f64>();
        }
        self.state = next;
    }

    /// The filter output (the input signal).
    #[inline]
    pub(crate) fn output(&self) -> f64 {
        self.state[0]
    }

    /// The second state of a second-order filter: the derivative of its output (0 for
    /// other filters).
    #[inline]
    pub(crate) fn derivative(&self) -> f64 {
        if self.dim == 2 {
            self.state[1]
        } else {
            0.0
        }
    }

    /// Stationary standard deviation of the output.
    pub(crate) fn output_std(&self) -> f64 {
        if self.dim == 0 {
            self.white_std
        } else {
            self.p_chol[0][0]
        }
    }
}

/// What drives one input or reference of a run: a form filter or a planned trajectory.
#[derive(Clone, Debug)]
pub(crate) enum Excitation {
    Random(FormFilterSampler),
    Planned(PlannedSampler),
    /// A multisine or sweep ([`super::excitation`]).
    Signal(SignalSampler),
}

impl Excitation {
    /// `filter` at `level` on the fine grid of `fine` steps per sample interval `sample`;
    /// the record starts after `burn_in` samples (a planned trajectory rests until then).
    /// `Err` carries the reason (the caller names the input).
    pub(crate) fn new(
        filter: &FormFilter,
        level: f64,
        sample: f64,
        fine: usize,
        burn_in: usize,
    ) -> Result<Self, String> {
        match *filter {
            FormFilter::Moves {
                distance,
                speed,
                accel,
                dwell,
            } => {
                let moves = Moves {
                    distance,
                    speed,
                    accel,
                    dwell,
                };
                PlannedSampler::new(&moves, level, sample, fine, burn_in).map(Excitation::Planned)
            }
            _ => FormFilterSampler::new(filter, level, sample / fine.max(1) as f64)
                .map(Excitation::Random),
        }
    }

    /// `signal` at `level` on the fine grid for a record of `n` samples after `burn_in`.
    pub(crate) fn signal(
        signal: &TestSignal,
        level: f64,
        sample: f64,
        fine: usize,
        burn_in: usize,
        n: usize,
    ) -> Result<Self, String> {
        SignalSampler::new(signal, level, sample, fine, burn_in, n).map(Excitation::Signal)
    }

    /// Draw the state from the stationary distribution, or a multisine's phases (a planned
    /// trajectory draws nothing).
    pub(crate) fn start(&mut self, rng: &mut impl Rng) {
        match self {
            Excitation::Random(s) => s.start(rng),
            Excitation::Signal(s) => s.start(rng),
            Excitation::Planned(_) => {}
        }
    }

    /// Advance by one fine step.
    #[inline]
    pub(crate) fn step(&mut self, rng: &mut impl Rng) {
        match self {
            Excitation::Random(s) => s.step(rng),
            Excitation::Planned(p) => p.step(),
            Excitation::Signal(s) => s.step(),
        }
    }

    /// The signal now.
    #[inline]
    pub(crate) fn output(&self) -> f64 {
        match self {
            Excitation::Random(s) => s.output(),
            Excitation::Planned(p) => p.setpoint().position,
            Excitation::Signal(s) => s.output(),
        }
    }

    /// Its derivative now (0 for a first-order or white form filter).
    #[inline]
    pub(crate) fn derivative(&self) -> f64 {
        match self {
            Excitation::Random(s) => s.derivative(),
            Excitation::Planned(p) => p.setpoint().velocity,
            // Test signals drive inputs only, never a controller's reference.
            Excitation::Signal(_) => 0.0,
        }
    }

    /// A scale of the signal for the divergence check: the stationary standard deviation,
    /// or the distance of the moves.
    pub(crate) fn output_std(&self) -> f64 {
        match self {
            Excitation::Random(s) => s.output_std(),
            Excitation::Planned(p) => p.scale(),
            Excitation::Signal(s) => s.output_std(),
        }
    }
}

fn draw(rng: &mut impl Rng, dim: usize) -> [f64; MAX_DIM] {
    let mut e = [0.0; MAX_DIM];
    for x in e.iter_mut().take(dim) {
        *x = rng.sample(StandardNormal);
    }
    e
}

fn lower_mul(l: &[[f64; MAX_DIM]; MAX_DIM], e: &[f64; MAX_DIM], dim: usize) -> [f64; MAX_DIM] {
    let mut out = [0.0; MAX_DIM];
    for i in 0..dim {
        out[i] = (0..=i).map(|j| l[i][j] * e[j]).sum();
    }
    out
}

/// Van Loan's method: with `C = [[−A, W], [0, Aᵀ]]·h` and `e^C = [[·, G₁₂], [0, G₂₂]]`,
/// `Φ = G₂₂ᵀ` and `Q = G₂₂ᵀ G₁₂`. `W` is the noise intensity matrix `L Lᵀ`.
pub(crate) fn van_loan(a: &DMatrix<f64>, w: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = a.nrows();
    let mut c = DMatrix::zeros(2 * n, 2 * n);
    c.view_mut((0, 0), (n, n)).copy_from(&(-a));
    c.view_mut((0, n), (n, n)).copy_from(w);
    c.view_mut((n, n), (n, n)).copy_from(&a.transpose());
    let e = (c * h).exp();
    let g12 = e.view((0, n), (n, n)).into_owned();
    let g22 = e.view((n, n), (n, n)).into_owned();
    let phi = g22.transpose();
    let q = &phi * g12;
    // Symmetrise: round-off makes Q slightly asymmetric.
    let q = (&q + q.transpose()) * 0.5;
    (phi, q)
}

/// Lower Cholesky factor into a fixed-size array; `None` if not positive definite
/// (a zero matrix, i.e. level 0, is accepted and gives a zero factor).
fn cholesky(m: &DMatrix<f64>) -> Option<[[f64; MAX_DIM]; MAX_DIM]> {
    let n = m.nrows();
    let mut out = [[0.0; MAX_DIM]; MAX_DIM];
    if m.iter().all(|&x| x == 0.0) {
        return Some(out);
    }
    let l = m.clone().cholesky()?.l();
    for i in 0..n {
        for j in 0..=i {
            out[i][j] = l[(i, j)];
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::SeedableRng;

    fn sample_variance(filter: FormFilter, level: f64, ts: f64, n: usize, seed: u64) -> f64 {
        let mut s = FormFilterSampler::new(&filter, level, ts).unwrap();
        let mut rng = StdRng::seed_from_u64(seed);
        s.start(&mut rng);
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let u = s.output();
            sum += u;
            sum2 += u * u;
            s.step(&mut rng);
        }
        let mean = sum / n as f64;
        sum2 / n as f64 - mean * mean
    }

    #[test]
    fn van_loan_matches_scalar_ou() {
        let a = 10.0;
        let h = 0.01;
        let (phi, q) = van_loan(
            &DMatrix::from_element(1, 1, -a),
            &DMatrix::from_element(1, 1, 1.0),
            h,
        );
        let phi_exact = (-a * h).exp();
        let q_exact = (1.0 - (-2.0 * a * h).exp()) / (2.0 * a);
        assert!((phi[(0, 0)] - phi_exact).abs() < 1e-14);
        assert!((q[(0, 0)] / q_exact - 1.0).abs() < 1e-12);
    }

    #[test]
    fn van_loan_is_consistent_with_the_stationary_covariance() {
        // P = Φ P Φᵀ + Q holds exactly for the stationary covariance P.
        let (w, z) = (3.0, 0.2);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * z * w]);
        let l = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, 0.0, 1.0]);
        let (phi, q) = van_loan(&a, &l, 0.05);
        let p = DMatrix::from_row_slice(
            2,
            2,
            &[1.0 / (4.0 * z * w * w * w), 0.0, 0.0, 1.0 / (4.0 * z * w)],
        );
        let back = &phi * &p * phi.transpose() + q;
        assert!((back - &p).norm() < 1e-12 * p.norm());
    }

    #[test]
    fn lowpass_variance_matches_theory() {
        // var = level² / (2a); the relative standard error of the estimate over n
        // samples with correlation time 1/a is about sqrt(2 / (a n ts)) = 1 % here.
        let (a, level, ts) = (10.0, 6.0, 0.01);
        let v = sample_variance(FormFilter::Lowpass { corner: a }, level, ts, 200_000, 7);
        let theory = level * level / (2.0 * a);
        assert!((v / theory - 1.0).abs() < 0.03, "{v} vs {theory}");
    }

    #[test]
    fn second_order_variance_matches_theory() {
        let (w, z, level, ts) = (5.0, 0.3, 15.0, 0.01);
        let v = sample_variance(
            FormFilter::SecondOrder {
                freq: w,
                damping: z,
            },
            level,
            ts,
            400_000,
            8,
        );
        let theory = level * level / (4.0 * z * w * w * w);
        assert!((v / theory - 1.0).abs() < 0.04, "{v} vs {theory}");
    }

    #[test]
    fn white_variance_is_intensity_over_sample_interval() {
        let v = sample_variance(FormFilter::White, 2.0, 0.01, 100_000, 9);
        assert!((v / 400.0 - 1.0).abs() < 0.02, "{v}");
    }

    #[test]
    fn bad_filters_are_rejected() {
        assert!(FormFilterSampler::new(&FormFilter::Lowpass { corner: -1.0 }, 1.0, 0.01).is_err());
        assert!(FormFilterSampler::new(
            &FormFilter::SecondOrder {
                freq: 1.0,
                damping: 0.0
            },
            1.0,
            0.01
        )
        .is_err());
        assert!(FormFilterSampler::new(&FormFilter::White, f64::NAN, 0.01).is_err());
    }
}
