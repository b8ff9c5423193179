//! The identification filter bank: chains of first-order low-pass sections, discretised
//! exactly for piecewise-linear (first-order-hold) input.
//!
//! One chain per (driving signal `s`, corner `λ`) of order `n`:
//!
//! ```text
//! ζ₁' = λ (s − ζ₁),   ζᵢ' = λ (ζᵢ₋₁ − ζᵢ)  (i = 2 … n)
//! ```
//!
//! so state `ζᵢ` has relative degree `i` with respect to `s`. In state form the whole bank is
//! `ζ' = F ζ + H s` with block-diagonal `F`. Sampling with interval `Tₛ` and assuming `s` linear
//! between samples, the exact recursion is
//!
//! ```text
//! ζ[k+1] = Φ ζ[k] + Γ₀ s[k] + Γ₁ s[k+1]
//! ```
//!
//! with `Φ, Γ₀, Γ₁` read off the matrix exponential of the augmented generator
//! `[[F Tₛ, H Tₛ, 0], [0, 0, 1], [0, 0, 0]]` (state `[ζ, s, Δs]`). A zero-order hold instead
//! (`Γ₀ = ∫Φ H`, `Γ₁ = 0`) delays the input by half a sample, which at `Tₛ = 0.01 s` biases a
//! damping estimate by tens of percent; it is kept only for the comparison test.

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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hold {
    /// Piecewise linear: exact for smooth signals up to `O(Tₛ²)` interpolation error.
    FirstOrder,
    /// Piecewise constant: biased, for comparison only.
    ZeroOrder,
}

