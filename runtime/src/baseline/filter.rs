//! The two low-pass filters of the baselines.
//!
//! [`Butterworth`]: a digital Butterworth low-pass of order `N` as a cascade of second-order
//! sections (and one first-order section for odd `N`), from the analogue prototype by the
//! bilinear transform with the corner pre-warped (`K = tan(π f_c / f_s)`): section `k` has
//! damping `ζₖ = sin((2k − 1) π / (2N))`. [`Butterworth::filtfilt`] runs it forward and
//! backward, so the result has no phase and the magnitude `|H|²` (−6 dB at the corner,
//! order `2N` roll-off).
//!
//! [`StateVariableFilter`]: the same Butterworth low-pass in continuous time, of order 4,
//! `L(s) = ω_c⁴ / D(s)`, in controllable canonical form with states scaled by powers of
//! `ω_c` (`ξᵢ = (L x)⁽ⁱ⁾ / ω_cⁱ`, so every entry of the generator is `ω_c` times a number of
//! order one), discretised exactly for an input linear between samples (first-order hold):
//!
//! ```text
//! ξ[k+1] = Φ ξ[k] + Γ₀ x[k] + Γ₁ x[k+1]
//! ```
//!
//! with `Φ, Γ₀, Γ₁` read off the matrix exponential of `[[A Tₛ, B Tₛ, 0], [0, 0, 1],
//! [0, 0, 0]]`. Its states are the filtered signal and its first three derivatives.

use nalgebra::DMatrix;
use std::f64::consts::PI;

/// `ln 100`: a filter's memory is the time its impulse response's envelope takes to fall
/// to 1 %.
const LN_100: f64 = 4.605_170_185_988_091;

/// Dampings `ζₖ` of the second-order factors `s² + 2ζₖ ω s + ω²` of an order-`n` Butterworth
/// polynomial (and whether a first-order factor `s + ω` remains).
fn dampings(order: usize) -> (Vec<f64>, bool) {
    let n = order as f64;
    let z = (1..=order / 2)
        .map(|k| ((2 * k - 1) as f64 * PI / (2.0 * n)).sin())
        .collect();
    (z, order % 2 == 1)
}

/// Samples over which a Butterworth low-pass of `order` at `corner_hz` forgets: its slowest
/// pole's envelope `exp(−ζ_min ω_c t)` falls to 1 % (`ζ_min = sin(π / 2N)`, 1 for order 1).
pub(crate) fn memory_samples(order: usize, corner_hz: f64, ts: f64) -> f64 {
    let (z, _) = dampings(order);
    let zmin = z.iter().copied().fold(1.0, f64::min);
    LN_100 / (zmin * 2.0 * PI * corner_hz * ts)
}

/// A digital Butterworth low-pass as second-order sections `[b0, b1, b2, a1, a2]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Butterworth {
    pub(super) sections: Vec<[f64; 5]>,
}

impl Butterworth {
    /// Order `order ≥ 1`, corner `corner_hz` at sample interval `ts`; the caller keeps the
    /// corner below the Nyquist frequency.
    pub fn lowpass(order: usize, corner_hz: f64, ts: f64) -> Butterworth {
        let k = (PI * corner_hz * ts).tan();
        let (z, odd) = dampings(order);
        let mut sections: Vec<[f64; 5]> = z
            .iter()
            .map(|&z| {
                let norm = 1.0 / (1.0 + 2.0 * z * k + k * k);
                let b0 = k * k * norm;
                [
                    b0,
                    2.0 * b0,
                    b0,
                    2.0 * (k * k - 1.0) * norm,
                    (1.0 - 2.0 * z * k + k * k) * norm,
                ]
            })
            .collect();
        if odd {
            let b0 = k / (1.0 + k);
            sections.push([b0, b0, 0.0, (k - 1.0) / (1.0 + k), 0.0]);
        }
        Butterworth { sections }
    }

    /// Zero-phase filtering of `x` into `out` (same length): forward then backward through
    /// every section. Edges: `x` is first extended by `pad` samples at each end by odd
    /// reflection about its end values (`2 x₀ − x_k`), which continues value and slope, and
    /// each pass starts every section in its steady state for the first value it sees; the
    /// caller still discards the samples within the filter's memory of either end (the
    /// reflection does not continue the curvature). `pad` is clipped to `x.len() − 1`.
    pub fn filtfilt(&self, x: &[f64], pad: usize, out: &mut Vec<f64>) {
        out.clear();
        let n = x.len();
        if n == 0 {
            return;
        }
        let pad = pad.min(n - 1);
        let mut ext = Vec::with_capacity(n + 2 * pad);
        ext.extend((1..=pad).rev().map(|k| 2.0 * x[0] - x[k]));
        ext.extend_from_slice(x);
        ext.extend((1..=pad).map(|k| 2.0 * x[n - 1] - x[n - 1 - k]));
        for s in &self.sections {
            run_section(s, ext.iter_mut());
        }
        for s in &self.sections {
            run_section(s, ext.iter_mut().rev());
        }
        out.extend_from_slice(&ext[pad..pad + n]);
    }
}

