//! Streaming accumulation of the raw cross moments of one excitation level.
//!
//! Per sample the only work is: evaluate the static basis `g`, advance the filter bank `ζ`,
//! and add `ι wᵀ` (with `ι = [ζ; y]`, `w = [g; y]`) to the sum of the current time block —
//! done per task of about a thousand samples as one matrix product, right after the task's
//! filter states and basis values are formed, while they are in cache. Tasks run in
//! parallel over time: the filter state at a task's start is recovered exactly from the
//! linearity of the filter (see [`LevelAccumulator`]). Every moment the equations need, including those
//! with `ζ'` and `ζ''`, is a fixed linear combination of these (see [`super::plan`]).
//!
//! Time averages use the trapezoid rule over samples, `∫ f ≈ Tₛ (Σ f − ½ f₀ − ½ f_N)`, which
//! splits exactly into time blocks: block `b` (samples `n_b … n_{b+1}`) contributes
//! `Tₛ (Σ_{[n_b, n_{b+1})} f + ½ f(n_{b+1}) − ½ f(n_b))`. At the block boundaries the full
//! products `ι qᵀ` are kept as snapshots; they supply both the trapezoid end corrections and
//! the boundary terms `[ι q]` of the finite-record identities.
//!
//! # Per-block contributions for the standard errors
//!
//! The standard errors need the record's moments written as a sum of local contributions
//! that are each an exact estimating equation. Cutting the record into blocks with sharp
//! edges does that only with boundary terms at every edge, and those are point values
//! (`ι ẋ`, with `ẋ` a noisy measured or estimated velocity): they telescope away in the
//! sum, yet dominate the block-to-block spread (at 1 kHz one sample of velocity noise
//! outweighs the noise averaged over a whole block). So the contributions use a partition
//! of unity of *hat* functions instead: `φ_j` rises linearly over block `j − 1` and falls
//! over block `j` (half hats at the record ends), `Σ_j φ_j = 1`. Integrating by parts with
//! `φ_j ι` as the instrument,
//!
//! ```text
//! ∫ φ ι ẋ = [φ ι x] − ∫ φ' ι x − ∫ φ ι' x,
//! ∫ φ ι ẍ = [φ ι ẋ] − [φ ι' x] + ∫ φ ι'' x + 2 ∫ φ' ι' x − Σ_b φ'_b [ι x]_b,
//! ```
//!
//! with `φ'` constant on each block: the only point values of a velocity left are at the
//! record ends, exactly as in the whole-record moments, and the hat contributions sum
//! exactly (in the discrete trapezoid rule too) to those. Besides the block sums this needs
//! `Σ s ι wᵀ` per block, `s` the position in the block in samples.
//!
//! # Blocks left out (rests)
//!
//! A block may be dropped ([`LevelMoments::kept`], see [`super::rests`]): the moments are
//! then those of the runs of kept blocks, each run integrated like a record of its own.
//! The whole-record view sums the kept blocks and takes `[ι q]` at the two ends of every
//! run; a hat has only its kept halves and a jump (a point value) where a run begins or
//! ends; everything is divided by the kept length. Without dropped blocks every formula
//! is the one above, operation for operation.

use super::filter::{BankState, FilterBank, Hold};
use super::plan::Plan;
use crate::basis::BasisEval;
use faer::{Accum, MatMut, MatRef, Par};
use std::time::{Duration, Instant};

/// Where the time of a moment pass goes (summed over threads).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PhaseTimes {
    /// Reading and validating the data (parsing, for CSV).
    pub read: Duration,
    pub filter: Duration,
    pub evaluate: Duration,
    pub accumulate: Duration,
    pub solve: Duration,
    /// Wall time (not summed over threads) of the streamed filter-and-moment pass over all
    /// levels: filtering, evaluation and accumulation together, with the reading they
    /// wait on.
    pub pass: Duration,
}

impl std::ops::AddAssign for PhaseTimes {
    fn add_assign(&mut self, o: Self) {
        self.read += o.read;
        self.filter += o.filter;
        self.evaluate += o.evaluate;
        self.accumulate += o.accumulate;
        self.solve += o.solve;
        self.pass += o.pass;
    }
}

/// Raw moments of one level, per time block.
#[derive(Clone, Debug)]
pub(crate) struct LevelMoments {
    pub n_i: usize,
    pub n_w: usize,
    pub n_q: usize,
    pub ts: f64,
    /// `Σ ι wᵀ` over the half-open sample range of each block (row-major `n_i × n_w`).
    pub sums: Vec<Vec<f64>>,
    /// `Σ (n − n_b) ι wᵀ` over the same ranges (`n_b` the first sample of the block).
    pub tsums: Vec<Vec<f64>>,
    /// Sample intervals per block.
    pub lens: Vec<usize>,
    /// `ι qᵀ` at each block boundary (row-major `n_i × n_q`), `blocks + 1` of them.
    pub snaps: Vec<Vec<f64>>,
    /// Per block: whether its moments count (`false` for a rest, see [`super::rests`]).
    pub kept: Vec<bool>,
}

/// Time-averaged moments `⟨φ ι w⟩` and boundary terms `[φ ι q]/T` for a weight `φ`
/// (`φ ≡ 1`: the whole record), with the `φ'` terms of the hat contributions
/// (`∫ φ' ι w / T` and `Σ_b φ'_b [ι q]_b / T`, zero for `φ ≡ 1`). All are divided by the
/// whole record's length `T`, so the views of all hats add up to the whole-record view.
#[derive(Clone, Debug)]
pub(crate) struct MomentView {
    pub n_w: usize,
    pub n_q: usize,
    pub m: Vec<f64>,
    pub bnd: Vec<f64>,
    /// `∫ φ' ι w / T`; empty for `φ ≡ 1`.
    pub m_d: Vec<f64>,
    /// `Σ_b φ'_b [ι q]_b / T`; empty for `φ ≡ 1`.
    pub bnd_d: Vec<f64>,
}