impl ChainDisc {
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
    fn run3(&self, state: &mut [f64], s_prev: f64, s: &[f64], out: &mut [f64], stride: usize) {
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

/// Chains of one driver updated together by one vector operation.
pub const LANES: usize = 4;

/// `LANES` chains side by side.
type Lane = [f64; LANES];

/// Largest filter order of the bank (the order check of identification enforces it).
pub const MAX_ORDER: usize = 8;

/// The whole bank in structure-of-arrays form: every driver's chains (one per corner) in
/// blocks of [`LANES`], so that one sample updates a block with a few straight-line vector
/// operations whatever the number of corners (a partial last block runs on zero
/// coefficients and stays zero).
///
/// Each chain follows the recursion of [`ChainDisc::run`], with the sums of a step taken
/// in another order and fused (see [`step`]): the outputs agree to rounding. Where the
/// processor has them, 512-bit (eight chains) or 256-bit (four chains, one block) vector
/// instructions do the work ([`FilterBank::advance`]), with the same operations in the same
/// order as the portable code: the outputs are the same bit for bit on every processor.
///
/// Outputs are written sample-major: at sample `k`, row [`FilterBank::row`]`(d, c, i)` of
/// `out[k · stride ..]` receives state `ζᵢ₊₁` of the chain of driver `d` and corner `c`,
/// the corners of one driver and state side by side (no padding rows). Sample-major is
/// what the moment accumulation multiplies with, and stores a sample's states in a few
/// contiguous runs.
#[derive(Clone, Debug)]
pub struct FilterBank {
    order: usize,
    n_drivers: usize,
    n_corners: usize,
    /// Blocks per driver, `⌈n_corners / LANES⌉`.
    bpd: usize,
    /// Per block: `Φ` (full `order × order`, row-major), `Γ₀`, `Γ₁`, each entry a lane.
    coef: Vec<Lane>,
    /// `Φ^(2^j)` per block (full `order × order`, row-major), `j = 0, 1, …`: the free
    /// response over any number of samples by binary powering.
    pow: Vec<Vec<Lane>>,
}

/// The state of a [`FilterBank`] after some sample: `ζ` of every chain and the driving
/// values at that sample (the `s[k]` of the next step).
#[derive(Clone, Debug, PartialEq)]
pub struct BankState {
    /// Per block, per state `i`: one lane.
    z: Vec<Lane>,
    prev: Vec<f64>,
}

impl BankState {
    /// The state of chain `(d, c)`, `ζ₁ … ζ_order`.
    pub fn chain(&self, bank: &FilterBank, d: usize, c: usize) -> Vec<f64> {
        let blk = d * bank.bpd + c / LANES;
        (0..bank.order)
            .map(|i| self.z[blk * bank.order + i][c % LANES])
            .collect()
    }

    /// The driving values at the sample of this state.
    pub fn prev(&self) -> &[f64] {
        &self.prev
    }
}

/// One block's coefficients with the order fixed at compile time.
struct Block<const N: usize> {
    phi: [[Lane; N]; N],
    g0: [Lane; N],
    g1: [Lane; N],
}

#[inline(always)]
fn mul(a: &Lane, b: &Lane) -> Lane {
    std::array::from_fn(|l| a[l] * b[l])
}

/// `a · b + c` per lane, rounded once.
#[inline(always)]
fn fma(a: &Lane, b: &Lane, c: &Lane) -> Lane {
    std::array::from_fn(|l| a[l].mul_add(b[l], c[l]))
}

/// One step of one block: `ζ ← Φ ζ + Γ₀ s[k−1] + Γ₁ s[k]`, as one product and fused
/// multiply-adds (one rounding each): `Γ₀ s[k−1]`, then `+ Γ₁ s[k]`, then `+ Φᵢⱼ ζⱼ` for
/// `j = 0 … i`. The input part is formed first, off the path from one sample's state to
/// the next, and each state's own term comes last, so a state waits on one fused operation
/// of its own previous value. Every vector path does the same operations in the same
/// order: the bank's outputs are the same bit for bit on every processor. (The order of
/// the sums and the roundings differ from [`ChainDisc::run`]: the two agree to rounding.)
#[inline(always)]
fn step<const N: usize>(b: &Block<N>, z: &mut [Lane; N], prev: &Lane, s: &Lane) {
    // Downwards, so that the states below `i` are still the old ones (`Φ` is lower
    // triangular).
    for i in (0..N).rev() {
        let mut acc = fma(&b.g1[i], s, &mul(&b.g0[i], prev));
        for (p, zj) in b.phi[i].iter().zip(z.iter()).take(i + 1) {
            acc = fma(p, zj, &acc);
        }
        z[i] = acc;
    }
}

impl FilterBank {
    /// The bank of `n_drivers × corners.len()` chains of `order` sections (chain `(d, c)`
    /// driven by driver `d` with corner `corners[c]`).
    ///
    /// # Panics
    /// If `order` is not in `1 ..= MAX_ORDER` (checked with the filter options before).
    pub fn new(corners: &[f64], n_drivers: usize, order: usize, ts: f64, hold: Hold) -> Self {
        assert!(
            (1..=MAX_ORDER).contains(&order),
            "invariant: filter order {order} checked to lie in 1..={MAX_ORDER}"
        );
        let n_corners = corners.len();
        let bpd = n_corners.div_ceil(LANES);
        let n = order;
        let per = n * n + 2 * n;
        let mut coef = vec![[0.0; LANES]; n_drivers * bpd * per];
        let mut phi1 = vec![[0.0; LANES]; n_drivers * bpd * n * n];
        for (c, &lambda) in corners.iter().enumerate() {
            let disc = ChainDisc::new(lambda, order, ts, hold);
            for d in 0..n_drivers {
                let blk = d * bpd + c / LANES;
                let l = c % LANES;
                let base = blk * per;
                for i in 0..n {
                    for j in 0..=i {
                        coef[base + i * n + j][l] = disc.phi[i * n + j];
                        phi1[blk * n * n + i * n + j][l] = disc.phi[i * n + j];
                    }
                    coef[base + n * n + i][l] = disc.g0[i];
                    coef[base + n * n + n + i][l] = disc.g1[i];
                }
            }
        }
        let mut bank = FilterBank {
            order,
            n_drivers,
            n_corners,
            bpd,
            coef,
            pow: vec![phi1],
        };
        bank.extend_powers(1);
        bank
    }

    /// Rows written per sample.
    pub fn n_rows(&self) -> usize {
        self.n_drivers * self.order * self.n_corners
    }

    /// The output row of state `ζᵢ₊₁` of chain `(d, c)`.
    pub fn row(&self, d: usize, c: usize, i: usize) -> usize {
        (d * self.order + i) * self.n_corners + c
    }

    /// All chains at rest, with driving values `prev` at the current sample.
    pub fn state(&self, prev: &[f64]) -> BankState {
        assert_eq!(prev.len(), self.n_drivers);
        BankState {
            z: vec![[0.0; LANES]; self.n_drivers * self.bpd * self.order],
            prev: prev.to_vec(),
        }
    }

    /// Make `Φ^(2^j)` available for every `j` a count below `2^bits` needs.
    fn extend_powers(&mut self, bits: usize) {
        let n = self.order;
        while self.pow.len() < bits.max(1) {
            let last = self.pow.last().expect("invariant: Φ itself is there");
            let mut sq = vec![[0.0; LANES]; last.len()];
            for (dst, src) in sq.chunks_exact_mut(n * n).zip(last.chunks_exact(n * n)) {
                for i in 0..n {
                    for j in 0..=i {
                        for k in j..=i {
                            for l in 0..LANES {
                                dst[i * n + j][l] += src[i * n + k][l] * src[k * n + j][l];
                            }
                        }
                    }
                }
            }
            self.pow.push(sq);
        }
    }

    /// Make [`Self::propagate`] available for counts up to `max_steps`.
    pub fn prepare_propagation(&mut self, max_steps: usize) {
        self.extend_powers((usize::BITS - max_steps.leading_zeros()) as usize);
    }

    /// The free response: `ζ ← Φ^steps ζ` (the driving values are left alone).
    ///
    /// # Panics
    /// If `steps` exceeds what [`Self::prepare_propagation`] made available.
    pub fn propagate(&self, state: &mut BankState, steps: usize) {
        let n = self.order;
        let mut tmp = vec![[0.0; LANES]; n];
        let mut m = steps;
        let mut j = 0;
        while m > 0 {
            if m & 1 == 1 {
                let p = &self.pow[j];
                for (z, pm) in state.z.chunks_exact_mut(n).zip(p.chunks_exact(n * n)) {
                    for i in 0..n {
                        let mut acc = [0.0; LANES];
                        for k in 0..=i {
                            for l in 0..LANES {
                                acc[l] += pm[i * n + k][l] * z[k][l];
                            }
                        }
                        tmp[i] = acc;
                    }
                    z.copy_from_slice(&tmp);
                }
            }
            m >>= 1;
            j += 1;
        }
    }

    /// The state after a run of `steps` samples from `start`, given the end state `rest`
    /// of the same run from rest: `Φ^steps ζ_start + ζ_rest`, with the driving values of
    /// `rest` (the filter is linear).
    pub fn compose(&self, start: &BankState, steps: usize, rest: &BankState) -> BankState {
        let mut s = start.clone();
        self.propagate(&mut s, steps);
        self.add(&mut s, rest);
        s.prev.clone_from(&rest.prev);
        s
    }

    /// `state ← state + other` (the states of a linear system add).
    pub fn add(&self, state: &mut BankState, other: &BankState) {
        for (a, b) in state.z.iter_mut().zip(&other.z) {
            for l in 0..LANES {
                a[l] += b[l];
            }
        }
    }

    /// Advance over `len` samples: `drivers[d][k]` is driver `d` at the `k`-th sample after
    /// the state's. With `out = Some((buf, stride))`, the states at each sample are written
    /// to `buf[k · stride + row]` (see [`Self::row`]); `stride ≥ n_rows()`.
    ///
    /// Runs the AVX-512 path where the processor has it, else the AVX + FMA path, else the
    /// portable one (on an x86-64 processor without FMA, made before 2013, its fused
    /// multiply-adds are computed in software: the same numbers, many times slower).
    pub fn advance(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        out: Option<(&mut [f64], usize)>,
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            if simd::has_avx512() {
                // SAFETY: the processor has what the path needs (checked just above).
                unsafe { self.advance_avx512(state, drivers, len, out) };
                return;
            }
            if simd::has_avx_fma() {
                // SAFETY: the processor has what the path needs (checked just above).
                unsafe { self.advance_avx(state, drivers, len, out) };
                return;
            }
        }
        self.advance_any(state, drivers, len, out);
    }

    /// [`Self::advance`] with 256-bit vectors (four chains each), up to 16 corners; more
    /// take the portable path, compiled here with fused multiply-add.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,fma")]
    fn advance_avx(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        out: Option<(&mut [f64], usize)>,
    ) {
        use std::arch::x86_64::__m256d;
        macro_rules! dispatch {
            ($($n:literal)*) => {
                match (self.order, self.n_corners.div_ceil(4)) {
                    $(
                        ($n, 1) => self.advance_simd::<__m256d, $n, 1>(state, drivers, len, out),
                        ($n, 2) => self.advance_simd::<__m256d, $n, 2>(state, drivers, len, out),
                        ($n, 3) => self.advance_simd::<__m256d, $n, 3>(state, drivers, len, out),
                        ($n, 4) => self.advance_simd::<__m256d, $n, 4>(state, drivers, len, out),
                    )*
                    _ => self.advance_any(state, drivers, len, out),
                }
            };
        }
        // SAFETY: AVX and FMA are enabled here.
        unsafe { dispatch!(1 2 3 4 5 6 7 8) }
    }

    /// [`Self::advance`] with 512-bit vectors (eight chains each: the default six corners of
    /// a driver take one vector instead of two half-filled ones), up to 16 corners.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn advance_avx512(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        out: Option<(&mut [f64], usize)>,
    ) {
        use std::arch::x86_64::__m512d;
        macro_rules! dispatch {
            ($($n:literal)*) => {
                match (self.order, self.n_corners.div_ceil(8)) {
                    $(
                        ($n, 1) => self.advance_simd::<__m512d, $n, 1>(state, drivers, len, out),
                        ($n, 2) => self.advance_simd::<__m512d, $n, 2>(state, drivers, len, out),
                    )*
                    _ => self.advance_any(state, drivers, len, out),
                }
            };
        }
        // SAFETY: AVX-512F is enabled here.
        unsafe { dispatch!(1 2 3 4 5 6 7 8) }
    }

