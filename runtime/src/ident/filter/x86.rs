//! The x86-64 vector paths of [`FilterBank::advance`]: AVX + FMA (four chains a vector) and
//! AVX-512 (eight), with the operations of the portable kernel (`super::kernel::step`) in
//! its order, so that every path gives the same outputs bit for bit.

use super::layout::{BankState, FilterBank, Lane, LANES};
use std::arch::x86_64::{
    __m256d, __m512d, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_maskstore_pd, _mm256_mul_pd,
    _mm256_set1_pd, _mm256_setr_epi64x, _mm256_storeu_pd, _mm512_fmadd_pd, _mm512_loadu_pd,
    _mm512_mask_storeu_pd, _mm512_mul_pd, _mm512_set1_pd, _mm512_storeu_pd,
};

/// The most lanes of any vector.
pub const MAX_W: usize = 8;

/// Whether the processor can run [`FilterBank::advance_avx512`].
pub fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
}

/// Whether the processor can run [`FilterBank::advance_avx`].
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
/// `prev[g]` are driver `first + g`'s. The operations of [`super::kernel::step`] in its order.
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

impl FilterBank {
    /// [`Self::advance`] with 256-bit vectors (four chains each), up to 16 corners; more
    /// take the portable path, compiled here with fused multiply-add.
    #[target_feature(enable = "avx,fma")]
    pub(super) fn advance_avx(
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
    #[target_feature(enable = "avx512f")]
    pub(super) fn advance_avx512(
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
    #[inline(always)]
    unsafe fn advance_simd<S: Vector, const N: usize, const V: usize>(
        &self,
        state: &mut BankState,
        drivers: &[&[f64]],
        len: usize,
        mut out: Option<(&mut [f64], usize)>,
    ) {
        self.check_args(drivers, len, &out);
        let (blocks_per_driver, nc) = (self.blocks_per_driver, self.n_corners);
        assert_eq!(
            nc.div_ceil(S::W),
            V,
            "invariant: dispatched on the vectors per driver"
        );
        // The lanes of vector `v`: blocks `v·W/LANES …` of `lanes[at + block · stride]`,
        // zeros past the driver's last block.
        let gather = |lanes: &[Lane], v: usize, stride: usize| -> S {
            let mut x = [0.0; MAX_W];
            for h in 0..S::W / LANES {
                let blk = v * S::W / LANES + h;
                if blk < blocks_per_driver {
                    x[h * LANES..(h + 1) * LANES].copy_from_slice(&lanes[blk * stride]);
                }
            }
            // SAFETY: `x` holds at least `S::W` values; the caller has `S`.
            unsafe { S::load(x.as_ptr()) }
        };
        // Every driver's chains have the same coefficients: the first driver's serve all.
        let per = N * N + 2 * N;
        let c = |j: usize, v: usize| gather(&self.coef[j..], v, per);
        let coef = Coef::<S, N, V> {
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
            let zst = &mut state.z[d * blocks_per_driver * N..(d + group) * blocks_per_driver * N];
            let load = |zst: &[Lane], g: usize| -> [[S; N]; V] {
                std::array::from_fn(|v| {
                    std::array::from_fn(|i| gather(&zst[g * blocks_per_driver * N + i..], v, N))
                })
            };
            let mut zs = [load(zst, 0), load(zst, group - 1)];
            let out = out.as_mut().map(|(buf, stride)| (&mut **buf, *stride));
            let prev = &mut state.prev[d..d + group];
            // SAFETY: the caller has `S`.
            unsafe {
                if group == 2 {
                    advance_group::<S, N, V, 2>(&coef, &mut zs, prev, drivers, d, len, nc, out);
                } else {
                    advance_group::<S, N, V, 1>(&coef, &mut zs, prev, drivers, d, len, nc, out);
                }
            }
            for (g, zg) in zs.iter().enumerate().take(group) {
                for (v, zv) in zg.iter().enumerate() {
                    for (i, z) in zv.iter().enumerate() {
                        let mut x = [0.0; MAX_W];
                        // SAFETY: `x` holds at least `S::W` values; the caller has `S`.
                        unsafe { z.store(x.as_mut_ptr()) };
                        for h in 0..S::W / LANES {
                            let blk = v * S::W / LANES + h;
                            if blk < blocks_per_driver {
                                zst[(g * blocks_per_driver + blk) * N + i]
                                    .copy_from_slice(&x[h * LANES..(h + 1) * LANES]);
                            }
                        }
                    }
                }
            }
            d += group;
        }
    }
}