/// One section in transposed direct form II over `x` in place, from its steady state for
/// the first value (a low-pass has unit gain at zero frequency: `b0 + b1 + b2 = 1 + a1 + a2`).
fn run_section<'a>(s: &[f64; 5], x: impl Iterator<Item = &'a mut f64>) {
    let [b0, b1, b2, a1, a2] = *s;
    let mut x = x.peekable();
    let first = x.peek().map_or(0.0, |v| **v);
    let mut z2 = (b2 - a2) * first;
    let mut z1 = (b1 - a1) * first + z2;
    for v in x {
        let u = *v;
        let y = b0 * u + z1;
        z1 = b1 * u - a1 * y + z2;
        z2 = b2 * u - a2 * y;
        *v = y;
    }
}

/// The fourth-order Butterworth state-variable filter, discretised exactly for
/// piecewise-linear input (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct StateVariableFilter {
    /// Corner in rad/s.
    pub omega: f64,
    phi: [[f64; 4]; 4],
    g0: [f64; 4],
    g1: [f64; 4],
}

impl StateVariableFilter {
    /// Order of the filter (the number of states).
    pub const ORDER: usize = 4;

    /// The filter with corner `corner_hz` at sample interval `ts`.
    pub fn new(corner_hz: f64, ts: f64) -> StateVariableFilter {
        let w = 2.0 * PI * corner_hz;
        // D(p) = Π (p² + 2ζₖ p + 1) in p = s/ω: coefficients c[0] + c[1] p + … + p⁴.
        let (z, _) = dampings(Self::ORDER);
        let mut c = vec![1.0];
        for z in z {
            let f = [1.0, 2.0 * z, 1.0];
            let mut next = vec![0.0; c.len() + 2];
            for (i, ci) in c.iter().enumerate() {
                for (j, fj) in f.iter().enumerate() {
                    next[i + j] += ci * fj;
                }
            }
            c = next;
        }
        // ξᵢ' = ω ξᵢ₊₁ (i < 3), ξ₃' = ω (x − Σ cᵢ ξᵢ); augmented with [x, Δx].
        let n = Self::ORDER;
        let h = w * ts;
        let mut m = DMatrix::<f64>::zeros(n + 2, n + 2);
        for i in 0..n - 1 {
            m[(i, i + 1)] = h;
        }
        for (i, ci) in c.iter().take(n).enumerate() {
            m[(n - 1, i)] = -h * ci;
        }
        m[(n - 1, n)] = h;
        m[(n, n + 1)] = 1.0;
        let e = m.exp();
        let mut f = StateVariableFilter {
            omega: w,
            phi: [[0.0; 4]; 4],
            g0: [0.0; 4],
            g1: [0.0; 4],
        };
        for i in 0..n {
            for j in 0..n {
                f.phi[i][j] = e[(i, j)];
            }
            f.g1[i] = e[(i, n + 1)];
            f.g0[i] = e[(i, n)] - e[(i, n + 1)];
        }
        f
    }

    /// Group delay at zero frequency in seconds: `D'(0) / (D(0) ω)`.
    pub fn delay(&self) -> f64 {
        let (z, _) = dampings(Self::ORDER);
        2.0 * z.iter().sum::<f64>() / self.omega
    }

    /// Samples over which the filter forgets (see [`memory_samples`]).
    pub fn memory(&self, ts: f64) -> f64 {
        memory_samples(Self::ORDER, self.omega / (2.0 * PI), ts)
    }

    /// Run the filter over `x` from rest; `out[d]` receives the `d`-th derivative of the
    /// filtered signal for each `d < out.len() ≤ 4` (each cleared, then filled to `x.len()`).
    pub fn run(&self, x: &[f64], out: &mut [&mut Vec<f64>]) {
        let scale: Vec<f64> = (0..out.len()).map(|d| self.omega.powi(d as i32)).collect();
        out.iter_mut().for_each(|o| o.clear());
        let mut xi = [0.0; 4];
        let mut prev = x.first().copied().unwrap_or(0.0);
        for (k, &v) in x.iter().enumerate() {
            if k > 0 {
                let mut next = [0.0; 4];
                for (i, nx) in next.iter_mut().enumerate() {
                    *nx = self.phi[i].iter().zip(&xi).map(|(p, s)| p * s).sum::<f64>()
                        + self.g0[i] * prev
                        + self.g1[i] * v;
                }
                xi = next;
            }
            prev = v;
            for (d, o) in out.iter_mut().enumerate() {
                o.push(xi[d] * scale[d]);
            }
        }
    }
}