    /// The vector paths: `V` vectors of `S::W` chains per driver (vector `v` holds the
    /// driver's corners `v·W …`, zero coefficients past the last). Where the registers
    /// allow, drivers go in pairs (an odd last one alone), both advanced at each sample:
    /// two independent recursions to overlap, two driving columns read side by side, and a
    /// sample's outputs of the pair written together (they are adjacent in the row).
    ///
    /// # Safety
    /// The processor has the instructions of `S`; called from a function that enables
    /// them, into which this is inlined.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn advance_simd<S: simd::Vector, const N: usize, const V: usize>(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        mut out: Option<(&mut [f64], usize)>,
    ) {
        self.check_args(drivers, len, &out);
        let (bpd, nc) = (self.bpd, self.n_corners);
        assert_eq!(
            nc.div_ceil(S::W),
            V,
            "invariant: dispatched on the vectors per driver"
        );
        // The lanes of vector `v`: blocks `v·W/LANES …` of `lanes[at + block · stride]`,
        // zeros past the driver's last block.
        let gather = |lanes: &[Lane], v: usize, stride: usize| -> S {
            let mut x = [0.0; simd::MAX_W];
            for h in 0..S::W / LANES {
                let blk = v * S::W / LANES + h;
                if blk < bpd {
                    x[h * LANES..(h + 1) * LANES].copy_from_slice(&lanes[blk * stride]);
                }
            }
            // SAFETY: `x` holds at least `S::W` values; the caller has `S`.
            unsafe { S::load(x.as_ptr()) }
        };
        // Every driver's chains have the same coefficients: the first driver's serve all.
        let per = N * N + 2 * N;
        let c = |j: usize, v: usize| gather(&self.coef[j..], v, per);
        let coef = simd::Coef::<S, N, V> {
            phi: std::array::from_fn(|v| {
                std::array::from_fn(|i| std::array::from_fn(|j| c(i * N + j, v)))
            }),
            g0: std::array::from_fn(|v| std::array::from_fn(|i| c(N * N + i, v))),
            g1: std::array::from_fn(|v| std::array::from_fn(|i| c(N * N + N + i, v))),
            lanes: std::array::from_fn(|v| (nc - v * S::W).min(S::W)),
        };
        // Drivers in pairs where the coefficients, both drivers' states and the driving
        // values fit in the registers (otherwise the states would go through memory).
        let pairs = V * (N * (N + 1) / 2 + 2 * N) + 2 * V * N + 4 <= S::REGISTERS;
        let mut d = 0;
        while d < drivers.len() {
            let group = (drivers.len() - d).min(if pairs { 2 } else { 1 });
            let zst = &mut state.z[d * bpd * N..(d + group) * bpd * N];
            let load = |zst: &[Lane], g: usize| -> [[S; N]; V] {
                std::array::from_fn(|v| {
                    std::array::from_fn(|i| gather(&zst[g * bpd * N + i..], v, N))
                })
            };
            let mut zs = [load(zst, 0), load(zst, group - 1)];
            let out = out.as_mut().map(|(buf, stride)| (&mut **buf, *stride));
            let prev = &mut state.prev[d..d + group];
            // SAFETY: the caller has `S`.
            unsafe {
                if group == 2 {
                    simd::advance_group::<S, N, V, 2>(
                        &coef, &mut zs, prev, drivers, d, len, nc, out,
                    );
                } else {
                    simd::advance_group::<S, N, V, 1>(
                        &coef, &mut zs, prev, drivers, d, len, nc, out,
                    );
                }
            }
            for (g, zg) in zs.iter().enumerate().take(group) {
                for (v, zv) in zg.iter().enumerate() {
                    for (i, z) in zv.iter().enumerate() {
                        let mut x = [0.0; simd::MAX_W];
                        // SAFETY: `x` holds at least `S::W` values; the caller has `S`.
                        unsafe { z.store(x.as_mut_ptr()) };
                        for h in 0..S::W / LANES {
                            let blk = v * S::W / LANES + h;
                            if blk < bpd {
                                zst[(g * bpd + blk) * N + i]
                                    .copy_from_slice(&x[h * LANES..(h + 1) * LANES]);
                            }
                        }
                    }
                }
            }
            d += group;
        }
    }

    fn check_args(&self, drivers: &[&[f64]], len: usize, out: &Option<(&mut [f64], usize)>) {
        assert_eq!(drivers.len(), self.n_drivers);
        assert!(drivers.iter().all(|c| c.len() >= len));
        if let Some((buf, stride)) = out {
            assert!(*stride >= self.n_rows() && buf.len() >= len * stride);
        }
    }

    /// The coefficients of every block with the order fixed at compile time.
    fn blocks<const N: usize>(&self) -> Vec<Block<N>> {
        let per = N * N + 2 * N;
        self.coef
            .chunks_exact(per)
            .map(|c| Block {
                phi: std::array::from_fn(|i| std::array::from_fn(|j| c[i * N + j])),
                g0: std::array::from_fn(|i| c[N * N + i]),
                g1: std::array::from_fn(|i| c[N * N + N + i]),
            })
            .collect()
    }

    #[inline(always)]
    fn advance_any(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        out: Option<(&mut [f64], usize)>,
    ) {
        macro_rules! dispatch {
            ($($n:literal)*) => {
                match self.order {
                    $($n => self.advance_n::<$n>(state, drivers, len, out),)*
                    o => unreachable!("invariant: filter order {o} checked in FilterBank::new"),
                }
            };
        }
        dispatch!(1 2 3 4 5 6 7 8)
    }

    #[inline(always)]
    fn advance_n<const N: usize>(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        mut out: Option<(&mut [f64], usize)>,
    ) {
        self.check_args(drivers, len, &out);
        let blocks = self.blocks::<N>();
        let mut z: Vec<[Lane; N]> = state
            .z
            .chunks_exact(N)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect();
        let (bpd, nc) = (self.bpd, self.n_corners);
        let width = N * nc;
        // Chains of different drivers are independent: time runs innermost, per driver, so
        // the block states stay in registers and the driving column is read in order.
        for (d, ((bs, zs), &col)) in blocks
            .chunks_exact(bpd)
            .zip(z.chunks_exact_mut(bpd))
            .zip(drivers)
            .enumerate()
        {
            let col = &col[..len];
            let mut prev = state.prev[d];
            match out.as_mut() {
                None => {
                    for &s in col {
                        let (p, sv) = ([prev; LANES], [s; LANES]);
                        for (b, zb) in bs.iter().zip(zs.iter_mut()) {
                            step(b, zb, &p, &sv);
                        }
                        prev = s;
                    }
                }
                Some((buf, stride)) => {
                    for (&s, row) in col.iter().zip(buf.chunks_exact_mut(*stride)) {
                        let (p, sv) = ([prev; LANES], [s; LANES]);
                        for (b, zb) in bs.iter().zip(zs.iter_mut()) {
                            step(b, zb, &p, &sv);
                        }
                        let dst = &mut row[d * width..(d + 1) * width];
                        for (b, zb) in zs.iter().enumerate() {
                            let (c0, r) = (b * LANES, (nc - b * LANES).min(LANES));
                            for (i, zi) in zb.iter().enumerate() {
                                dst[i * nc + c0..i * nc + c0 + r].copy_from_slice(&zi[..r]);
                            }
                        }
                        prev = s;
                    }
                }
            }
            state.prev[d] = prev;
        }
        for (dst, src) in state.z.chunks_exact_mut(N).zip(&z) {
            dst.copy_from_slice(src);
        }
    }

    /// Number of corners (chains per driver).
    pub fn n_corners(&self) -> usize {
        self.n_corners
    }

    /// The filter order.
    pub fn order(&self) -> usize {
        self.order
    }
}