/// The moments an estimating equation reads from a weight `φ`'s view of a level: `⟨φ ι w⟩`,
/// the boundary terms `[φ ι q]/T` and the `φ'` terms, each for an instrument given as a
/// combination `a` of filter states `(i, coefficient)` and a column of `w` (or `q`).
pub(crate) trait Window {
    fn mean(&self, a: &[(usize, f64)], col: usize) -> f64;
    fn bnd(&self, a: &[(usize, f64)], col: usize) -> f64;
    fn mean_d(&self, a: &[(usize, f64)], col: usize) -> f64;
    fn bnd_d(&self, a: &[(usize, f64)], col: usize) -> f64;
}

impl Window for MomentView {
    #[inline]
    fn mean(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter().map(|&(i, c)| c * self.m[i * self.n_w + col]).sum()
    }
    #[inline]
    fn bnd(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter()
            .map(|&(i, c)| c * self.bnd[i * self.n_q + col])
            .sum()
    }
    #[inline]
    fn mean_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        if self.m_d.is_empty() {
            return 0.0;
        }
        a.iter()
            .map(|&(i, c)| c * self.m_d[i * self.n_w + col])
            .sum()
    }
    #[inline]
    fn bnd_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        if self.bnd_d.is_empty() {
            return 0.0;
        }
        a.iter()
            .map(|&(i, c)| c * self.bnd_d[i * self.n_q + col])
            .sum()
    }
}

/// The contribution of hat `j` to a level, read entry by entry from the block sums: the
/// same numbers, operation for operation, as [`LevelMoments::hat`] forms as whole matrices
/// (the tests compare them bit for bit), without forming the `n_i × n_w` matrices a
/// row needs only a few entries of.
pub(crate) struct Hat<'a> {
    lm: &'a LevelMoments,
    j: usize,
    intervals: f64,
    t: f64,
}

impl<'a> Hat<'a> {
    pub fn new(lm: &'a LevelMoments, j: usize) -> Self {
        let intervals = lm.intervals() as f64;
        Hat {
            lm,
            j,
            intervals,
            t: lm.ts * intervals,
        }
    }

    /// `(m, m_d)` at `(i, k)`, normalised.
    #[inline]
    fn m_entry(&self, i: usize, k: usize) -> (f64, f64) {
        let lm = self.lm;
        let (n_w, n_q) = (lm.n_w, lm.n_q);
        let (mut m, mut m_d) = (0.0, 0.0);
        let mut add = |b: usize, rising: bool| {
            let len = lm.lens[b] as f64;
            let (e0, e1) = (lm.snaps[b][i * n_q + k], lm.snaps[b + 1][i * n_q + k]);
            let sign = if rising { 1.0 } else { -1.0 };
            let full = lm.sums[b][i * n_w + k] + 0.5 * (e1 - e0);
            let rise = lm.tsums[b][i * n_w + k] / len + 0.5 * e1;
            m += if rising { rise } else { full - rise };
            m_d += sign * full / len;
        };
        if lm.kept_before(self.j) {
            add(self.j - 1, true);
        }
        if lm.kept_after(self.j) {
            add(self.j, false);
        }
        (m / self.intervals, m_d / self.t)
    }

    /// `(bnd, bnd_d)` at `(i, k)`, normalised.
    #[inline]
    fn q_entry(&self, i: usize, k: usize) -> (f64, f64) {
        let lm = self.lm;
        let n_q = lm.n_q;
        let mut bnd_d = 0.0;
        let mut add = |b: usize, rising: bool| {
            let len = lm.lens[b] as f64;
            let sign = if rising { 1.0 } else { -1.0 };
            bnd_d += sign * (lm.snaps[b + 1][i * n_q + k] - lm.snaps[b][i * n_q + k]) / len;
        };
        let (before, after) = (lm.kept_before(self.j), lm.kept_after(self.j));
        if before {
            add(self.j - 1, true);
        }
        if after {
            add(self.j, false);
        }
        let mut bnd = 0.0;
        if after && !before {
            bnd -= lm.snaps[self.j][i * n_q + k];
        }
        if before && !after {
            bnd += lm.snaps[self.j][i * n_q + k];
        }
        (bnd / self.t, bnd_d / (self.t * lm.ts))
    }
}

impl Window for Hat<'_> {
    #[inline]
    fn mean(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter().map(|&(i, c)| c * self.m_entry(i, col).0).sum()
    }
    #[inline]
    fn bnd(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter().map(|&(i, c)| c * self.q_entry(i, col).0).sum()
    }
    #[inline]
    fn mean_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter().map(|&(i, c)| c * self.m_entry(i, col).1).sum()
    }
    #[inline]
    fn bnd_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter().map(|&(i, c)| c * self.q_entry(i, col).1).sum()
    }
}

impl LevelMoments {
    /// The first column of `w` with a non-finite moment (an overflow), if any.
    pub fn overflowed_column(&self) -> Option<usize> {
        let bad = |m: &[f64], n: usize| m.iter().position(|v| !v.is_finite()).map(|i| i % n);
        self.sums
            .iter()
            .chain(&self.tsums)
            .find_map(|m| bad(m, self.n_w))
            .or_else(|| self.snaps.iter().find_map(|m| bad(m, self.n_q)))
    }

    pub fn n_blocks(&self) -> usize {
        self.lens.len()
    }

    /// Blocks whose moments count.
    pub fn kept_blocks(&self) -> usize {
        self.kept.iter().filter(|k| **k).count()
    }

    /// Whether the block before boundary `j` exists and counts.
    #[inline]
    fn kept_before(&self, j: usize) -> bool {
        j > 0 && self.kept[j - 1]
    }

    /// Whether the block after boundary `j` exists and counts.
    #[inline]
    fn kept_after(&self, j: usize) -> bool {
        j < self.n_blocks() && self.kept[j]
    }

    /// Sample intervals of the blocks that count.
    fn intervals(&self) -> usize {
        self.lens
            .iter()
            .zip(&self.kept)
            .filter(|(_, k)| **k)
            .map(|(l, _)| l)
            .sum()
    }

