//! Streaming accumulation of the raw cross moments of one excitation level.
//!
//! Per sample the only work is: evaluate the static basis `g`, advance the filter bank `ζ`,
//! and add `ι wᵀ` (with `ι = [ζ; y]`, `w = [g; y]`) to the sum of the current time block —
//! done per chunk as one matrix product. Every moment the equations need, including those
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

use super::filter::{ChainDisc, Hold};
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
}

impl std::ops::AddAssign for PhaseTimes {
    fn add_assign(&mut self, o: Self) {
        self.read += o.read;
        self.filter += o.filter;
        self.evaluate += o.evaluate;
        self.accumulate += o.accumulate;
        self.solve += o.solve;
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

impl MomentView {
    #[inline]
    pub fn mean(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter().map(|&(i, c)| c * self.m[i * self.n_w + col]).sum()
    }
    #[inline]
    pub fn bnd(&self, a: &[(usize, f64)], col: usize) -> f64 {
        a.iter()
            .map(|&(i, c)| c * self.bnd[i * self.n_q + col])
            .sum()
    }
    #[inline]
    pub fn mean_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        if self.m_d.is_empty() {
            return 0.0;
        }
        a.iter()
            .map(|&(i, c)| c * self.m_d[i * self.n_w + col])
            .sum()
    }
    #[inline]
    pub fn bnd_d(&self, a: &[(usize, f64)], col: usize) -> f64 {
        if self.bnd_d.is_empty() {
            return 0.0;
        }
        a.iter()
            .map(|&(i, c)| c * self.bnd_d[i * self.n_q + col])
            .sum()
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

    fn intervals(&self) -> usize {
        self.lens.iter().sum()
    }

    /// The moments of the whole record.
    pub fn view(&self) -> MomentView {
        let (n_i, n_w, n_q) = (self.n_i, self.n_w, self.n_q);
        let mut m = vec![0.0; n_i * n_w];
        for b in 0..self.n_blocks() {
            let (s0, s1) = (&self.snaps[b], &self.snaps[b + 1]);
            for i in 0..n_i {
                for j in 0..n_w {
                    m[i * n_w + j] +=
                        self.sums[b][i * n_w + j] + 0.5 * (s1[i * n_q + j] - s0[i * n_q + j]);
                }
            }
        }
        let (first, last) = (&self.snaps[0], &self.snaps[self.n_blocks()]);
        let bnd: Vec<f64> = last.iter().zip(first).map(|(a, b)| a - b).collect();
        self.normalise(m, bnd, vec![], vec![])
    }

    /// Weight of hat `j` (`0 ..= n_blocks`): `∫ φ_j / T`. The weights add up to one.
    pub fn hat_weight(&self, j: usize) -> f64 {
        let nb = self.n_blocks();
        let mut w = 0.0;
        if j > 0 {
            w += 0.5 * self.lens[j - 1] as f64;
        }
        if j < nb {
            w += 0.5 * self.lens[j] as f64;
        }
        w / self.intervals() as f64
    }

    /// The contribution of hat `j` (`0 ..= n_blocks`), see the module doc.
    pub fn hat(&self, j: usize) -> MomentView {
        let (n_i, n_w, n_q) = (self.n_i, self.n_w, self.n_q);
        let nb = self.n_blocks();
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
        if j > 0 {
            add(j - 1, true);
        }
        if j < nb {
            add(j, false);
        }
        // φ jumps only at the record ends: φ_0(0) = 1, φ_nb(T) = 1.
        if j == 0 {
            bnd.iter_mut()
                .zip(&self.snaps[0])
                .for_each(|(b, s)| *b -= s);
        }
        if j == nb {
            bnd.iter_mut()
                .zip(&self.snaps[nb])
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

/// Streams the samples of one level through the filter bank and accumulates moments.
pub(crate) struct LevelAccumulator<'a> {
    plan: &'a Plan,
    eval: &'a dyn BasisEval,
    chains: Vec<ChainDisc>,
    ts: f64,
    n_total: usize,
    bounds: Vec<usize>,
    pos: usize,
    z_state: Vec<f64>,
    s_prev: Vec<f64>,
    sums: Vec<Vec<f64>>,
    tsums: Vec<Vec<f64>>,
    snaps: Vec<Vec<f64>>,
    tails: Vec<Vec<f64>>,
    iota: Vec<f64>,
    wbuf: Vec<f64>,
    /// `wbuf` weighted by the sample's position in its block.
    wbuf_t: Vec<f64>,
    scratch: Vec<f64>,
    qrow: Vec<f64>,
    /// [`central_velocity_weights`].
    vhat_weights: Vec<f64>,
    /// Kernel widths of the plan's extra columns at this level ([`super::noise`]).
    extra_width: Vec<f64>,
    /// The first non-finite basis value met: (root, sample, value).
    pub non_finite: Option<(usize, usize, f64)>,
    pub times: PhaseTimes,
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
        let chains = plan
            .corners
            .iter()
            .map(|&l| ChainDisc::new(l, plan.order, ts, hold))
            .collect();
        let (n_i, n_w, n_q) = (plan.n_i(), plan.n_w(), plan.n_q());
        LevelAccumulator {
            plan,
            eval,
            chains,
            ts,
            n_total,
            bounds,
            pos: 0,
            z_state: vec![0.0; plan.n_z()],
            s_prev: vec![0.0; plan.drivers.len()],
            sums: vec![vec![0.0; n_i * n_w]; n_blocks],
            tsums: vec![vec![0.0; n_i * n_w]; n_blocks],
            snaps: vec![vec![0.0; n_i * n_q]; n_blocks + 1],
            tails: vec![Vec::with_capacity(VHAT_WINDOW); plan.vhat_bodies.len()],
            iota: Vec::new(),
            wbuf: Vec::new(),
            wbuf_t: Vec::new(),
            scratch: Vec::new(),
            qrow: vec![0.0; n_q],
            vhat_weights: central_velocity_weights(),
            extra_width: vec![1.0; plan.extra.len()],
            non_finite: None,
            times: PhaseTimes::default(),
        }
    }

    /// Set the kernel widths of the plan's extra columns for this level.
    pub fn set_extra_widths(&mut self, widths: Vec<f64>) {
        assert_eq!(widths.len(), self.plan.extra.len());
        self.extra_width = widths;
    }

    /// Feed the next `len` samples; `cols[s]` is signal `s` (by `SignalId`).
    pub fn push(&mut self, cols: &[&[f64]], len: usize) {
        let mut off = 0;
        while off < len {
            let p0 = self.pos;
            // Split at the next block boundary strictly after p0 (and at the last sample).
            let next_bound = self
                .bounds
                .iter()
                .copied()
                .find(|&b| b > p0)
                .unwrap_or(self.n_total);
            let piece = (len - off).min(next_bound - p0);
            self.piece(cols, off, piece);
            off += piece;
        }
    }

    fn piece(&mut self, cols: &[&[f64]], off: usize, len: usize) {
        let plan = self.plan;
        let (n_z, n_i, n_w, n_q) = (plan.n_z(), plan.n_i(), plan.n_w(), plan.n_q());
        let n_g = plan.roots.len();
        let p0 = self.pos;
        self.iota.resize(n_i * len, 0.0);
        self.wbuf.resize(n_w * len, 0.0);
        let view: Vec<&[f64]> = cols
            .iter()
            .map(|c| if c.is_empty() { *c } else { &c[off..off + len] })
            .collect();

        let (iota_z, iota_y) = self.iota.split_at_mut(n_z * len);
        let (w_g, w_y) = self.wbuf.split_at_mut(n_g * len);
        for (k, s) in plan.y.iter().enumerate() {
            iota_y[k * len..(k + 1) * len].copy_from_slice(view[s.index()]);
            w_y[k * len..(k + 1) * len].copy_from_slice(view[s.index()]);
        }
        if !plan.extra.is_empty() {
            let ny = plan.y.len();
            let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
            super::noise::fill_extra(
                &plan.extra,
                &self.extra_width,
                &ys,
                len,
                &mut w_y[ny * len..],
            );
        }
        let eval = self.eval;
        let scratch = &mut self.scratch;
        let chains = &self.chains;
        let order = plan.order;
        let n_c = plan.corners.len();
        let z_state = &mut self.z_state;
        let s_prev = &mut self.s_prev;
        let first = p0 == 0;
        let (t_eval, t_filter) = rayon::join(
            || {
                let t = Instant::now();
                if n_g > 0 {
                    eval.eval_block(&view, len, w_g, scratch);
                }
                t.elapsed()
            },
            || {
                use rayon::prelude::*;
                let t = Instant::now();
                iota_z
                    .par_chunks_mut(order * len)
                    .zip(z_state.par_chunks_mut(order))
                    .enumerate()
                    .for_each(|(ch, (out, st))| {
                        let d = ch / n_c;
                        let s = view[plan.drivers[d].index()];
                        if first {
                            // ζ(0) = 0: the filters start at rest with the record.
                            for i in 0..order {
                                out[i * len] = 0.0;
                            }
                            chains[ch % n_c].run(st, s[0], &s[1..], &mut out[1..], len);
                        } else {
                            chains[ch % n_c].run(st, s_prev[d], s, out, len);
                        }
                    });
                for (d, sp) in s_prev.iter_mut().enumerate() {
                    *sp = view[plan.drivers[d].index()][len - 1];
                }
                t.elapsed()
            },
        );
        self.times.evaluate += t_eval;
        self.times.filter += t_filter;
        if self.non_finite.is_none() {
            // A finite sum means every value is finite: one pass, no branch per sample.
            self.non_finite = self.wbuf[..n_g * len]
                .chunks_exact(len)
                .enumerate()
                .find(|(_, c)| !c.iter().sum::<f64>().is_finite())
                .and_then(|(r, c)| {
                    let i = c.iter().position(|v| !v.is_finite())?;
                    Some((r, p0 + i, c[i]))
                });
        }

        let t = Instant::now();
        // Snapshot at a block boundary (the first sample of this piece).
        if let Some(b) = self.bounds.iter().position(|&b| b == p0) {
            for k in 0..n_w {
                self.qrow[k] = self.wbuf[k * len];
            }
            for (k, body) in plan.vhat_bodies.iter().enumerate() {
                let x = view[self.plan_position(*body)];
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
                let ii = self.iota[i * len];
                for k in 0..n_q {
                    snap[i * n_q + k] = ii * self.qrow[k];
                }
            }
        }
        // Sums over the half-open block range; the last sample only enters the snapshot.
        let block = self.bounds.iter().rposition(|&b| b <= p0).unwrap_or(0);
        if block < self.sums.len() {
            // Position of each sample in its block, for the hat contributions.
            let off = (p0 - self.bounds[block]) as f64;
            self.wbuf_t.resize(n_w * len, 0.0);
            for (dst, src) in self
                .wbuf_t
                .chunks_exact_mut(len)
                .zip(self.wbuf.chunks_exact(len))
            {
                for (k, (d, s)) in dst.iter_mut().zip(src).enumerate() {
                    *d = (off + k as f64) * s;
                }
            }
            let half = n_i / 2;
            let iota = &self.iota;
            let wt = MatRef::from_column_major_slice(&self.wbuf[..], len, n_w);
            let wt_t = MatRef::from_column_major_slice(&self.wbuf_t[..], len, n_w);
            let (s_top, s_bot) = self.sums[block].split_at_mut(half * n_w);
            let (t_top, t_bot) = self.tsums[block].split_at_mut(half * n_w);
            // Fixed halves so the result does not depend on the number of threads.
            let run = |rows: std::ops::Range<usize>, s: &mut [f64], t: &mut [f64]| {
                let nr = rows.len();
                let a =
                    MatRef::from_row_major_slice(&iota[rows.start * len..rows.end * len], nr, len);
                let dst = MatMut::from_row_major_slice_mut(s, nr, n_w);
                faer::linalg::matmul::matmul(dst, Accum::Add, a, wt, 1.0, Par::Seq);
                let dst = MatMut::from_row_major_slice_mut(t, nr, n_w);
                faer::linalg::matmul::matmul(dst, Accum::Add, a, wt_t, 1.0, Par::Seq);
            };
            rayon::join(
                || run(0..half, s_top, t_top),
                || run(half..n_i, s_bot, t_bot),
            );
        }
        // Keep the most recent positions for end-point velocity estimates.
        for (k, body) in plan.vhat_bodies.iter().enumerate() {
            let x = view[self.plan_position(*body)];
            let tail = &mut self.tails[k];
            let take = x.len().min(VHAT_WINDOW - 1);
            let keep = (VHAT_WINDOW - 1 - take).min(tail.len());
            tail.drain(..tail.len() - keep);
            tail.extend_from_slice(&x[x.len() - take..]);
        }
        self.times.accumulate += t.elapsed();
        self.pos += len;
    }

    fn plan_position(&self, b: dynid_ir::ir::BodyId) -> usize {
        2 * b.index()
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
            },
            self.times,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
