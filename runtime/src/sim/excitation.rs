//! The deterministic excitations of structural testing: multisines and sine sweeps.
//!
//! A [`TestSignal`] replaces the form filter of every excited input of a run (references
//! keep theirs). Like a form filter it is evaluated exactly at every point of the input
//! grid (`Ts / input_oversample`) and interpolated linearly between grid points inside the
//! RK4 sub-steps (first-order hold): a DAC followed by its reconstruction filter, not a
//! zero-order hold. With `input_oversample = 1` the identification's filters discretise
//! exactly this input.
//!
//! - **Multisine** (level = RMS of the input): `u(t) = Σ_k A cos(2π k f₀ t + φ_k)` over the
//!   lines `k f₀` of the band `[f_min_hz, f_max_hz]` (Hz), `f₀ = periods / duration` so the
//!   record holds an integer number of periods; the full grid takes every line, the odd
//!   grid the odd `k` only (the even lines then show the nonlinear distortion). `A =
//!   level·√(2/L)` for `L` lines, so the RMS is the level. Phases are random (uniform, drawn
//!   per level from the excitation stream) or Schroeder's (`φ_l = −π l(l−1)/L`, a low crest
//!   factor). One period is tabulated on the input grid by an inverse real FFT, so the
//!   signal is exactly periodic; the burn-in runs whole periods of it and the record starts
//!   at phase 0 of a period.
//! - **Sweep** (level = amplitude): `u(t) = level · sin(θ(t))`, the instantaneous frequency
//!   going from `f_start_hz` to `f_end_hz` over one sweep of `duration / sweeps` seconds,
//!   linearly (`θ = 2π(f₁t + (f₂−f₁)t²/(2T))`) or logarithmically
//!   (`θ = 2π f₁ T (r^{t/T} − 1)/ln r`, `r = f₂/f₁`); the sweep repeats, the burn-in
//!   included, and the record starts at the start of a sweep.

use rand::Rng;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Most points of one tabulated multisine period (128 MiB of `f64`).
pub const MAX_PERIOD_POINTS: usize = 1 << 24;

/// Lines of a multisine's frequency grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Grid {
    /// Every harmonic of `f₀` in the band.
    Full,
    /// The odd harmonics of `f₀` in the band.
    Odd,
}

/// Phases of a multisine's lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phases {
    /// Independent, uniform on `[0, 2π)`, drawn per level.
    Random,
    /// Schroeder's low-crest-factor phases (the same at every level).
    Schroeder,
}

/// How a sweep's frequency moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepLaw {
    Linear,
    Log,
}

/// A deterministic excitation of every excited input (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TestSignal {
    /// Level = RMS of the input.
    Multisine {
        f_min_hz: f64,
        f_max_hz: f64,
        /// Whole periods in the recorded duration.
        periods: usize,
        grid: Grid,
        phases: Phases,
    },
    /// Level = amplitude of the input.
    Sweep {
        f_start_hz: f64,
        f_end_hz: f64,
        law: SweepLaw,
        /// Sweeps in the recorded duration.
        sweeps: usize,
    },
}

impl TestSignal {
    /// Periods (multisine) or sweeps in the record.
    pub fn periods(&self) -> usize {
        match *self {
            TestSignal::Multisine { periods, .. } => periods,
            TestSignal::Sweep { sweeps, .. } => sweeps,
        }
    }