    /// The moments of the whole record.
    pub fn view(&self) -> MomentView {
        let (n_i, n_w, n_q) = (self.n_i, self.n_w, self.n_q);
        let mut m = vec![0.0; n_i * n_w];
        for b in (0..self.n_blocks()).filter(|&b| self.kept[b]) {
            let (s0, s1) = (&self.snaps[b], &self.snaps[b + 1]);
            for i in 0..n_i {
                for j in 0..n_w {
                    m[i * n_w + j] +=
                        self.sums[b][i * n_w + j] + 0.5 * (s1[i * n_q + j] - s0[i * n_q + j]);
                }
            }
        }
        // `[ι q]` over every run of kept blocks: the whole record's ends without rests.
        let mut bnd = vec![0.0; n_i * n_q];
        for j in 0..=self.n_blocks() {
            let (before, after) = (self.kept_before(j), self.kept_after(j));
            if before == after {
                continue;
            }
            let sign = if after { -1.0 } else { 1.0 };
            // (`0 − s + e` is bit for bit the `e − s` of a record without rests.)
            bnd.iter_mut()
                .zip(&self.snaps[j])
                .for_each(|(b, s)| *b += sign * s);
        }
        self.normalise(m, bnd, vec![], vec![])
    }

    /// Weight of hat `j` (`0 ..= n_blocks`): `∫ φ_j / T`. The weights add up to one.
    pub fn hat_weight(&self, j: usize) -> f64 {
        let nb = self.n_blocks();
        let mut w = 0.0;
        if self.kept_before(j) {
            w += 0.5 * self.lens[j - 1] as f64;
        }
        if j < nb && self.kept[j] {
            w += 0.5 * self.lens[j] as f64;
        }
        w / self.intervals() as f64
    }

    /// The contribution of hat `j` (`0 ..= n_blocks`), see the module doc, as whole
    /// matrices (the reference for [`Hat`], which reads the same entries one by one).
    #[cfg(test)]
    pub fn hat(&self, j: usize) -> MomentView {
        let (n_i, n_w, n_q) = (self.n_i, self.n_w, self.n_q);
        let mut m = vec![0.0; n_i * n_w];
        let mut m_d = vec![0.0; n_i * n_w];
        let mut bnd = vec![0.0; n_i * n_q];
        let mut bnd_d = vec![0.0; n_i * n_q];
        // Block b seen from hat j: rising (b = j − 1, φ = s/L, φ' = +1/(L Tₛ)) or falling
        // (b = j, φ = 1 − s/L, φ' = −1/(L Tₛ)). Trapezoid sums in samples:
        // full F = Σ f + ½ (f_end − f_start), rising part R = Σ s f / L + ½ f_end.
        let mut add = |b: usize, rising: bool| {
            let len = self.lens[b] as f64;
            let (s0, s1) = (&self.snaps[b], &self.snaps[b + 1]);
            let sign = if rising { 1.0 } else { -1.0 };
            for i in 0..n_i {
                for k in 0..n_w {
                    let (e0, e1) = (s0[i * n_q + k], s1[i * n_q + k]);
                    let full = self.sums[b][i * n_w + k] + 0.5 * (e1 - e0);
                    let rise = self.tsums[b][i * n_w + k] / len + 0.5 * e1;
                    m[i * n_w + k] += if rising { rise } else { full - rise };
                    m_d[i * n_w + k] += sign * full / len;
                }
                for k in 0..n_q {
                    bnd_d[i * n_q + k] += sign * (s1[i * n_q + k] - s0[i * n_q + k]) / len;
                }
            }
        };
        let (before, after) = (self.kept_before(j), self.kept_after(j));
        if before {
            add(j - 1, true);
        }
        if after {
            add(j, false);
        }
        // φ jumps only at the ends of a run of kept blocks (the record's ends without
        // rests): φ_0(0) = 1, φ_nb(T) = 1.
        if after && !before {
            bnd.iter_mut()
                .zip(&self.snaps[j])
                .for_each(|(b, s)| *b -= s);
        }
        if before && !after {
            bnd.iter_mut()
                .zip(&self.snaps[j])
                .for_each(|(b, s)| *b += s);
        }
        self.normalise(m, bnd, m_d, bnd_d)
    }

    /// Divide sample sums by the record's intervals, point values and `φ'` sums (which carry
    /// a `1/Tₛ`) by its length `T`.
    fn normalise(
        &self,
        mut m: Vec<f64>,
        mut bnd: Vec<f64>,
        mut m_d: Vec<f64>,
        mut bnd_d: Vec<f64>,
    ) -> MomentView {
        let intervals = self.intervals() as f64;
        let t = self.ts * intervals;
        m.iter_mut().for_each(|v| *v /= intervals);
        bnd.iter_mut().for_each(|v| *v /= t);
        // ∫ φ' f dt = Σ_b (±1/(L Tₛ)) · Tₛ F_b = Σ_b ±F_b / L, then divided by T; the
        // boundary differences carry the 1/(L Tₛ) in full.
        m_d.iter_mut().for_each(|v| *v /= t);
        bnd_d.iter_mut().for_each(|v| *v /= t * self.ts);
        MomentView {
            n_w: self.n_w,
            n_q: self.n_q,
            m,
            bnd,
            m_d,
            bnd_d,
        }
    }
}

/// Number of samples in the backward window of the end-point velocity estimate.
const VHAT_WINDOW: usize = 21;

/// Velocity at the last point of `x` (uniform spacing `ts`) from a least-squares quadratic
/// through the window. Its error enters only through boundary terms divided by the block
/// length, so a short one-sided fit is ample.
fn end_velocity(x: &[f64], ts: f64) -> f64 {
    let n = x.len();
    if n < 3 {
        return 0.0;
    }
    // Local time τ_k = k − (n−1) ≤ 0; fit x ≈ c0 + c1 τ + c2 τ², velocity = c1 / Tₛ.
    let mut s = [0.0f64; 5];
    let mut r = [0.0f64; 3];
    for (k, &xk) in x.iter().enumerate() {
        let tau = k as f64 - (n - 1) as f64;
        let mut p = 1.0;
        for (j, sj) in s.iter_mut().enumerate() {
            *sj += p;
            if j < 3 {
                r[j] += p * xk;
            }
            p *= tau;
        }
    }
    let a = nalgebra::Matrix3::new(s[0], s[1], s[2], s[1], s[2], s[3], s[2], s[3], s[4]);
    let c = a
        .lu()
        .solve(&nalgebra::Vector3::new(r[0], r[1], r[2]))
        .unwrap_or_default();
    c[1] / ts
}

