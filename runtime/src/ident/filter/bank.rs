//! The whole bank in structure-of-arrays form: construction from the reference chains, the
//! free response by binary powers of `Φ`, and [`FilterBank::advance`], which runs the
//! fastest kernel the processor has.

use super::chain::{ChainDisc, Hold};
use super::layout::{BankState, FilterBank, LANES, MAX_ORDER};
#[cfg(target_arch = "x86_64")]
use super::x86;

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
        let blocks_per_driver = n_corners.div_ceil(LANES);
        let n = order;
        let per = n * n + 2 * n;
        let mut coef = vec![[0.0; LANES]; n_drivers * blocks_per_driver * per];
        let mut phi1 = vec![[0.0; LANES]; n_drivers * blocks_per_driver * n * n];
        for (c, &lambda) in corners.iter().enumerate() {
            let disc = ChainDisc::new(lambda, order, ts, hold);
            for d in 0..n_drivers {
                let blk = d * blocks_per_driver + c / LANES;
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
            blocks_per_driver,
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
            z: vec![[0.0; LANES]; self.n_drivers * self.blocks_per_driver * self.order],
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
            if x86::has_avx512() {
                // SAFETY: the processor has what the path needs (checked just above).
                unsafe { self.advance_avx512(state, drivers, len, out) };
                return;
            }
            if x86::has_avx_fma() {
                // SAFETY: the processor has what the path needs (checked just above).
                unsafe { self.advance_avx(state, drivers, len, out) };
                return;
            }
        }
        self.advance_any(state, drivers, len, out);
    }
    pub(super) fn check_args(
        &self,
        drivers: &[&[f64]],
        len: usize,
        out: &Option<(&mut [f64], usize)>,
    ) {
        assert_eq!(drivers.len(), self.n_drivers);
        assert!(drivers.iter().all(|c| c.len() >= len));
        if let Some((buf, stride)) = out {
            assert!(*stride >= self.n_rows() && buf.len() >= len * stride);
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