    /// Check the signal against a record of `n` samples at interval `ts`; `Err` is
    /// `(what, help)`.
    pub fn check(&self, n: usize, ts: f64, fine: usize) -> Result<(), (String, String)> {
        let nyquist = 0.5 / ts;
        let band_ok = |lo: f64, hi: f64| lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > 0.0;
        let p = self.periods();
        if p == 0 {
            return Err((
                "0 periods".into(),
                "give at least one period (or sweep) per record".into(),
            ));
        }
        if !n.is_multiple_of(p) {
            return Err((
                format!("{n} samples in {p} periods"),
                format!(
                    "the record must hold a whole number of samples per period: make the samples (duration / sample = {n}) a multiple of the periods, e.g. --periods {}",
                    divisor_near(n, p)
                ),
            ));
        }
        match *self {
            TestSignal::Multisine {
                f_min_hz,
                f_max_hz,
                grid,
                ..
            } => {
                if !band_ok(f_min_hz, f_max_hz) || f_min_hz > f_max_hz || f_max_hz >= nyquist {
                    return Err((
                        format!("multisine band {f_min_hz}–{f_max_hz} Hz"),
                        format!(
                            "give a band 0 < low ≤ high below the Nyquist frequency {nyquist} Hz"
                        ),
                    ));
                }
                let period = (n / p) as f64 * ts;
                if lines(f_min_hz, f_max_hz, period, grid).is_empty() {
                    return Err((
                        format!(
                            "no {} line of 1/{period} Hz in the band {f_min_hz}–{f_max_hz} Hz",
                            if grid == Grid::Odd { "odd" } else { "" }
                        ),
                        "widen the band or lengthen the period (fewer periods or a longer duration)".into(),
                    ));
                }
                if (n / p).saturating_mul(fine) > MAX_PERIOD_POINTS {
                    return Err((
                        format!("a multisine period of {} input points", (n / p) * fine),
                        format!("a period is tabulated, at most {MAX_PERIOD_POINTS} points: give more periods"),
                    ));
                }
            }
            TestSignal::Sweep {
                f_start_hz,
                f_end_hz,
                ..
            } => {
                if !band_ok(f_start_hz, f_end_hz) || f_start_hz >= nyquist || f_end_hz >= nyquist {
                    return Err((
                        format!("sweep {f_start_hz}–{f_end_hz} Hz"),
                        format!("give positive start and end frequencies below the Nyquist frequency {nyquist} Hz"),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A divisor of `n` near `p` (for a help line).
fn divisor_near(n: usize, p: usize) -> usize {
    (1..=n.max(1))
        .filter(|d| n.is_multiple_of(*d))
        .min_by_key(|d| d.abs_diff(p))
        .unwrap_or(1)
}

/// Harmonic numbers `k` of `1/period` in `[lo, hi]` Hz on `grid`.
pub fn lines(lo: f64, hi: f64, period: f64, grid: Grid) -> Vec<usize> {
    let k0 = (lo * period - 1e-9).ceil().max(1.0) as usize;
    let k1 = (hi * period + 1e-9).floor().max(0.0) as usize;
    (k0..=k1)
        .filter(|k| grid == Grid::Full || k % 2 == 1)
        .collect()
}

/// One input driven by a [`TestSignal`] at one level, stepped on the input grid.
#[derive(Clone, Debug)]
pub(crate) struct SignalSampler {
    signal: TestSignal,
    level: f64,
    /// Input grid interval.
    h: f64,
    /// Input-grid points per period (sweep).
    period_points: usize,
    /// Grid points since the start of the current period.
    i: usize,
    /// One multisine period (filled by `start`).
    table: Vec<f64>,
    /// Multisine lines `k`.
    lines: Vec<usize>,
}

impl SignalSampler {
    /// `signal` at `level` for a record of `n` samples at `ts`, `fine` grid points per
    /// sample, after `n_burn` burn-in samples. `Err` carries the reason.
    pub(crate) fn new(
        signal: &TestSignal,
        level: f64,
        ts: f64,
        fine: usize,
        n_burn: usize,
        n: usize,
    ) -> Result<Self, String> {
        if !(level.is_finite() && level >= 0.0) {
            return Err(format!("level {level} is not a finite non-negative number"));
        }
        signal
            .check(n, ts, fine)
            .map_err(|(what, help)| format!("{what}: {help}"))?;
        let fine = fine.max(1);
        let period_points = n / signal.periods() * fine;
        let lines = match *signal {
            TestSignal::Multisine {
                f_min_hz,
                f_max_hz,
                grid,
                periods,
                ..
            } => lines(f_min_hz, f_max_hz, (n / periods) as f64 * ts, grid),
            TestSignal::Sweep { .. } => Vec::new(),
        };
        // Start so that the record (after `n_burn` samples) opens a period.
        let burn = (n_burn * fine) % period_points;
        Ok(SignalSampler {
            signal: *signal,
            level,
            h: ts / fine as f64,
            period_points,
            i: (period_points - burn) % period_points,
            table: Vec::new(),
            lines,
        })
    }

    /// Draw the phases (random multisine) and tabulate a multisine period.
    pub(crate) fn start(&mut self, rng: &mut impl Rng) {
        if let TestSignal::Multisine { phases, .. } = self.signal {
            let nl = self.lines.len() as f64;
            let phi: Vec<f64> = (0..self.lines.len())
                .map(|l| match phases {
                    Phases::Random => rng.random::<f64>() * 2.0 * PI,
                    Phases::Schroeder => -PI * (l as f64) * (l as f64 + 1.0) / nl,
                })
                .collect();
            let amp = self.level * (2.0 / nl).sqrt();
            self.table = tabulate(self.period_points, &self.lines, amp, &phi);
        }
    }

    /// Advance by one grid point.
    #[inline]
    pub(crate) fn step(&mut self) {
        self.i += 1;
        if self.i == self.period_points {
            self.i = 0;
        }
    }

    /// The input now.
    #[inline]
    pub(crate) fn output(&self) -> f64 {
        match self.signal {
            TestSignal::Multisine { .. } => self.table.get(self.i).copied().unwrap_or(0.0),
            TestSignal::Sweep {
                f_start_hz,
                f_end_hz,
                law,
                ..
            } => {
                self.level
                    * sweep_phase(
                        f_start_hz,
                        f_end_hz,
                        law,
                        self.i as f64 * self.h,
                        self.period_points as f64 * self.h,
                    )
                    .sin()
            }
        }
    }

    /// A scale of the input for the divergence check.
    pub(crate) fn output_std(&self) -> f64 {
        match self.signal {
            TestSignal::Multisine { .. } => self.level,
            TestSignal::Sweep { .. } => self.level / 2f64.sqrt(),
        }
    }
}

/// Phase `θ(t)` of a sweep from `f1` to `f2` Hz over `t_sweep` seconds.
pub fn sweep_phase(f1: f64, f2: f64, law: SweepLaw, t: f64, t_sweep: f64) -> f64 {
    let r = f2 / f1;
    match law {
        SweepLaw::Log if (r - 1.0).abs() > 1e-12 => {
            2.0 * PI * f1 * t_sweep * ((r.ln() * t / t_sweep).exp() - 1.0) / r.ln()
        }
        _ => 2.0 * PI * (f1 * t + (f2 - f1) * t * t / (2.0 * t_sweep)),
    }
}

/// `Σ amp·cos(2π k j / n + φ)` over `lines` for `j = 0 … n−1`, by one inverse real FFT.
fn tabulate(n: usize, lines: &[usize], amp: f64, phi: &[f64]) -> Vec<f64> {
    let ifft = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
    let mut spec = ifft.make_input_vec();
    for (&k, &p) in lines.iter().zip(phi) {
        // `check` keeps every line below the Nyquist frequency of the sample grid.
        if let Some(s) = spec.get_mut(k) {
            *s = Complex::from_polar(0.5 * amp, p);
        }
    }
    let mut out = ifft.make_output_vec();
    // Bins 0 (and n/2 for even n) are zero, as the inverse transform requires.
    ifft.process(&mut spec, &mut out)
        .expect("invariant: buffers made by the plan, real DC and Nyquist bins");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::SeedableRng;

    fn multisine(grid: Grid, phases: Phases) -> TestSignal {
        TestSignal::Multisine {
            f_min_hz: 0.2,
            f_max_hz: 3.0,
            periods: 4,
            grid,
            phases,
        }
    }

    #[test]
    fn multisine_table_is_the_sum_of_its_cosines_with_the_level_as_rms() {
        let (ts, n) = (0.01, 4000);
        for (grid, phases) in [(Grid::Full, Phases::Random), (Grid::Odd, Phases::Schroeder)] {
            let sig = multisine(grid, phases);
            let mut s = SignalSampler::new(&sig, 2.5, ts, 1, 0, n).unwrap();
            s.start(&mut StdRng::seed_from_u64(3));
            // Period 10 s: lines 2 … 30 (full), 3, 5 … 29 (odd).
            let want: Vec<usize> = (2..=30)
                .filter(|k| grid == Grid::Full || k % 2 == 1)
                .collect();
            assert_eq!(s.lines, want);
            let period = 1000;
            let mut sum2 = 0.0;
            for j in 0..n {
                let u = s.output();
                if j < period {
                    sum2 += u * u;
                } else {
                    assert_eq!(u, s.table[j % period], "periodic at {j}");
                }
                s.step();
            }
            assert!(((sum2 / period as f64).sqrt() / 2.5 - 1.0).abs() < 1e-12);
            // Every grid line at the same amplitude, nothing off the grid.
            let fwd = RealFftPlanner::<f64>::new().plan_fft_forward(period);
            let mut x = s.table.clone();
            let mut spec = fwd.make_output_vec();
            fwd.process(&mut x, &mut spec).unwrap();
            for (k, c) in spec.iter().enumerate() {
                let on = want.contains(&k);
                let mag = c.norm() * 2.0 / period as f64;
                let amp = 2.5 * (2.0 / want.len() as f64).sqrt();
                if on {
                    assert!((mag / amp - 1.0).abs() < 1e-10, "line {k}: {mag}");
                } else {
                    assert!(mag < 1e-10 * amp, "bin {k} off the grid: {mag}");
                }
            }
        }
    }

    #[test]
    fn record_starts_a_period_after_the_burn_in() {
        let sig = multisine(Grid::Full, Phases::Schroeder);
        let mut s = SignalSampler::new(&sig, 1.0, 0.01, 2, 333, 4000).unwrap();
        s.start(&mut StdRng::seed_from_u64(1));
        for _ in 0..333 * 2 {
            s.step();
        }
        assert_eq!(s.i, 0);
    }

    #[test]
    fn sweep_frequency_moves_from_start_to_end() {
        for law in [SweepLaw::Linear, SweepLaw::Log] {
            let (f1, f2, t) = (0.5, 4.0, 20.0);
            let d = 1e-6;
            let f = |x: f64| {
                (sweep_phase(f1, f2, law, x + d, t) - sweep_phase(f1, f2, law, x - d, t))
                    / (2.0 * d * 2.0 * PI)
            };
            assert!((f(d) / f1 - 1.0).abs() < 1e-6, "{law:?}");
            assert!((f(t - d) / f2 - 1.0).abs() < 1e-6, "{law:?}");
            let mid = f(t / 2.0);
            let want = if law == SweepLaw::Linear {
                0.5 * (f1 + f2)
            } else {
                (f1 * f2).sqrt()
            };
            assert!((mid / want - 1.0).abs() < 1e-6, "{law:?} {mid}");
        }
    }

    #[test]
    fn bad_signals_are_refused() {
        let ok = multisine(Grid::Full, Phases::Random);
        assert!(ok.check(4000, 0.01, 1).is_ok());
        // 4001 samples do not split into 4 periods.
        assert!(ok.check(4001, 0.01, 1).is_err());
        let high = TestSignal::Multisine {
            f_min_hz: 1.0,
            f_max_hz: 60.0,
            periods: 1,
            grid: Grid::Full,
            phases: Phases::Random,
        };
        assert!(high.check(4000, 0.01, 1).is_err());
        // Period 1 s: no odd line in 2.1–2.9 Hz.
        let empty = TestSignal::Multisine {
            f_min_hz: 2.1,
            f_max_hz: 2.9,
            periods: 40,
            grid: Grid::Odd,
            phases: Phases::Random,
        };
        assert!(empty.check(4000, 0.01, 1).is_err());
        let sweep = TestSignal::Sweep {
            f_start_hz: 0.0,
            f_end_hz: 3.0,
            law: SweepLaw::Log,
            sweeps: 1,
        };
        assert!(sweep.check(4000, 0.01, 1).is_err());
        assert!(SignalSampler::new(&ok, f64::NAN, 0.01, 1, 0, 4000).is_err());
    }
}