/// Half-width of the centred window of the velocity estimate at interior block boundaries.
const VHAT_HALF: usize = 10;

/// Weights `w` of the velocity at the centre of 2·[`VHAT_HALF`] + 1 samples,
/// v ≈ Σ w_k x_k / Tₛ: the slope at the centre of the least-squares polynomial of degree 5
/// (Savitzky–Golay), from the SVD pseudo-inverse of the Vandermonde matrix (time scaled to
/// [−1, 1]). At interior block boundaries samples on both sides are available; the
/// one-sided quadratic of [`end_velocity`] is biased there by the curvature of the signal
/// (with only tens of samples per period). Interior boundary velocities cancel from the
/// whole-record moments and do not enter the hat contributions; they are kept in the
/// snapshots for completeness of `[ι q]`. The centred fit is exact for polynomials of
/// degree 5 and passes a sinusoid with 35 samples per period within 0.1 % (the one-sided
/// fit: about 100 % RMS error there), for a white-noise gain of 0.16 / Tₛ (one-sided:
/// 0.14 / Tₛ).
fn central_velocity_weights() -> Vec<f64> {
    const DEG: usize = 5;
    let h = VHAT_HALF as f64;
    let v = nalgebra::DMatrix::<f64>::from_fn(2 * VHAT_HALF + 1, DEG + 1, |k, j| {
        ((k as f64 - h) / h).powi(j as i32)
    });
    let pinv = v
        .pseudo_inverse(1e-12)
        .expect("invariant: a Vandermonde matrix of distinct points has full rank");
    // x ≈ Σ c_j (t/h)^j, so dx/dt at t = 0 is c_1 / h (t in samples).
    pinv.row(1).iter().map(|w| w / h).collect()
}

/// Samples per task of the time-parallel pass (see [`LevelAccumulator`]): its filter states
/// and basis values (about 50 rows of doubles) stay in the second-level cache between
/// filtering and accumulation, and a default chunk of 8192 samples gives 8 tasks.
pub(crate) const TASK_LEN: usize = 1024;

/// One contiguous run of samples inside a streamed chunk, within one time block.
#[derive(Clone, Copy, Debug)]
struct Task {
    /// First sample, relative to the chunk.
    off: usize,
    len: usize,
    /// First sample in the record.
    global: usize,
    /// The block whose sums it adds to; `None` for the last sample of the record (only a
    /// snapshot).
    block: Option<usize>,
    /// Position of the first sample in its block.
    tpos: usize,
}

/// The working buffers of a task in pass 2, one set per worker thread (not per task: for
/// a wide model they are megabytes each).
#[derive(Default)]
struct TaskScratch {
    /// `ι` sample-major: `iota[k · n_rows + r]`, rows the bank's then the measured signals.
    iota: Vec<f64>,
    /// `w` then `(tpos + k) w`, column-major (`w[col · len + k]`).
    w: Vec<f64>,
    scratch: Vec<f64>,
}

/// The results of one task (kept between chunks).
#[derive(Default)]
struct TaskWork {
    /// `Σ ι [w, (tpos + k) w]ᵀ` over the task, row-major `n_rows × 2 n_w`.
    part: Vec<f64>,
    /// `ι` (in the plan's row order) and `w` at the first sample.
    first_iota: Vec<f64>,
    first_w: Vec<f64>,
    /// Pass 1: the state at the end from a zero start; pass 2: the true end state.
    end: Option<BankState>,
    non_finite: Option<(usize, usize, f64)>,
    filter: Duration,
    evaluate: Duration,
    accumulate: Duration,
}

/// Streams the samples of one level through the filter bank and accumulates moments.
///
/// Each streamed chunk is cut into tasks of at most [`TASK_LEN`] samples (and at the block
/// boundaries), processed in parallel in two passes. The filter is linear, so the state at
/// the start of task `t + 1` is exactly `Φ^{len_t} ζ_start[t] + ζ⁰_end[t]`, with `ζ⁰_end[t]`
/// the end state of task `t` run from rest:
///
/// 1. every task runs the bank from rest (no output) for `ζ⁰_end` — in parallel;
/// 2. a serial scan composes the start states (`Φ^m` by binary powering);
/// 3. every task runs the bank from its true start, writing the states of its samples
///    next to the basis values, and adds `Σ ι wᵀ` and `Σ s ι wᵀ` by one matrix product —
///    in parallel, each task's data read once while it is in cache.
///
/// The tasks depend only on the chunk length and the blocks, not on the number of
/// threads, so neither do the results. Against one serial run they differ by rounding
/// only (the start states and the order of the sums): within 1e-12 relative, see
/// `time_parallel_pass_matches_the_serial_recursion`. Memory is a few buffers per chunk,
/// independent of the record length.
pub(crate) struct LevelAccumulator<'a> {
    plan: &'a Plan,
    eval: &'a dyn BasisEval,
    bank: FilterBank,
    task_len: usize,
    /// Plan row of each row of the bank's output then of the measured signals.
    row_map: Vec<Option<usize>>,
    ts: f64,
    n_total: usize,
    bounds: Vec<usize>,
    kept: Vec<bool>,
    pos: usize,
    /// The bank's state at the last sample fed (meaningless before the first).
    state: Option<BankState>,
    sums: Vec<Vec<f64>>,
    tsums: Vec<Vec<f64>>,
    snaps: Vec<Vec<f64>>,
    tails: Vec<Vec<f64>>,
    work: Vec<TaskWork>,
    /// Pass 2's buffers, one set per worker thread.
    scratch: Vec<std::sync::Mutex<TaskScratch>>,
    /// `0, 1, 2, …, task_len − 1` as floating-point numbers.
    ramp: Vec<f64>,
    qrow: Vec<f64>,
    /// [`central_velocity_weights`].
    vhat_weights: Vec<f64>,
    /// Kernel widths of the plan's extra columns at this level ([`super::noise`]).
    extra_width: Vec<f64>,
    /// The first non-finite basis value met: (root, sample, value).
    pub non_finite: Option<(usize, usize, f64)>,
    pub times: PhaseTimes,
    /// Column drivers ([`super::plan::RootDriver`]): delay in samples of a delayed column
    /// at this level (the velocity differentiator's half-width plus one).
    root_delay: usize,
    /// Per column driver: its values over the last `delay` samples before this chunk.
    root_hist: Vec<Vec<f64>>,
    /// Per column driver: its (delayed) values over the current chunk, driver-major.
    root_buf: Vec<f64>,
    /// With column drivers: every root over the current chunk, root-major, evaluated once
    /// for the drivers and read again by pass 2 (empty without column drivers).
    chunk_roots: Vec<f64>,
}