/// What the vector paths of [`FilterBank::advance`] need of an instruction set, and the
/// kernel they share.
#[cfg(target_arch = "x86_64")]
mod simd {
    use std::arch::x86_64::{
        __m256d, __m512d, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_maskstore_pd, _mm256_mul_pd,
        _mm256_set1_pd, _mm256_setr_epi64x, _mm256_storeu_pd, _mm512_fmadd_pd, _mm512_loadu_pd,
        _mm512_mask_storeu_pd, _mm512_mul_pd, _mm512_set1_pd, _mm512_storeu_pd,
    };

    /// The most lanes of any vector.
    pub const MAX_W: usize = 8;

    /// Whether the processor can run [`super::FilterBank::advance_avx512`].
    pub fn has_avx512() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
    }

    /// Whether the processor can run [`super::FilterBank::advance_avx`].
    pub fn has_avx_fma() -> bool {
        std::arch::is_x86_feature_detected!("avx") && std::arch::is_x86_feature_detected!("fma")
    }

    /// A vector of `W` chains. Every method needs the processor to have the instructions:
    /// they are called only from functions that enable them.
    pub trait Vector: Copy {
        /// Lanes.
        const W: usize;
        /// Vector registers of the instruction set.
        const REGISTERS: usize;
        unsafe fn splat(x: f64) -> Self;
        /// `W` values from `at`.
        unsafe fn load(at: *const f64) -> Self;
        /// `W` values to `at`.
        unsafe fn store(self, at: *mut f64);
        /// The first `lanes` values to `at`.
        unsafe fn store_first(self, at: *mut f64, lanes: usize);
        unsafe fn mul(self, b: Self) -> Self;
        /// `self · b + c`, rounded once.
        unsafe fn mul_add(self, b: Self, c: Self) -> Self;
    }

    impl Vector for __m256d {
        const W: usize = 4;
        const REGISTERS: usize = 16;
        #[inline(always)]
        unsafe fn splat(x: f64) -> Self {
            unsafe { _mm256_set1_pd(x) }
        }
        #[inline(always)]
        unsafe fn load(at: *const f64) -> Self {
            unsafe { _mm256_loadu_pd(at) }
        }
        #[inline(always)]
        unsafe fn store(self, at: *mut f64) {
            unsafe { _mm256_storeu_pd(at, self) }
        }
        #[inline(always)]
        unsafe fn store_first(self, at: *mut f64, lanes: usize) {
            // A lane is stored where its mask has the sign bit set.
            let on = |l: usize| if l < lanes { -1 } else { 0 };
            unsafe { _mm256_maskstore_pd(at, _mm256_setr_epi64x(on(0), on(1), on(2), on(3)), self) }
        }
        #[inline(always)]
        unsafe fn mul(self, b: Self) -> Self {
            unsafe { _mm256_mul_pd(self, b) }
        }
        #[inline(always)]
        unsafe fn mul_add(self, b: Self, c: Self) -> Self {
            unsafe { _mm256_fmadd_pd(self, b, c) }
        }
    }

    impl Vector for __m512d {
        const W: usize = 8;
        const REGISTERS: usize = 32;
        #[inline(always)]
        unsafe fn splat(x: f64) -> Self {
            unsafe { _mm512_set1_pd(x) }
        }
        #[inline(always)]
        unsafe fn load(at: *const f64) -> Self {
            unsafe { _mm512_loadu_pd(at) }
        }
        #[inline(always)]
        unsafe fn store(self, at: *mut f64) {
            unsafe { _mm512_storeu_pd(at, self) }
        }
        #[inline(always)]
        unsafe fn store_first(self, at: *mut f64, lanes: usize) {
            let mask = ((1u16 << lanes.min(8)) - 1) as u8;
            unsafe { _mm512_mask_storeu_pd(at, mask, self) }
        }
        #[inline(always)]
        unsafe fn mul(self, b: Self) -> Self {
            unsafe { _mm512_mul_pd(self, b) }
        }
        #[inline(always)]
        unsafe fn mul_add(self, b: Self, c: Self) -> Self {
            unsafe { _mm512_fmadd_pd(self, b, c) }
        }
    }

    /// The bank's coefficients as vectors, and the lanes of each vector that are chains.
    pub struct Coef<S, const N: usize, const V: usize> {
        pub phi: [[[S; N]; N]; V],
        pub g0: [[S; N]; V],
        pub g1: [[S; N]; V],
        pub lanes: [usize; V],
    }

    /// `D` drivers from `first` on, advanced together over `len` samples; `zs[g]` and
    /// `prev[g]` are driver `first + g`'s. The operations of [`super::step`] in its order.
    ///
    /// # Safety
    /// The processor has the instructions of `S`; called from a function that enables
    /// them, into which this is inlined.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn advance_group<S: Vector, const N: usize, const V: usize, const D: usize>(
        coef: &Coef<S, N, V>,
        zs: &mut [[[S; N]; V]; 2],
        prev: &mut [f64],
        drivers: &[&[f64]],
        first: usize,
        len: usize,
        nc: usize,
        out: Option<(&mut [f64], usize)>,
    ) {
        let cols: [&[f64]; D] = std::array::from_fn(|g| &drivers[first + g][..len]);
        let mut p: [f64; D] = std::array::from_fn(|g| prev[g]);
        let width = N * nc;
        // No closures here: a closure would not inherit the instruction set of the function
        // this is inlined into, and its vector operations would become calls.
        let mut out = out;
        for k in 0..len {
            if k % 8 == 0 {
                // The columns come from memory (the first pass read them long before), and
                // the recursion reads them slower than the processor's own prefetching
                // expects.
                for c in &cols {
                    crate::prefetch::ahead(c, k);
                }
            }
            for g in 0..D {
                // SAFETY: the caller has `S`.
                unsafe {
                    let (pv, sv) = (S::splat(p[g]), S::splat(cols[g][k]));
                    for (v, zv) in zs[g].iter_mut().enumerate() {
                        for i in (0..N).rev() {
                            let mut acc = coef.g1[v][i].mul_add(sv, coef.g0[v][i].mul(pv));
                            for (phi, z) in coef.phi[v][i].iter().zip(zv.iter()).take(i + 1) {
                                acc = phi.mul_add(*z, acc);
                            }
                            zv[i] = acc;
                        }
                    }
                }
                p[g] = cols[g][k];
            }
            if let Some((buf, stride)) = out.as_mut() {
                let row = &mut buf[k * *stride + first * width..k * *stride + (first + D) * width];
                let base = row.as_mut_ptr();
                for (g, zg) in zs.iter().enumerate().take(D) {
                    for (v, zv) in zg.iter().enumerate() {
                        for (i, z) in zv.iter().enumerate() {
                            // SAFETY: lanes `g·width + i·nc + v·W ..+ r` of `row` (r the
                            // chains of vector `v`) lie inside its `D · width` values; the
                            // caller has `S`.
                            unsafe {
                                let at = base.add(g * width + i * nc + v * S::W);
                                if coef.lanes[v] == S::W {
                                    z.store(at);
                                } else {
                                    z.store_first(at, coef.lanes[v]);
                                }
                            }
                        }
                    }
                }
            }
        }
        prev[..D].copy_from_slice(&p);
    }
}

