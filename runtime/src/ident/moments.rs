//! The raw cross moments of one excitation level, per time block, and the views the
//! estimating equations read from them: the whole record's and each hat window's.
//!
//! The moments are accumulated by `super::accumulate`: per sample `ι wᵀ` (with `ι = [ζ; y]`,
//! `w = [g; y]`) is added to the sum of the current time block. Every moment the equations
//! need, including those with `ζ'` and `ζ''`, is a fixed linear combination of these (see
//! [`super::plan`]).
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
use std::time::Duration;

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
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct LevelMoments {
    pub n_row_signals: usize,
    pub n_col_signals: usize,
    pub n_snap_cols: usize,
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
    pub n_col_signals: usize,
    pub n_snap_cols: usize,
    pub m: Vec<f64>,
    pub bnd: Vec<f64>,
    /// `∫ φ' ι w / T`; empty for `φ ≡ 1`.
    pub m_d: Vec<f64>,
    /// `Σ_b φ'_b [ι q]_b / T`; empty for `φ ≡ 1`.
    pub bnd_d: Vec<f64>,
    /// `∫ φ / T`: 1 for the whole record.
    pub weight: f64,
}

/// The moments an estimating equation reads from a weight `φ`'s view of a level: `⟨φ ι w⟩`,
/// the boundary terms `[φ ι q]/T` and the `φ'` terms, each for an instrument given as a
/// combination `a` of filter states `(i, coefficient)` and a column of `w` (or `q`).
pub(crate) trait Window {
    fn mean(&self, a: &[(usize, f64)], col: usize) -> f64;
    fn bnd(&self, a: &[(usize, f64)], col: usize) -> f64;
    fn mean_d(&self, a: &[(usize, f64)], col: usize) -> f64;
    fn bnd_d(&self, a: &[(usize, f64)], col: usize) -> f64;
    /// `⟨φ⟩ = ∫ φ / T`, the moment of a constant 1.
    fn weight(&self) -> f64;
}