impl<'a> LevelAccumulator<'a> {
    pub fn new(
        plan: &'a Plan,
        eval: &'a dyn BasisEval,
        ts: f64,
        n_total: usize,
        n_blocks: usize,
        hold: Hold,
    ) -> Self {
        let n_blocks = n_blocks.clamp(1, (n_total - 1).max(1));
        let bounds: Vec<usize> = (0..=n_blocks)
            .map(|b| ((b as u128 * (n_total - 1) as u128) / n_blocks as u128) as usize)
            .collect();
        Self::with_blocks(plan, eval, ts, n_total, bounds, vec![true; n_blocks], hold)
    }

    /// As [`Self::new`] with given block boundaries (`0 … n_total − 1`, increasing) and,
    /// per block, whether its moments count (see [`super::rests`]).
    pub fn with_blocks(
        plan: &'a Plan,
        eval: &'a dyn BasisEval,
        ts: f64,
        n_total: usize,
        bounds: Vec<usize>,
        kept: Vec<bool>,
        hold: Hold,
    ) -> Self {
        assert_eq!(
            bounds.len(),
            kept.len() + 1,
            "invariant: one flag per block"
        );
        let n_blocks = kept.len();
        let bank = FilterBank::new(&plan.corners, plan.n_drivers(), plan.order, ts, hold);
        let (n_i, n_w, n_q) = (plan.n_i(), plan.n_w(), plan.n_q());
        let mut row_map = vec![None; bank.n_rows()];
        for d in 0..plan.n_drivers() {
            for c in 0..plan.corners.len() {
                for i in 0..plan.order {
                    row_map[bank.row(d, c, i)] = Some(plan.state(d, c, i));
                }
            }
        }
        row_map.extend((plan.n_z()..n_i).map(Some));
        let mut acc = LevelAccumulator {
            plan,
            eval,
            bank,
            task_len: 0,
            row_map,
            ts,
            n_total,
            bounds,
            kept,
            pos: 0,
            state: None,
            sums: vec![vec![0.0; n_i * n_w]; n_blocks],
            tsums: vec![vec![0.0; n_i * n_w]; n_blocks],
            snaps: vec![vec![0.0; n_i * n_q]; n_blocks + 1],
            tails: vec![Vec::with_capacity(VHAT_WINDOW); plan.vhat_bodies.len()],
            work: Vec::new(),
            scratch: (0..rayon::current_num_threads().max(1))
                .map(|_| Default::default())
                .collect(),
            ramp: Vec::new(),
            qrow: vec![0.0; n_q],
            vhat_weights: central_velocity_weights(),
            extra_width: vec![1.0; plan.extra.len()],
            non_finite: None,
            times: PhaseTimes::default(),
            root_delay: 0,
            root_hist: vec![Vec::new(); plan.root_drivers.len()],
            root_buf: Vec::new(),
            chunk_roots: Vec::new(),
        };
        acc.set_task_len(TASK_LEN);
        acc
    }

    /// Samples per task of the time-parallel pass (at least 1; [`TASK_LEN`] by default).
    pub fn set_task_len(&mut self, task_len: usize) {
        self.task_len = task_len.max(1);
        self.ramp = (0..self.task_len).map(|k| k as f64).collect();
        self.bank.prepare_propagation(self.task_len);
    }

    /// Delay of the delayed column drivers at this level, in samples (see
    /// [`super::plan::RootDriver`]); set before the first chunk.
    pub fn set_root_delay(&mut self, delay: usize) {
        assert_eq!(
            self.pos, 0,
            "invariant: the delay is set before the first chunk"
        );
        self.root_delay = delay;
    }

    /// Fill `root_buf` with the column drivers' values over the next `len` samples: the
    /// basis evaluated over the chunk into `chunk_roots` (in tasks, in parallel; pass 2
    /// reads it instead of evaluating again), each delayed column shifted
    /// by the delay through `root_hist` (before the record's first sample a column holds
    /// its first value, as the filters start at rest there).
    fn fill_root_drivers(&mut self, cols: &[&[f64]], len: usize) {
        use rayon::prelude::*;
        let plan = self.plan;
        let n_g = plan.roots.len();
        if plan.root_drivers.is_empty() || n_g == 0 {
            return;
        }
        let step = self.task_len;
        let mut g = std::mem::take(&mut self.chunk_roots);
        g.resize(n_g * len, 0.0);
        let pieces: Vec<(usize, usize)> = (0..len)
            .step_by(step)
            .map(|o| (o, step.min(len - o)))
            .collect();
        let parts: Vec<Vec<f64>> = pieces
            .par_iter()
            .map(|&(o, l)| {
                let view: Vec<&[f64]> = cols
                    .iter()
                    .map(|c| if c.is_empty() { *c } else { &c[o..o + l] })
                    .collect();
                let mut out = vec![0.0; n_g * l];
                self.eval.eval_block(&view, l, &mut out, &mut Vec::new());
                out
            })
            .collect();
        for (&(o, l), part) in pieces.iter().zip(&parts) {
            for r in 0..n_g {
                // shape: `part` is n_g × l column-major, `g` is n_g × len.
                g[r * len + o..r * len + o + l].copy_from_slice(&part[r * l..(r + 1) * l]);
            }
        }
        self.root_buf.resize(plan.root_drivers.len() * len, 0.0);
        for (k, rd) in plan.root_drivers.iter().enumerate() {
            // shape: `g` holds every root over the chunk; `rd.root < n_g`.
            let col = &g[rd.root * len..(rd.root + 1) * len];
            let dst = &mut self.root_buf[k * len..(k + 1) * len];
            let delay = if rd.delayed { self.root_delay } else { 0 };
            if delay == 0 {
                dst.copy_from_slice(col);
                continue;
            }
            let hist = &mut self.root_hist[k];
            if self.pos == 0 {
                hist.clear();
                hist.resize(delay, col.first().copied().unwrap_or(0.0));
            }
            // The concatenation `hist ++ col`: the chunk's driver is its first `len`
            // values, the next history its last `delay`.
            let mut all = std::mem::take(hist);
            all.extend_from_slice(col);
            dst.copy_from_slice(&all[..len]);
            *hist = all[len..].to_vec();
        }
        self.chunk_roots = g;
    }