/// Log-spaced corner frequencies covering the band where the response has power.
///
/// `omegas` are dominant angular frequencies estimated from the data (zero-crossing rates of
/// the positions); the band runs from half the lowest to eight times the highest, and
/// is capped well below the Nyquist frequency so that the piecewise-linear input model stays
/// accurate.
pub fn design_corners(omegas: &[f64], ts: f64, count: usize) -> Vec<f64> {
    let finite: Vec<f64> = omegas
        .iter()
        .copied()
        .filter(|w| w.is_finite() && *w > 0.0)
        .collect();
    let nyq = std::f64::consts::PI / ts;
    let (lo, hi) = if finite.is_empty() {
        (nyq / 1000.0, nyq / 20.0)
    } else {
        let mn = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let mx = finite.iter().copied().fold(0.0, f64::max);
        (mn / 2.0, mx * 8.0)
    };
    let hi = hi.min(nyq / 10.0);
    let lo = lo.min(hi / 8.0);
    if count == 1 {
        return vec![(lo * hi).sqrt()];
    }
    (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count - 1) as f64))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// First-order section with a ramp input s = t: ζ(t) = t − (1 − e^{−λt})/λ exactly.
    #[test]
    fn foh_is_exact_for_a_ramp_and_zoh_is_not() {
        let (lambda, ts, n) = (3.0, 0.01, 500);
        let s: Vec<f64> = (0..n).map(|k| k as f64 * ts).collect();
        let exact = |t: f64| t - (1.0 - (-lambda * t).exp()) / lambda;
        for (hold, tol) in [(Hold::FirstOrder, 1e-13), (Hold::ZeroOrder, f64::INFINITY)] {
            let d = ChainDisc::new(lambda, 1, ts, hold);
            let mut st = [0.0];
            let mut out = vec![0.0; n - 1];
            d.run(&mut st, s[0], &s[1..], &mut out, n - 1);
            let err = (1..n)
                .map(|k| (out[k - 1] - exact(k as f64 * ts)).abs())
                .fold(0.0, f64::max);
            if hold == Hold::FirstOrder {
                assert!(err < tol, "FOH error {err}");
            } else {
                // ZOH lags by half a sample: error → Tₛ/2 once the transient has decayed.
                assert!((err - ts / 2.0).abs() < 0.1 * ts, "ZOH error {err}");
            }
        }
    }

    /// A smooth multi-tone driving signal.
    fn signal(n: usize, phase: f64) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let t = k as f64 * 0.01;
                (1.3 * t + phase).sin() + 0.4 * (7.1 * t).cos() + 0.05 * (31.0 * t + phase).sin()
            })
            .collect()
    }

    /// The largest difference relative to the largest value.
    fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let err = a
            .iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        err / scale
    }

    type Path = fn(&FilterBank, &mut BankState, &[&[f64]], usize, Option<(&mut [f64], usize)>);

    /// The vector paths of [`FilterBank::advance`] this processor can run. Each path is
    /// reported as `vector path NAME: tested` or `vector path NAME: SKIPPED (why)` (shown
    /// with `--nocapture`, and in the output of a failing test), so that a run on a
    /// processor without AVX-512 says so. `DYNID_REQUIRE_VECTOR_PATHS=avx,avx512` turns a
    /// skip of a named path into a failure (for a machine known to have it).
    fn vector_paths() -> Vec<(&'static str, Path)> {
        #[allow(unused_mut)]
        let mut paths: Vec<(&'static str, Path)> = Vec::new();
        #[allow(unused_mut)]
        let mut skipped: Vec<(&'static str, &'static str)> = Vec::new();
        #[cfg(target_arch = "x86_64")]
        {
            if simd::has_avx_fma() {
                // SAFETY: the processor has what the path needs (checked just above).
                paths.push(("avx", |b, s, d, l, o| unsafe { b.advance_avx(s, d, l, o) }));
            } else {
                skipped.push(("avx", "the processor lacks avx and fma"));
            }
            if simd::has_avx512() {
                // SAFETY: the processor has what the path needs (checked just above).
                paths.push(("avx512", |b, s, d, l, o| unsafe {
                    b.advance_avx512(s, d, l, o)
                }));
            } else {
                skipped.push(("avx512", "the processor lacks avx512f"));
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        skipped.extend([("avx", "not x86_64"), ("avx512", "not x86_64")]);
        for (name, _) in &paths {
            eprintln!("vector path {name}: tested");
        }
        for (name, why) in &skipped {
            eprintln!("vector path {name}: SKIPPED ({why})");
        }
        let required = std::env::var("DYNID_REQUIRE_VECTOR_PATHS").unwrap_or_default();
        for name in required.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            assert!(
                paths.iter().any(|(p, _)| *p == name),
                "DYNID_REQUIRE_VECTOR_PATHS names `{name}`, which this processor cannot run \
                 (tested: {:?}, skipped: {skipped:?})",
                paths.iter().map(|(p, _)| *p).collect::<Vec<_>>()
            );
        }
        paths
    }

    /// Which vector paths this processor runs and which the tests skip: `.ci/run` shows
    /// this test's output, so a CI machine without AVX-512 states it.
    #[test]
    fn vector_paths_tested_and_skipped() {
        let paths = vector_paths();
        #[cfg(target_arch = "x86_64")]
        assert_eq!(
            paths.iter().any(|(n, _)| *n == "avx512"),
            simd::has_avx512(),
            "the AVX-512 path is tested exactly where the processor has it"
        );
        #[cfg(not(target_arch = "x86_64"))]
        assert!(paths.is_empty());
    }

    /// The bank (structure of arrays, fed in uneven pieces) against the per-chain recursion
    /// of `ChainDisc::run`, for every order with an odd number of corners (a padded block),
    /// to 1e-12 of the largest value of each state.
    #[test]
    fn bank_equals_the_per_chain_recursion() {
        let (ts, n) = (0.01, 3001);
        let drivers = [signal(n, 0.0), signal(n, 1.0), signal(n, 2.5)];
        // Every count of chains per driver up to 13: whole and partial last blocks, one to
        // three blocks per driver (the vector path's sizes) and four (the portable path).
        let many: Vec<f64> = (0..13).map(|c| 0.3 * 1.35f64.powi(c)).collect();
        let cases = (1..=13).map(|nc| (MAX_ORDER, many[..nc].to_vec()));
        let cases = cases.chain((1..=MAX_ORDER).map(|o| (o, vec![0.3, 1.1, 2.5, 6.0, 19.0])));
        let paths = vector_paths();
        for (order, corners) in cases {
            let bank = FilterBank::new(&corners, drivers.len(), order, ts, Hold::FirstOrder);
            let stride = bank.n_rows() + 3;
            let prev: Vec<f64> = drivers.iter().map(|s| s[0]).collect();
            // Every path this processor has, fed in uneven pieces.
            let run = |path: Path| {
                let mut st = bank.state(&prev);
                let mut out = vec![f64::NAN; (n - 1) * stride];
                let mut k0 = 1;
                for piece in [1, 17, 1000, 1981, 1] {
                    let ds: Vec<&[f64]> = drivers.iter().map(|s| &s[k0..k0 + piece]).collect();
                    let o = Some((&mut out[(k0 - 1) * stride..], stride));
                    path(&bank, &mut st, &ds, piece, o);
                    k0 += piece;
                }
                assert_eq!(k0, n);
                (st, out)
            };
            let (st, out) = run(FilterBank::advance);
            // The portable path, in one piece, and every vector path give the same values
            // bit for bit.
            let mut st_any = bank.state(&prev);
            let mut out_any = vec![f64::NAN; (n - 1) * stride];
            let ds: Vec<&[f64]> = drivers.iter().map(|s| &s[1..]).collect();
            bank.advance_any(&mut st_any, &ds, n - 1, Some((&mut out_any, stride)));
            for &(name, path) in &paths {
                let (st_v, out_v) = run(path);
                assert_eq!(st_v, st_any, "{name}, order {order}");
                assert!(
                    out_v
                        .iter()
                        .zip(&out_any)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{name}, order {order}, {} corners",
                    corners.len()
                );
            }
            assert_eq!(st_any, st, "order {order}");
            for (k, (a, b)) in out.iter().zip(&out_any).enumerate() {
                if k % stride < bank.n_rows() {
                    assert_eq!(a.to_bits(), b.to_bits(), "order {order}, {k}");
                } else {
                    assert!(a.is_nan(), "written past the rows: {k}");
                }
            }
            let mut worst = 0.0f64;
            for (d, s) in drivers.iter().enumerate() {
                for (c, &lambda) in corners.iter().enumerate() {
                    let chain = ChainDisc::new(lambda, order, ts, Hold::FirstOrder);
                    let mut z = vec![0.0; order];
                    let mut want = vec![0.0; order * (n - 1)];
                    chain.run(&mut z, s[0], &s[1..], &mut want, n - 1);
                    for i in 0..order {
                        let got: Vec<f64> = (0..n - 1)
                            .map(|k| out[k * stride + bank.row(d, c, i)])
                            .collect();
                        worst = worst.max(rel_diff(&got, &want[i * (n - 1)..(i + 1) * (n - 1)]));
                    }
                    worst = worst.max(rel_diff(&st.chain(&bank, d, c), &z));
                }
            }
            assert!(
                worst <= 1e-12,
                "order {order}: relative difference {worst:e}"
            );
            assert_eq!(
                st.prev(),
                &[drivers[0][n - 1], drivers[1][n - 1], drivers[2][n - 1]]
            );
        }
    }

    /// Linearity, as the time-parallel pass uses it: the run from a state equals the run
    /// from rest plus the free response `Φ^m ζ` of that state.
    #[test]
    fn a_run_is_the_run_from_rest_plus_the_free_response() {
        let (ts, n) = (0.01, 1500);
        let corners = [0.5, 2.0, 9.0];
        let s = signal(n + 1, 0.3);
        for order in [1, 2, 3, 5] {
            let mut bank = FilterBank::new(&corners, 1, order, ts, Hold::FirstOrder);
            bank.prepare_propagation(n);
            // A state reached by running for a while.
            let mut start = bank.state(&[s[0]]);
            let warm = signal(400, 2.0);
            bank.advance(&mut start, &[&warm], warm.len(), None);
            let start = BankState {
                prev: vec![s[0]],
                ..start
            };
            for m in [1, 2, 7, 64, 1000, n] {
                let mut direct = start.clone();
                bank.advance(&mut direct, &[&s[1..]], m, None);
                let mut rest = bank.state(&[s[0]]);
                bank.advance(&mut rest, &[&s[1..]], m, None);
                let mut composed = start.clone();
                bank.propagate(&mut composed, m);
                bank.add(&mut composed, &rest);
                for c in 0..corners.len() {
                    let (a, b) = (composed.chain(&bank, 0, c), direct.chain(&bank, 0, c));
                    let err = rel_diff(&a, &b);
                    assert!(err <= 1e-12, "order {order}, m = {m}, corner {c}: {err:e}");
                }
            }
        }
    }

    #[test]
    fn chains_match_the_generic_loop() {
        let d = ChainDisc::new(2.5, 3, 0.01, Hold::FirstOrder);
        let s: Vec<f64> = (0..200).map(|k| (k as f64 * 0.05).sin()).collect();
        let mut a = [0.1, 0.2, 0.3];
        let mut b = a;
        let mut oa = vec![0.0; 3 * 199];
        let mut ob = oa.clone();
        d.run3(&mut a, s[0], &s[1..], &mut oa, 199);
        // Generic path through a 3-chain built as order 3 but forced through the loop.
        let mut prev = s[0];
        for (k, &sk) in s[1..].iter().enumerate() {
            let next: [f64; 3] = std::array::from_fn(|i| {
                let lin: f64 = (0..=i).map(|j| d.phi[i * 3 + j] * b[j]).sum();
                lin + d.g0[i] * prev + d.g1[i] * sk
            });
            b = next;
            for i in 0..3 {
                ob[i * 199 + k] = b[i];
            }
            prev = sk;
        }
        for (a, b) in oa.iter().zip(&ob) {
            assert!((a - b).abs() < 1e-14, "{a} vs {b}");
        }
    }
}