impl Window for MomentView {
    #[inline]
    fn mean(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter()
            .map(|&(i, c)| c * self.m[i * self.n_col_signals + col])
            .sum()
    }
    #[inline]
    fn bnd(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter()
            .map(|&(i, c)| c * self.bnd[i * self.n_snap_cols + col])
            .sum()
    }
    #[inline]
    fn mean_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        if self.m_d.is_empty() {
            return 0.0;
        }
        a.iter()
            .map(|&(i, c)| c * self.m_d[i * self.n_col_signals + col])
            .sum()
    }
    #[inline]
    fn bnd_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        if self.bnd_d.is_empty() {
            return 0.0;
        }
        a.iter()
            .map(|&(i, c)| c * self.bnd_d[i * self.n_snap_cols + col])
            .sum()
    }
    #[inline]
    fn weight(&self) -> f64 {
        self.weight
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
        let (n_col_signals, n_snap_cols) = (lm.n_col_signals, lm.n_snap_cols);
        let (mut m, mut m_d) = (0.0, 0.0);
        let mut add = |b: usize, rising: bool| {
            let len = lm.lens[b] as f64;
            let (e0, e1) = (
                lm.snaps[b][i * n_snap_cols + k],
                lm.snaps[b + 1][i * n_snap_cols + k],
            );
            let sign = if rising { 1.0 } else { -1.0 };
            let full = lm.sums[b][i * n_col_signals + k] + 0.5 * (e1 - e0);
            let rise = lm.tsums[b][i * n_col_signals + k] / len + 0.5 * e1;
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
        let n_snap_cols = lm.n_snap_cols;
        let mut bnd_d = 0.0;
        let mut add = |b: usize, rising: bool| {
            let len = lm.lens[b] as f64;
            let sign = if rising { 1.0 } else { -1.0 };
            bnd_d += sign
                * (lm.snaps[b + 1][i * n_snap_cols + k] - lm.snaps[b][i * n_snap_cols + k])
                / len;
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
            bnd -= lm.snaps[self.j][i * n_snap_cols + k];
        }
        if before && !after {
            bnd += lm.snaps[self.j][i * n_snap_cols + k];
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
    fn weight(&self) -> f64 {
        self.lm.hat_weight(self.j)
    }
}

impl LevelMoments {
    /// The first column of `w` with a non-finite moment (an overflow), if any.
    pub fn overflowed_column(&self) -> Option<usize> {
        let bad = |m: &[f64], n: usize| m.iter().position(|v| !v.is_finite()).map(|i| i % n);
        self.sums
            .iter()
            .chain(&self.tsums)
            .find_map(|m| bad(m, self.n_col_signals))
            .or_else(|| self.snaps.iter().find_map(|m| bad(m, self.n_snap_cols)))
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
    pub(crate) fn kept_before(&self, j: usize) -> bool {
        j > 0 && self.kept[j - 1]
    }

    /// Whether the block after boundary `j` exists and counts.
    #[inline]
    pub(crate) fn kept_after(&self, j: usize) -> bool {
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
        let (n_row_signals, n_col_signals, n_snap_cols) =
            (self.n_row_signals, self.n_col_signals, self.n_snap_cols);
        let mut m = vec![0.0; n_row_signals * n_col_signals];
        for b in (0..self.n_blocks()).filter(|&b| self.kept[b]) {
            let (s0, s1) = (&self.snaps[b], &self.snaps[b + 1]);
            for i in 0..n_row_signals {
                for j in 0..n_col_signals {
                    m[i * n_col_signals + j] += self.sums[b][i * n_col_signals + j]
                        + 0.5 * (s1[i * n_snap_cols + j] - s0[i * n_snap_cols + j]);
                }
            }
        }
        // `[ι q]` over every run of kept blocks: the whole record's ends without rests.
        let mut bnd = vec![0.0; n_row_signals * n_snap_cols];
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
        let (n_row_signals, n_col_signals, n_snap_cols) =
            (self.n_row_signals, self.n_col_signals, self.n_snap_cols);
        let mut m = vec![0.0; n_row_signals * n_col_signals];
        let mut m_d = vec![0.0; n_row_signals * n_col_signals];
        let mut bnd = vec![0.0; n_row_signals * n_snap_cols];
        let mut bnd_d = vec![0.0; n_row_signals * n_snap_cols];
        // Block b seen from hat j: rising (b = j − 1, φ = s/L, φ' = +1/(L Tₛ)) or falling
        // (b = j, φ = 1 − s/L, φ' = −1/(L Tₛ)). Trapezoid sums in samples:
        // full F = Σ f + ½ (f_end − f_start), rising part R = Σ s f / L + ½ f_end.
        let mut add = |b: usize, rising: bool| {
            let len = self.lens[b] as f64;
            let (s0, s1) = (&self.snaps[b], &self.snaps[b + 1]);
            let sign = if rising { 1.0 } else { -1.0 };
            for i in 0..n_row_signals {
                for k in 0..n_col_signals {
                    let (e0, e1) = (s0[i * n_snap_cols + k], s1[i * n_snap_cols + k]);
                    let full = self.sums[b][i * n_col_signals + k] + 0.5 * (e1 - e0);
                    let rise = self.tsums[b][i * n_col_signals + k] / len + 0.5 * e1;
                    m[i * n_col_signals + k] += if rising { rise } else { full - rise };
                    m_d[i * n_col_signals + k] += sign * full / len;
                }
                for k in 0..n_snap_cols {
                    bnd_d[i * n_snap_cols + k] +=
                        sign * (s1[i * n_snap_cols + k] - s0[i * n_snap_cols + k]) / len;
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
        MomentView {
            weight: self.hat_weight(j),
            ..self.normalise(m, bnd, m_d, bnd_d)
        }
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
            n_col_signals: self.n_col_signals,
            n_snap_cols: self.n_snap_cols,
            m,
            bnd,
            m_d,
            bnd_d,
            weight: 1.0,
        }
    }
}
