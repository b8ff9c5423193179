//! The portable kernel of the bank: one step of a block of [`LANES`] chains as a product and
//! fused multiply-adds in a fixed order, and the bank advanced with it. The vector paths
//! (`super::x86`) do the same operations in the same order.

use super::layout::{BankState, FilterBank, Lane, LANES};

/// One block's coefficients with the order fixed at compile time.
pub(super) struct Block<const N: usize> {
    pub(super) phi: [[Lane; N]; N],
    pub(super) g0: [Lane; N],
    pub(super) g1: [Lane; N],
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
pub(super) fn step<const N: usize>(b: &Block<N>, z: &mut [Lane; N], prev: &Lane, s: &Lane) {
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
    pub(super) fn advance_any(
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
        let (blocks_per_driver, nc) = (self.blocks_per_driver, self.n_corners);
        let width = N * nc;
        // Chains of different drivers are independent: time runs innermost, per driver, so
        // the block states stay in registers and the driving column is read in order.
        for (d, ((bs, zs), &col)) in blocks
            .chunks_exact(blocks_per_driver)
            .zip(z.chunks_exact_mut(blocks_per_driver))
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
}