    /// Set the kernel widths of the plan's extra columns for this level.
    pub fn set_extra_widths(&mut self, widths: Vec<f64>) {
        assert_eq!(widths.len(), self.plan.extra.len());
        self.extra_width = widths;
    }

    /// The pieces of the next `len` samples between block boundaries: `(offset, length)`.
    fn pieces(&self, len: usize) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        let mut off = 0;
        while off < len {
            let p0 = self.pos + off;
            // Split at the next block boundary strictly after p0 (and at the last sample).
            let next_bound = self
                .bounds
                .iter()
                .copied()
                .find(|&b| b > p0)
                .unwrap_or(self.n_total);
            let piece = (len - off).min(next_bound - p0);
            out.push((off, piece));
            off += piece;
        }
        out
    }

    /// Feed the next `len` samples; `cols[s]` is signal `s` (by `SignalId`).
    pub fn push(&mut self, cols: &[&[f64]], len: usize) {
        use rayon::prelude::*;
        if len == 0 {
            return;
        }
        let plan = self.plan;
        let pieces = self.pieces(len);
        let mut tasks = Vec::new();
        for &(off, plen) in &pieces {
            let global = self.pos + off;
            let block = self.bounds.iter().rposition(|&b| b <= global).unwrap_or(0);
            let block = (block < self.sums.len()).then_some(block);
            let b0 = block.map_or(global, |b| self.bounds[b]);
            let mut o = 0;
            while o < plen {
                let tl = (plen - o).min(self.task_len);
                tasks.push(Task {
                    off: off + o,
                    len: tl,
                    global: global + o,
                    block,
                    tpos: global + o - b0,
                });
                o += tl;
            }
        }
        if self.work.len() < tasks.len() {
            self.work.resize_with(tasks.len(), TaskWork::default);
        }
        self.fill_root_drivers(cols, len);
        let root_buf = std::mem::take(&mut self.root_buf);
        let chunk_roots = std::mem::take(&mut self.chunk_roots);
        let mut drivers: Vec<&[f64]> = plan.drivers.iter().map(|d| cols[d.index()]).collect();
        if !plan.root_drivers.is_empty() {
            drivers.extend(root_buf.chunks_exact(len));
        }
        let bank = &self.bank;
        let at = |k: usize| -> Vec<f64> { drivers.iter().map(|c| c[k]).collect() };
        // The state before each task's first sample; the record's first task starts at rest
        // at its own first sample.
        let start_of = |t: &Task, carried: Option<&BankState>| match (t.global, carried) {
            (0, _) => bank.state(&at(t.off)),
            (_, Some(s)) if t.off == 0 => s.clone(),
            _ => bank.state(&at(t.off - 1)),
        };
        let carried = self.state.take();
        let mut starts = vec![start_of(&tasks[0], carried.as_ref())];
        if tasks.len() > 1 {
            // Pass 1: each task from rest (the first from its true start).
            let work = &mut self.work[..tasks.len()];
            let first = &starts[0];
            tasks
                .par_iter()
                .zip(work.par_iter_mut())
                .enumerate()
                .for_each(|(i, (t, wk))| {
                    let clock = Instant::now();
                    let mut st = if i == 0 {
                        first.clone()
                    } else {
                        start_of(t, None)
                    };
                    run_filter(bank, &mut st, &drivers, t, None);
                    wk.end = Some(st);
                    wk.filter += clock.elapsed();
                });
            let clock = Instant::now();
            for (i, t) in tasks.iter().enumerate().take(tasks.len() - 1) {
                let end = self.work[i]
                    .end
                    .take()
                    .expect("invariant: pass 1 ran for every task");
                let next = if i == 0 {
                    end
                } else {
                    bank.compose(&starts[i], t.len, &end)
                };
                starts.push(next);
            }
            self.times.filter += clock.elapsed();
        }

        // Pass 2: from the true starts, with the moments.
        let (n_w, n_rows) = (plan.n_w(), self.row_map.len());
        let ctx = TaskCtx {
            plan,
            eval: self.eval,
            bank,
            row_map: &self.row_map,
            extra_width: &self.extra_width,
            cols,
            drivers: &drivers,
            ramp: &self.ramp,
            roots: (!chunk_roots.is_empty()).then_some((&chunk_roots[..], len)),
        };
        let pool = &self.scratch;
        tasks
            .par_iter()
            .zip(self.work[..tasks.len()].par_iter_mut())
            .zip(starts.into_par_iter())
            .for_each(|((t, wk), st)| {
                // The worker's own buffers, kept between tasks and chunks (grown once, never
                // zeroed again). Another thread of a pool larger than the one the
                // accumulator was made for may find them taken: it then uses its own.
                let slot = rayon::current_thread_index().unwrap_or(0) % pool.len();
                match pool[slot].try_lock() {
                    Ok(mut sc) => ctx.run(t, wk, &mut sc, st),
                    Err(_) => ctx.run(t, wk, &mut TaskScratch::default(), st),
                }
            });

        // In order: snapshots, block sums, velocity tails.
        let mut ti = 0;
        for &(off, plen) in &pieces {
            let p0 = self.pos + off;
            let clock = Instant::now();
            if let Some(b) = self.bounds.iter().position(|&b| b == p0) {
                self.snapshot(b, ti, cols, off, plen);
            }
            while ti < tasks.len() && tasks[ti].off < off + plen {
                let (t, wk) = (&tasks[ti], &mut self.work[ti]);
                if self.non_finite.is_none() {
                    self.non_finite = wk.non_finite;
                }
                if let Some(b) = t.block {
                    let (sums, tsums) = (&mut self.sums[b], &mut self.tsums[b]);
                    for (r, part) in wk.part.chunks_exact(2 * n_w).enumerate().take(n_rows) {
                        if let Some(m) = self.row_map[r] {
                            let (ps, pt) = part.split_at(n_w);
                            for (d, p) in sums[m * n_w..(m + 1) * n_w].iter_mut().zip(ps) {
                                *d += p;
                            }
                            for (d, p) in tsums[m * n_w..(m + 1) * n_w].iter_mut().zip(pt) {
                                *d += p;
                            }
                        }
                    }
                }
                self.times.filter += std::mem::take(&mut wk.filter);
                self.times.evaluate += std::mem::take(&mut wk.evaluate);
                self.times.accumulate += std::mem::take(&mut wk.accumulate);
                ti += 1;
            }
            // Keep the most recent positions for end-point velocity estimates.
            for (k, body) in plan.vhat_bodies.iter().enumerate() {
                let x = &cols[plan_position(*body)][off..off + plen];
                let tail = &mut self.tails[k];
                let take = x.len().min(VHAT_WINDOW - 1);
                let keep = (VHAT_WINDOW - 1 - take).min(tail.len());
                tail.drain(..tail.len() - keep);
                tail.extend_from_slice(&x[x.len() - take..]);
            }
            self.times.accumulate += clock.elapsed();
        }
        self.state = self.work[tasks.len() - 1].end.take();
        self.pos += len;
        self.root_buf = root_buf;
        self.chunk_roots = chunk_roots;
    }

    /// The snapshot `ι qᵀ` at block boundary `b`, the first sample of the piece
    /// `cols[..][off .. off + plen]`, whose first task is `self.work[task]`.
    fn snapshot(&mut self, b: usize, task: usize, cols: &[&[f64]], off: usize, plen: usize) {
        let plan = self.plan;
        let (n_i, n_w, n_q) = (plan.n_i(), plan.n_w(), plan.n_q());
        let wk = &self.work[task];
        self.qrow[..n_w].copy_from_slice(&wk.first_w);
        for (k, body) in plan.vhat_bodies.iter().enumerate() {
            let x = &cols[plan_position(*body)][off..off + plen];
            let tail = &self.tails[k];
            // Interior boundary with enough samples on both sides in hand: centred fit.
            // (A boundary within a few samples of a chunk end keeps the one-sided fit.)
            if tail.len() >= VHAT_HALF && x.len() > VHAT_HALF {
                let win = tail[tail.len() - VHAT_HALF..]
                    .iter()
                    .chain(&x[..=VHAT_HALF]);
                self.qrow[n_w + k] =
                    win.zip(&self.vhat_weights).map(|(x, w)| x * w).sum::<f64>() / self.ts;
            } else {
                let mut win: Vec<f64> = tail.clone();
                win.push(x[0]);
                self.qrow[n_w + k] = end_velocity(&win, self.ts);
            }
        }
        let snap = &mut self.snaps[b];
        for i in 0..n_i {
            let ii = wk.first_iota[i];
            for k in 0..n_q {
                snap[i * n_q + k] = ii * self.qrow[k];
            }
        }
    }

    pub fn finish(self) -> (LevelMoments, PhaseTimes) {
        assert_eq!(self.pos, self.n_total, "record ended early");
        let lens = self.bounds.windows(2).map(|w| w[1] - w[0]).collect();
        (
            LevelMoments {
                n_i: self.plan.n_i(),
                n_w: self.plan.n_w(),
                n_q: self.plan.n_q(),
                ts: self.ts,
                sums: self.sums,
                tsums: self.tsums,
                lens,
                snaps: self.snaps,
                kept: self.kept,
            },
            self.times,
        )
    }
}

