//! The reference chain: the exact discretisation of one chain `(λ, order)` and its
//! recursion, run sample by sample.

use nalgebra::DMatrix;

/// Exact discretisation of one chain `(λ, order)`.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainDisc {
    pub order: usize,
    /// `Φ`, row-major `order × order` (lower triangular).
    pub phi: Vec<f64>,
    pub g0: Vec<f64>,
    pub g1: Vec<f64>,
}

/// How the input is assumed to behave between samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Hold {
    /// Piecewise linear: exact for smooth signals up to `O(Tₛ²)` interpolation error.
    FirstOrder,
    /// Piecewise constant: biased, for comparison only.
    ZeroOrder,
}

impl ChainDisc {
    /// Most samples of an impulse response [`Self::noise_covariance`] sums: a chain whose
    /// memory is longer (`λ Tₛ` below about 3·10⁻⁶) is truncated there.
    pub const MAX_MEMORY: usize = 10_000_000;

    /// Discretise the chain with corner `lambda` (rad/s) and `order` sections.
    pub fn new(lambda: f64, order: usize, ts: f64, hold: Hold) -> ChainDisc {
        let n = order;
        let mut m = DMatrix::<f64>::zeros(n + 2, n + 2);
        for i in 0..n {
            m[(i, i)] = -lambda * ts;
            if i > 0 {
                m[(i, i - 1)] = lambda * ts;
            }
        }
        m[(0, n)] = lambda * ts;
        m[(n, n + 1)] = 1.0;
        let e = m.exp();
        let mut phi = vec![0.0; n * n];
        let mut g0 = vec![0.0; n];
        let mut g1 = vec![0.0; n];
        for i in 0..n {
            for j in 0..n {
                phi[i * n + j] = e[(i, j)];
            }
            match hold {
                Hold::FirstOrder => {
                    g1[i] = e[(i, n + 1)];
                    g0[i] = e[(i, n)] - e[(i, n + 1)];
                }
                Hold::ZeroOrder => g0[i] = e[(i, n)],
            }
        }
        ChainDisc {
            order: n,
            phi,
            g0,
            g1,
        }
    }

    /// Covariance of the chain's states (row-major `order × order`) when its driving
    /// samples are white noise of unit variance: `Σₘ hₘ hₘᵀ` over the impulse response of
    /// one sample, `h₀ = Γ₁` (the sample is the hold's newer end), `h₁ = Φ Γ₁ + Γ₀`,
    /// `hₘ = Φ hₘ₋₁`, summed until the response has decayed to 10⁻¹⁰ of its largest
    /// squared norm (the chain's memory; a stable chain's response decays geometrically),
    /// and over at most [`Self::MAX_MEMORY`] samples.
    pub fn noise_covariance(&self) -> Vec<f64> {
        let n = self.order;
        let mut p = vec![0.0; n * n];
        let mut h = self.g1.clone();
        let mut next = vec![0.0; n];
        let mut peak = 0.0f64;
        for m in 0..Self::MAX_MEMORY {
            let norm: f64 = h.iter().map(|v| v * v).sum();
            peak = peak.max(norm);
            if m > 1 && norm <= 1e-10 * peak {
                break;
            }
            for i in 0..n {
                for j in 0..n {
                    p[i * n + j] += h[i] * h[j];
                }
            }
            for (i, nx) in next.iter_mut().enumerate() {
                let row = &self.phi[i * n..(i + 1) * n];
                *nx = row.iter().zip(&h).map(|(a, b)| a * b).sum::<f64>()
                    + if m == 0 { self.g0[i] } else { 0.0 };
            }
            std::mem::swap(&mut h, &mut next);
        }
        p
    }

    /// Advance one chain over a block of driving samples.
    ///
    /// `state` holds `ζ` at the sample before `s[0]` (with `s_prev` the driving value there);
    /// on return it holds `ζ` at the last sample. `out[i * stride + k]` receives `ζᵢ₊₁` at
    /// sample `k`.
    #[inline]
    pub fn run(&self, state: &mut [f64], s_prev: f64, s: &[f64], out: &mut [f64], stride: usize) {
        let n = self.order;
        if n == 3 {
            self.run3(state, s_prev, s, out, stride);
            return;
        }
        let mut prev = s_prev;
        let mut next = vec![0.0; n];
        for (k, &sk) in s.iter().enumerate() {
            for (i, nx) in next.iter_mut().enumerate() {
                let row = &self.phi[i * n..i * n + i + 1];
                let acc: f64 = row.iter().zip(state.iter()).map(|(p, z)| p * z).sum();
                *nx = acc + self.g0[i] * prev + self.g1[i] * sk;
            }
            for (i, &nx) in next.iter().enumerate() {
                state[i] = nx;
                out[i * stride + k] = nx;
            }
            prev = sk;
        }
    }

    /// The common order-3 chain, unrolled (the hot loop of identification).
    #[inline]
    pub(super) fn run3(
        &self,
        state: &mut [f64],
        s_prev: f64,
        s: &[f64],
        out: &mut [f64],
        stride: usize,
    ) {
        let len = s.len();
        let p = &self.phi;
        let (p00, p10, p11, p20, p21, p22) = (p[0], p[3], p[4], p[6], p[7], p[8]);
        let (a0, a1, a2) = (self.g0[0], self.g0[1], self.g0[2]);
        let (b0, b1, b2) = (self.g1[0], self.g1[1], self.g1[2]);
        let (mut z0, mut z1, mut z2) = (state[0], state[1], state[2]);
        let (o0, rest) = out.split_at_mut(stride);
        let (o1, o2) = rest.split_at_mut(stride);
        let (o0, o1, o2) = (&mut o0[..len], &mut o1[..len], &mut o2[..len]);
        let mut prev = s_prev;
        for k in 0..len {
            let sk = s[k];
            let n0 = p00 * z0 + a0 * prev + b0 * sk;
            let n1 = p10 * z0 + p11 * z1 + a1 * prev + b1 * sk;
            let n2 = p20 * z0 + p21 * z1 + p22 * z2 + a2 * prev + b2 * sk;
            z0 = n0;
            z1 = n1;
            z2 = n2;
            o0[k] = z0;
            o1[k] = z1;
            o2[k] = z2;
            prev = sk;
        }
        state[0] = z0;
        state[1] = z1;
        state[2] = z2;
    }
}