/// The column of body `b`'s position.
fn plan_position(b: dynid_ir::ir::BodyId) -> usize {
    2 * b.index()
}

/// Advance the bank over task `t` from `st` (for the record's first task: at rest at its
/// first sample, whose output is the rest state).
fn run_filter(
    bank: &FilterBank,
    st: &mut BankState,
    drivers: &[&[f64]],
    t: &Task,
    out: Option<(&mut [f64], usize)>,
) {
    let skip = usize::from(t.global == 0);
    let out = match out {
        Some((buf, stride)) if skip == 1 => {
            buf[..bank.n_rows()].fill(0.0);
            Some((&mut buf[stride..], stride))
        }
        o => o,
    };
    let ds: Vec<&[f64]> = drivers
        .iter()
        .map(|c| &c[t.off + skip..t.off + t.len])
        .collect();
    bank.advance(st, &ds, t.len - skip, out);
}

/// Whether every value is finite: `v · 0` is zero for a finite `v` and NaN otherwise, summed
/// in eight independent lanes (one pass, no branch per value, vectorised).
fn all_finite(c: &[f64]) -> bool {
    let mut acc = [0.0f64; 8];
    let mut chunks = c.chunks_exact(8);
    for ch in &mut chunks {
        for (a, v) in acc.iter_mut().zip(ch) {
            *a += v * 0.0;
        }
    }
    for (a, v) in acc.iter_mut().zip(chunks.remainder()) {
        *a += v * 0.0;
    }
    acc.iter().sum::<f64>() == 0.0
}

/// What pass 2 of every task reads.
struct TaskCtx<'c> {
    plan: &'c Plan,
    eval: &'c dyn BasisEval,
    bank: &'c FilterBank,
    row_map: &'c [Option<usize>],
    extra_width: &'c [f64],
    cols: &'c [&'c [f64]],
    drivers: &'c [&'c [f64]],
    /// `0, 1, 2, …` up to the task length, as floating-point numbers.
    ramp: &'c [f64],
    /// Every root over the chunk (root-major) and the chunk's length, where the column
    /// drivers evaluated them already.
    roots: Option<(&'c [f64], usize)>,
}

impl TaskCtx<'_> {
    /// Pass 2 of one task: filter from the true start `st`, evaluate the basis, and form
    /// the task's moment sums.
    fn run(&self, t: &Task, wk: &mut TaskWork, sc: &mut TaskScratch, mut st: BankState) {
        let plan = self.plan;
        let (n_w, n_g, n_y) = (plan.n_w(), plan.roots.len(), plan.y.len());
        let (len, n_rows, n_zr) = (t.len, self.row_map.len(), self.bank.n_rows());
        let view: Vec<&[f64]> = self
            .cols
            .iter()
            .map(|c| {
                if c.is_empty() {
                    *c
                } else {
                    &c[t.off..t.off + len]
                }
            })
            .collect();

        let clock = Instant::now();
        sc.iota.resize(n_rows * len, 0.0);
        run_filter(
            self.bank,
            &mut st,
            self.drivers,
            t,
            Some((&mut sc.iota[..], n_rows)),
        );
        wk.end = Some(st);
        // The measured signals after the bank's rows, all in one sweep over the samples.
        let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
        for (k, row) in sc.iota.chunks_exact_mut(n_rows).enumerate() {
            for (d, y) in row[n_zr..n_zr + ys.len()].iter_mut().zip(&ys) {
                *d = y[k];
            }
        }
        wk.filter += clock.elapsed();

        let clock = Instant::now();
        sc.w.resize(2 * n_w * len, 0.0);
        let (w_g, w_rest) = sc.w.split_at_mut(n_g * len);
        match self.roots {
            Some((g, chunk)) => {
                for (r, dst) in w_g.chunks_exact_mut(len).enumerate() {
                    // shape: `g` is n_g × chunk and the task lies inside the chunk.
                    dst.copy_from_slice(&g[r * chunk + t.off..r * chunk + t.off + len]);
                }
            }
            None if n_g > 0 => self.eval.eval_block(&view, len, w_g, &mut sc.scratch),
            None => {}
        }
        for (k, s) in plan.y.iter().enumerate() {
            w_rest[k * len..(k + 1) * len].copy_from_slice(view[s.index()]);
        }
        if !plan.extra.is_empty() {
            let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
            super::noise::fill_extra(
                &plan.extra,
                self.extra_width,
                &ys,
                len,
                &mut w_rest[n_y * len..(n_w - n_g) * len],
            );
        }
        wk.non_finite = w_g
            .chunks_exact(len)
            .enumerate()
            .find(|(_, c)| !all_finite(c))
            .and_then(|(r, c)| {
                let i = c.iter().position(|v| !v.is_finite())?;
                Some((r, t.global + i, c[i]))
            });
        wk.evaluate += clock.elapsed();

        let clock = Instant::now();
        wk.first_w.clear();
        wk.first_w
            .extend(sc.w.chunks_exact(len).take(n_w).map(|c| c[0]));
        wk.first_iota.resize(plan.n_i(), 0.0);
        for (r, m) in self.row_map.iter().enumerate() {
            if let Some(m) = m {
                wk.first_iota[*m] = sc.iota[r];
            }
        }
        if t.block.is_some() {
            // Position of each sample in its block, for the hat contributions: `tpos + k`
            // as the sum of two floating-point integers (exact), so the loop vectorises.
            let (w, w_t) = sc.w.split_at_mut(n_w * len);
            let (t0, ramp) = (t.tpos as f64, &self.ramp[..len]);
            for (dst, src) in w_t.chunks_exact_mut(len).zip(w.chunks_exact(len)) {
                for ((d, s), r) in dst.iter_mut().zip(src).zip(ramp) {
                    *d = (t0 + r) * s;
                }
            }
            wk.part.resize(n_rows * 2 * n_w, 0.0);
            let a = MatRef::from_column_major_slice(&sc.iota[..], n_rows, len);
            let b = MatRef::from_column_major_slice(&sc.w[..], len, 2 * n_w);
            let dst = MatMut::from_row_major_slice_mut(&mut wk.part[..], n_rows, 2 * n_w);
            faer::linalg::matmul::matmul(dst, Accum::Replace, a, b, 1.0, Par::Seq);
        }
        wk.accumulate += clock.elapsed();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_finite_finds_every_kind_of_non_finite_value_anywhere() {
        for len in [0, 1, 7, 8, 9, 23, 1024] {
            let c: Vec<f64> = (0..len).map(|k| (k as f64 - 3.0) * 1e300).collect();
            assert!(all_finite(&c), "len {len}");
            for at in 0..len {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut d = c.clone();
                    d[at] = bad;
                    assert!(!all_finite(&d), "len {len}, {bad} at {at}");
                }
            }
        }
    }

    #[test]
    fn central_velocity_is_exact_to_degree_five_and_sharp_on_sinusoids() {
        let w = central_velocity_weights();
        assert_eq!(w.len(), 2 * VHAT_HALF + 1);
        let h = VHAT_HALF as f64;
        let ts = 0.01;
        // x(t) = t^j (t in seconds, centred): slope 1 for j = 1, 0 otherwise.
        for j in 0..=5 {
            let x: Vec<f64> = (0..w.len())
                .map(|k| ((k as f64 - h) * ts).powi(j))
                .collect();
            let v: f64 = x.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / ts;
            let want = if j == 1 { 1.0 } else { 0.0 };
            assert!((v - want).abs() < 1e-9, "degree {j}: {v}");
        }
        // 35 samples per period, at several phases: within 0.1 % of the amplitude ω.
        let omega = 2.0 * std::f64::consts::PI / (35.0 * ts);
        for phase in [0.0, 0.7, 2.1] {
            let v: f64 = w
                .iter()
                .enumerate()
                .map(|(k, w)| w * (omega * (k as f64 - h) * ts + phase).sin())
                .sum::<f64>()
                / ts;
            let want = omega * phase.cos();
            assert!(
                (v - want).abs() < 1e-3 * omega,
                "phase {phase}: {v} vs {want}"
            );
        }
    }
}
