//! Velocity estimates from measured positions, for terms nonlinear in a velocity that is not
//! measured (Coulomb friction `r·sign(v)`, quadratic damping `c·v|v|`).
//!
//! A term linear in a velocity moves onto the filters and never needs one; a nonlinear term
//! has to be evaluated sample by sample, so it uses an estimate `v̂` of the velocity:
//!
//! ```text
//! v̂[n] = (1/Tₛ) Σ_{j=−H…H} w_j x[n+j],     w_j = g'(j) / Σᵢ i g'(i),
//! g(t) = sin(ω_c t)/(π t) · blackman(t / (H+1)),
//! ```
//!
//! the derivative of a windowed-sinc low-pass with cutoff `ω_c` (rad/sample). It is
//! zero-phase (`w` is antisymmetric), so the zero crossings of `v̂` — all that `sign(v)`
//! sees — are not delayed, and it is exact for polynomials of degree 2 (the normalisation
//! fixes the slope of a ramp). The Blackman window makes the transition band `≈ 11π/(2H+1)`
//! wide; `H = ⌈5.5π/ω_c⌉` puts it from about `ω_c/2` to `3ω_c/2`.
//!
//! **Bandwidth from the data.** A first pass estimates the position spectrum (Welch: Hann
//! segments, half overlap, linear trend removed). Its floor — white measurement noise or
//! quantisation — is the median over the top quarter of the band; `ω_c` is the first
//! frequency above the spectral peak where the spectrum falls below twice the floor, i.e.
//! where the signal meets the noise. A wider band would add noise amplified by `ω²`, a
//! narrower one would cut the signal. `ω_c` is kept between twice the peak frequency and
//! `π/4` (clean data has no floor; a quarter of Nyquist keeps the window at ≥ 22 samples).
//!
//! **Record ends.** Within `H` samples of an end the window is shortened symmetrically to
//! the `d` samples available on the near side (half-width `d`, cutoff raised to
//! `max(ω_c, 5.5π/d)` so the window still holds the transition band); the very first and
//! last samples use the three-point one-sided difference. These samples are noisier, not
//! delayed.
//!
//! **Streaming.** [`EstimatedVelocity`] wraps a [`LevelSource`]: it holds back `H` samples
//! of every column (a delay line of `2H` past samples plus one chunk), fills the velocity
//! columns with `v̂` and passes chunks on; memory does not grow with the record.
//!
//! **Reversals.** Where a body turns back, Coulomb friction flips with the direction and its
//! acceleration jumps: the velocity has a kink at its zero, which the smoothing rounds, so
//! `v̂` crosses zero late — by a quarter of a sample at the overshoots of
//! `ServoAxis::planned`, always late, and `sign(v̂)` is wrong on one sample of every
//! reversal. Around each zero crossing of `v̂` the positions `x[j−7 … j+8]` are fitted by a
//! motion that stops at `t0` and turns back with an acceleration that may jump there
//! (`x ≈ p0 + p1·τ²·[τ<0] + p2·τ²·[τ≥0] + p3·τ³`, `τ = k − t0`, least squares for `t0`
//! within 1.5 samples of `v̂`'s crossing), and where that fit is significantly better than
//! with the crossing of `v̂` (a likelihood-ratio test), the samples on the wrong side get
//! the fitted velocity. This is done on levels that rest for at least
//! [`crate::ident::rests::MIN_REST_SHARE`] of their samples — planned moves with dwells,
//! whose reversals are the overshoots at the ends of the moves (docs/method.md §7).
//!
//! **Bias.** With noise `e` of standard deviation `σ_e` on `v̂`, `sign(v̂)` averages to
//! `erf(v / (√2 σ_e))` near a reversal, a steep viscous-like force, so a Coulomb coefficient
//! comes out low by an amount that grows with the position noise; the figures are in the
//! `velocity_estimate` tests of `tests/recovery.rs`.

use crate::data::{DataError, LevelSource};
use serde::Serialize;
use std::f64::consts::PI;

/// How one unmeasured velocity was estimated, per level.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct VelocityEstimate {
    /// The estimated signal (`m.v`).
    pub signal: String,
    /// The measured position it is estimated from (`m.x`).
    pub from: String,
    pub method: String,
    /// Cutoff `ω_c` per level, rad/s.
    pub cutoff: Vec<f64>,
    /// Window half-width `H` per level, samples.
    pub half_width: Vec<usize>,
}

/// Name of the method, for reports.
pub const METHOD: &str = "zero-phase windowed-sinc differentiator (Blackman), cutoff where the \
                          position spectrum meets its noise floor";

/// Largest cutoff, rad/sample.
const MAX_CUTOFF: f64 = PI / 4.0;

/// A designed zero-phase differentiator.
#[derive(Clone, Debug, PartialEq)]
pub struct Differentiator {
    /// Cutoff, rad/sample.
    pub cutoff: f64,
    /// Half-width `H`.
    pub half: usize,
    /// `w_j` for `j = −H … H` (index `j + H`).
    pub weights: Vec<f64>,
}

/// Weights of the windowed-sinc differentiator of half-width `half` and cutoff `wc`
/// (rad/sample) into `out` (length `2·half + 1`), normalised to the exact slope of a ramp.
fn design_into(wc: f64, half: usize, out: &mut [f64]) {
    let hw = (half + 1) as f64;
    let a = PI / hw;
    let mut norm = 0.0;
    for j in 0..=half {
        let t = j as f64;
        let (s, ds) = if j == 0 {
            (wc / PI, 0.0)
        } else {
            (
                (wc * t).sin() / (PI * t),
                (wc * t * (wc * t).cos() - (wc * t).sin()) / (PI * t * t),
            )
        };
        let win = 0.42 + 0.5 * (a * t).cos() + 0.08 * (2.0 * a * t).cos();
        let dwin = -0.5 * a * (a * t).sin() - 0.16 * a * (2.0 * a * t).sin();
        let g1 = ds * win + s * dwin;
        out[half + j] = g1;
        out[half - j] = -g1;
        norm += 2.0 * t * g1;
    }
    for w in out.iter_mut() {
        *w /= norm;
    }
}

impl Differentiator {
    /// Design for cutoff `wc` (rad/sample); the half-width follows from the cutoff and is
    /// capped at `max_half`.
    pub fn new(wc: f64, max_half: usize) -> Differentiator {
        let half = ((5.5 * PI / wc).ceil() as usize).clamp(2, max_half.max(2));
        let mut weights = vec![0.0; 2 * half + 1];
        design_into(wc, half, &mut weights);
        Differentiator {
            cutoff: wc,
            half,
            weights,
        }
    }

    /// Gain of the estimate at frequency `w` (rad/sample) relative to the exact derivative.
    pub fn relative_gain(&self, w: f64) -> f64 {
        // Σ w_j e^{iωj} = 2i Σ_{j>0} w_j sin(ωj); the derivative has gain ω.
        let h = self.half;
        let g: f64 = (1..=h)
            .map(|j| 2.0 * self.weights[h + j] * (w * j as f64).sin())
            .sum();
        g / w
    }
}

/// Velocity (per sample) at sample `i` of `x`, where a window that would reach past either
/// end of `x` is shortened as at a record end. `scratch` holds `2H + 1` values.
fn estimate_at(d: &Differentiator, x: &[f64], i: usize, scratch: &mut [f64]) -> f64 {
    let n = x.len();
    let room = i.min(n - 1 - i);
    if room >= d.half {
        let h = d.half;
        return x[i - h..=i + h]
            .iter()
            .zip(&d.weights)
            .map(|(x, w)| x * w)
            .sum();
    }
    match room {
        0 if n < 3 => {
            if n < 2 {
                0.0
            } else {
                x[1] - x[0]
            }
        }
        0 if i == 0 => (-3.0 * x[0] + 4.0 * x[1] - x[2]) / 2.0,
        0 => (3.0 * x[n - 1] - 4.0 * x[n - 2] + x[n - 3]) / 2.0,
        1 => (x[i + 1] - x[i - 1]) / 2.0,
        r => {
            let wc = d.cutoff.max(5.5 * PI / r as f64).min(0.9 * PI);
            let w = &mut scratch[..2 * r + 1];
            design_into(wc, r, w);
            x[i - r..=i + r]
                .iter()
                .zip(w.iter())
                .map(|(x, w)| x * w)
                .sum()
        }
    }
}

/// Half-width, in samples, of the window of the reversal fit ([`reversal_fit`]).
const REVERSAL_HALF: usize = 8;

/// The crossing of the fit replaces the estimate's own only where the fit with the
/// estimate's crossing leaves a residual larger by this many residual variances (a
/// likelihood-ratio test of one parameter at about 95 %; on `ServoAxis::planned` the
/// reversals in motion give 10–19).
const REVERSAL_TEST: f64 = 4.0;

/// How far, in samples, the fitted crossing may lie from the estimate's own.
const REVERSAL_SPAN: f64 = 1.5;

/// The positions `x[j+1−W ..= j+W]` (`W` = [`REVERSAL_HALF`]) around a zero crossing of
/// the estimate at `j + q` (`0 ≤ q < 1`), fitted by a motion that stops at `j + t0` and
/// turns back with an acceleration that jumps there (Coulomb friction flips with the
/// direction): `x ≈ p0 + p1·τ²·[τ<0] + p2·τ²·[τ≥0] + p3·τ³`, `τ = k − j − t0`, least
/// squares (QR) for each `t0` on a grid within [`REVERSAL_SPAN`] of `q`, refined tenfold
/// about the best. Everything is relative to `j`, so the result does not depend on where
/// `x` starts (the stream's chunking). Returns `t0` and `p`, or `None` where the window
/// does not fit in `x`, the positions do not prefer `t0` to `q` significantly
/// ([`REVERSAL_TEST`]), or the fit is no reversal (`p1`, `p2` of opposite signs: the
/// velocity touches zero without turning).
fn reversal_fit(x: &[f64], j: usize, q: f64) -> Option<(f64, [f64; 4])> {
    use nalgebra::{SMatrix, SVector};
    const N: usize = 2 * REVERSAL_HALF;
    if j + 1 < REVERSAL_HALF || j + REVERSAL_HALF >= x.len() {
        return None;
    }
    let k0 = j + 1 - REVERSAL_HALF;
    let b = SVector::<f64, N>::from_fn(|r, _| x[k0 + r] - x[j]);
    let fit = |t0: f64| -> Option<(f64, [f64; 4])> {
        let a = SMatrix::<f64, N, 4>::from_fn(|r, col| {
            let tau = r as f64 - (REVERSAL_HALF - 1) as f64 - t0;
            match col {
                0 => 1.0,
                1 if tau < 0.0 => tau * tau,
                2 if tau >= 0.0 => tau * tau,
                3 => tau * tau * tau,
                _ => 0.0,
            }
        });
        let qr = a.qr();
        let p = qr.r().solve_upper_triangular(&(qr.q().transpose() * b))?;
        let rss = (b - a * p).norm_squared();
        Some((rss, [p[0], p[1], p[2], p[3]]))
    };
    let mut best: Option<(f64, f64, [f64; 4])> = None;
    let search = |from: f64, step: f64, steps: usize, best: &mut Option<(f64, f64, [f64; 4])>| {
        for i in 0..=steps {
            let t0 = from + step * i as f64;
            if let Some((rss, p)) = fit(t0) {
                if best.is_none_or(|b| rss < b.0) {
                    *best = Some((rss, t0, p));
                }
            }
        }
    };
    search(
        q - REVERSAL_SPAN,
        0.1,
        (20.0 * REVERSAL_SPAN).round() as usize,
        &mut best,
    );
    let coarse = best?.1;
    search(coarse - 0.1, 0.01, 20, &mut best);
    let (rss, t0, p) = best?;
    // The crossing moves only where the positions say so: the fit with the crossing where
    // the estimate puts it must be worse by more than REVERSAL_TEST residual variances.
    let at_c = fit(q)?.0;
    let var = rss / (N - 4) as f64;
    let significant = at_c - rss > REVERSAL_TEST * var;
    (p[1] * p[2] > 0.0 && significant).then_some((t0, p))
}

/// Velocity (per sample) at `dk` samples after `j` of the motion [`reversal_fit`] found.
fn reversal_velocity(t0: f64, p: &[f64; 4], dk: f64) -> f64 {
    let tau = dk - t0;
    let quad = if tau < 0.0 { p[1] } else { p[2] };
    2.0 * quad * tau + 3.0 * p[3] * tau * tau
}

/// Where the estimate `v` (per sample, `v[i]` for index `lo + i` of `x`) changes sign,
/// the samples it puts on the wrong side of the crossing [`reversal_fit`] finds get the
/// fitted velocity instead, for the indices `from .. to` of `x` (`out[i]` for `from + i`).
/// A zero-phase smoothing differentiator sees the jump of the acceleration at a reversal
/// (Coulomb friction flips) as a kink and crosses zero late, by about a quarter of a sample
/// on `ServoAxis::planned`: always late, so `sign(v̂)` is wrong on one side of every
/// reversal (see `tests/servo_planned.rs`, `planned_mass_bias_came_from_late_reversals`).
fn correct_reversals(x: &[f64], lo: usize, v: &[f64], from: usize, out: &mut [f64]) {
    for i in 0..v.len().saturating_sub(1) {
        let (a, b) = (v[i], v[i + 1]);
        let crosses = a * b < 0.0;
        if !crosses {
            continue;
        }
        let j = lo + i;
        let q = a / (a - b);
        let Some((t0, p)) = reversal_fit(x, j, q) else {
            continue;
        };
        if (-p[1]).signum() != a.signum() {
            continue; // (a turn the other way round than the estimate's)
        }
        for k in j.saturating_sub(1)..=j + 2 {
            let dk = k as f64 - j as f64;
            if !(from..from + out.len()).contains(&k) || (dk - q).abs() > REVERSAL_SPAN {
                continue;
            }
            let vf = reversal_velocity(t0, &p, dk);
            if vf.signum() != v[k - lo].signum() {
                out[k - from] = vf;
            }
        }
    }
}

/// Welch estimate of the spectrum of one streamed signal (arbitrary scale: only ratios are
/// used).
pub(crate) struct Welch {
    seg: usize,
    buf: Vec<f64>,
    window: Vec<f64>,
    power: crate::fft::SegmentPower,
    psd: Vec<f64>,
    count: usize,
}

impl Welch {
    pub fn new(seg: usize) -> Welch {
        let window = (0..seg)
            .map(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / seg as f64).cos())
            .collect();
        Welch {
            seg,
            buf: Vec::with_capacity(seg),
            window,
            power: crate::fft::SegmentPower::new(seg),
            psd: vec![0.0; seg / 2 + 1],
            count: 0,
        }
    }

    /// Segment length for a record of `n` samples: a power of two, at most `n/8` (so that
    /// about fifteen half-overlapping segments are averaged) and between 64 and 4096.
    pub fn segment_for(n: usize) -> usize {
        let mut s = 64;
        while s * 2 <= 4096 && s * 2 <= n / 8 {
            s *= 2;
        }
        s
    }

    pub fn push(&mut self, x: &[f64]) {
        for &v in x {
            self.buf.push(v);
            if self.buf.len() == self.seg {
                self.segment();
                let half = self.seg / 2;
                self.buf.drain(..half);
            }
        }
    }

    fn segment(&mut self) {
        let n = self.seg as f64;
        // Least-squares line through the segment, removed (positions may drift).
        let tm = (n - 1.0) / 2.0;
        let mean = self.buf.iter().sum::<f64>() / n;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (k, &v) in self.buf.iter().enumerate() {
            let t = k as f64 - tm;
            sxy += t * (v - mean);
            sxx += t * t;
        }
        let slope = sxy / sxx;
        let input = self.power.input_mut();
        for (k, v) in input.iter_mut().enumerate() {
            let t = k as f64 - tm;
            *v = (self.buf[k] - mean - slope * t) * self.window[k];
        }
        self.power.add_power(&mut self.psd, |_| 1.0);
        self.count += 1;
    }

    /// Cutoff (rad/sample) where the spectrum meets its noise floor, see the module docs.
    /// `None` when the record held no complete segment.
    pub fn cutoff(&self) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let nb = self.psd.len();
        let bin = 2.0 * PI / self.seg as f64;
        // Five-bin running mean against the scatter of single bins.
        let smooth: Vec<f64> = (0..nb)
            .map(|k| {
                let (a, b) = (k.saturating_sub(2), (k + 2).min(nb - 1));
                self.psd[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
            })
            .collect();
        let mut top: Vec<f64> = self.psd[(3 * nb) / 4..].to_vec();
        top.sort_by(f64::total_cmp);
        let floor = top[top.len() / 2];
        let peak = (1..nb)
            .max_by(|&a, &b| smooth[a].total_cmp(&smooth[b]))
            .unwrap_or(1);
        let cross = (peak..nb)
            .find(|&k| smooth[k] < 2.0 * floor)
            .unwrap_or(nb - 1);
        let lo = 2.0 * peak as f64 * bin;
        Some((cross as f64 * bin).max(lo).min(MAX_CUTOFF))
    }
}

/// The share of a streamed position's samples at rest, by the criterion of
/// [`crate::ident::rests`] (speed from central differences at most
/// [`crate::ident::rests::REST_FRACTION`] of the RMS speed, in runs of at least
/// [`crate::ident::rests::MIN_REST`]): one pass for the RMS speed ([`RestShare::threshold`]),
/// one for the runs.
#[derive(Default)]
struct RestShare {
    /// The last two positions (oldest first).
    prev: [f64; 2],
    seen: usize,
    sum2: f64,
    run: usize,
    at_rest: usize,
}

impl RestShare {
    /// Central differences (per sample) of `x`, continuing the stream; with `runs`
    /// (`(threshold, shortest run)`) the runs at rest are counted, otherwise the squares
    /// summed.
    fn push(&mut self, x: &[f64], runs: Option<(f64, usize)>) {
        for &x in x {
            if self.seen >= 2 {
                let s = 0.5 * (x - self.prev[0]).abs();
                match runs {
                    None => self.sum2 += s * s,
                    Some((t, _)) if s <= t => self.run += 1,
                    Some((_, min)) => self.close(min),
                }
            }
            self.prev = [self.prev[1], x];
            self.seen += 1;
        }
    }

    fn close(&mut self, min: usize) {
        if self.run >= min {
            self.at_rest += self.run;
        }
        self.run = 0;
    }

    /// The speed threshold of a rest, from the first pass.
    fn threshold(&self) -> f64 {
        let n = self.seen.saturating_sub(2).max(1) as f64;
        crate::ident::rests::REST_FRACTION * (self.sum2 / n).sqrt()
    }

    /// Share of the `n` samples at rest, after the second pass.
    fn share(&mut self, n: usize, min: usize) -> f64 {
        self.close(min);
        self.at_rest as f64 / n.max(1) as f64
    }
}

/// A level source whose unmeasured velocity columns are filled with estimates from the
/// measured positions.
pub struct EstimatedVelocity<'a> {
    inner: &'a dyn LevelSource,
    /// `(velocity slot, position slot, differentiator, reversals fitted)`.
    targets: Vec<(usize, usize, Differentiator, bool)>,
}

impl<'a> EstimatedVelocity<'a> {
    /// Design one differentiator per `(velocity slot, position slot)` from a first pass
    /// over `inner` (the position spectra).
    pub fn design(
        inner: &'a dyn LevelSource,
        targets: &[(usize, usize)],
        chunk: usize,
    ) -> Result<Self, DataError> {
        let mut n = 0usize;
        let mut speed: Vec<RestShare> = targets.iter().map(|_| RestShare::default()).collect();
        inner.stream(chunk, &mut |cols, len| {
            for (s, &(_, p)) in speed.iter_mut().zip(targets) {
                s.push(&cols[p][..len], None);
            }
            n += len;
        })?;
        let ts = inner.ts();
        let min_rest = ((crate::ident::rests::MIN_REST / ts).ceil() as usize).max(2);
        let thresholds: Vec<f64> = speed.iter().map(RestShare::threshold).collect();
        let mut rests: Vec<RestShare> = targets.iter().map(|_| RestShare::default()).collect();
        let seg = Welch::segment_for(n);
        let mut welch: Vec<Welch> = targets.iter().map(|_| Welch::new(seg)).collect();
        inner.stream(chunk, &mut |cols, len| {
            for (((w, r), &t), &(_, p)) in welch
                .iter_mut()
                .zip(&mut rests)
                .zip(&thresholds)
                .zip(targets)
            {
                w.push(&cols[p][..len]);
                r.push(&cols[p][..len], Some((t, min_rest)));
            }
        })?;
        let max_half = (n.saturating_sub(1) / 2).max(2);
        let targets = targets
            .iter()
            .zip(&welch)
            .zip(&mut rests)
            .map(|((&(v, p), w), r)| {
                let wc = w.cutoff().unwrap_or(MAX_CUTOFF);
                let fit = r.share(n, min_rest) >= crate::ident::rests::MIN_REST_SHARE;
                (v, p, Differentiator::new(wc, max_half), fit)
            })
            .collect();
        Ok(EstimatedVelocity { inner, targets })
    }

    /// `(velocity slot, cutoff in rad/s, half-width)` per estimated velocity.
    pub fn designs(&self) -> Vec<(usize, f64, usize)> {
        let ts = self.inner.ts();
        self.targets
            .iter()
            .map(|(v, _, d, _)| (*v, d.cutoff / ts, d.half))
            .collect()
    }
}

impl LevelSource for EstimatedVelocity<'_> {
    fn origin(&self) -> String {
        self.inner.origin()
    }
    fn ts(&self) -> f64 {
        self.inner.ts()
    }
    fn locate(&self, k: usize) -> String {
        self.inner.locate(k)
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        let ts = self.inner.ts();
        let hmax = self.targets.iter().map(|t| t.2.half).max().unwrap_or(0);
        let margin = if self.targets.iter().any(|t| t.3) {
            REVERSAL_HALF + 2
        } else {
            0
        };
        // (`margin`: samples held back beyond the window, and kept beyond its past, for the
        // reversal fits of [`correct_reversals`]: two samples of the estimate either side of
        // a chunk, and the fit's window about them.)
        // Delay line: `buf[s]` holds samples `base ..` of slot `s`; samples before `emitted`
        // have been passed on, and `2H` of them are kept as the past of the window.
        let mut buf: Vec<Vec<f64>> = Vec::new();
        let mut vel: Vec<Vec<f64>> = vec![Vec::new(); self.targets.len()];
        let mut scratch = vec![0.0; 2 * hmax + 1];
        let mut around: Vec<f64> = Vec::new();
        let mut base = 0usize;
        let mut emitted = 0usize;
        let mut received = 0usize;
        let mut present: Vec<bool> = Vec::new();
        let mut emit = |buf: &mut Vec<Vec<f64>>,
                        present: &[bool],
                        base: &mut usize,
                        emitted: &mut usize,
                        upto: usize,
                        sink: &mut dyn FnMut(&[&[f64]], usize)| {
            let len = upto - *emitted;
            if len == 0 {
                return;
            }
            let (from, to) = (*emitted - *base, upto - *base);
            for (k, (_, p, d, fit)) in self.targets.iter().enumerate() {
                let x = &buf[*p];
                let v = &mut vel[k];
                // The estimate (per sample) from two samples before `from` to two after
                // `to`. `x[0]` is the record start while `base = 0`; later the buffer keeps
                // 2H + margin past samples, and during the stream H + margin future ones.
                let (lo, hi) = (from.saturating_sub(2), (to + 2).min(x.len()));
                around.clear();
                around.extend((lo..hi).map(|i| estimate_at(d, x, i, &mut scratch)));
                v.clear();
                v.extend_from_slice(&around[from - lo..to - lo]);
                if *fit {
                    correct_reversals(x, lo, &around, from, v);
                }
                v.iter_mut().for_each(|v| *v /= ts);
            }
            {
                let mut cols: Vec<&[f64]> = buf
                    .iter()
                    .zip(present)
                    .map(|(c, &ok)| if ok { &c[from..to] } else { &[][..] })
                    .collect();
                for (k, (vs, ..)) in self.targets.iter().enumerate() {
                    cols[*vs] = &vel[k];
                }
                sink(&cols, len);
            }
            *emitted = upto;
            // Keep 2H + margin past samples for the next windows.
            let keep_from = emitted.saturating_sub(2 * hmax + margin).max(*base);
            let drop = keep_from - *base;
            for (c, &ok) in buf.iter_mut().zip(present) {
                if ok {
                    c.drain(..drop);
                }
            }
            *base = keep_from;
        };
        self.inner.stream(max_len, &mut |cols, len| {
            if buf.is_empty() {
                buf = vec![Vec::new(); cols.len()];
                present = cols.iter().map(|c| !c.is_empty()).collect();
            }
            for ((b, c), &ok) in buf.iter_mut().zip(cols).zip(&present) {
                if ok {
                    b.extend_from_slice(&c[..len]);
                }
            }
            received += len;
            // Samples with H + margin samples of future in hand can go.
            let upto = received.saturating_sub(hmax + margin);
            if upto > emitted {
                // The window of sample i must not reach past the buffer end; estimate_at
                // treats the buffer end as a record end, so only emit complete windows.
                emit(&mut buf, &present, &mut base, &mut emitted, upto, sink);
            }
        })?;
        if received > emitted {
            emit(&mut buf, &present, &mut base, &mut emitted, received, sink);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Record;

    #[test]
    fn differentiator_is_exact_for_quadratics_and_flat_in_band() {
        let d = Differentiator::new(0.1, 10_000);
        assert_eq!(d.half, (5.5 * PI / 0.1_f64).ceil() as usize);
        let h = d.half as f64;
        let x: Vec<f64> = (0..d.weights.len())
            .map(|k| {
                let t = k as f64 - h;
                3.0 + 2.0 * t + 0.7 * t * t
            })
            .collect();
        let v: f64 = x.iter().zip(&d.weights).map(|(x, w)| x * w).sum();
        assert!((v - 2.0).abs() < 1e-9, "{v}");
        // Passband up to half the cutoff within 0.1 %, stopband beyond 1.6 cutoffs below 1 %.
        for k in 1..=50 {
            let w = 0.5 * 0.1 * k as f64 / 50.0;
            let g = d.relative_gain(w);
            assert!((g - 1.0).abs() < 1e-3, "gain {g} at {w}");
        }
        for k in 0..100 {
            let w = 0.16 + (PI - 0.16) * k as f64 / 99.0;
            let g = d.relative_gain(w) * w;
            assert!(g.abs() < 0.01 * 0.1, "stopband {g} at {w}");
        }
    }

    /// Stream a sinusoid plus noise through the wrapper in odd-sized chunks: the estimate
    /// matches the true velocity in the interior, the cutoff sits between the tone and the
    /// Nyquist frequency, and the chunking does not change a single value.
    #[test]
    fn streamed_estimate_matches_the_velocity_and_ignores_chunking() {
        use rand::{Rng, SeedableRng};
        let (n, ts, om) = (20_000usize, 0.01, 3.0);
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let x: Vec<f64> = (0..n)
            .map(|k| (om * k as f64 * ts).sin() + 1e-4 * (rng.random::<f64>() - 0.5))
            .collect();
        let rec = Record {
            names: vec!["x".into()],
            columns: vec![x],
            ts,
            t0: 0.0,
        };
        let src = Src(&rec);
        let est = EstimatedVelocity::design(&src, &[(1, 0)], 1000).unwrap();
        let (_, wc, half) = est.designs()[0];
        assert!(wc > 2.0 * om && wc < PI / ts / 4.0 + 1e-9, "cutoff {wc}");
        let collect = |chunk: usize| {
            let mut v = Vec::new();
            est.stream(chunk, &mut |cols, len| {
                assert_eq!(cols[0].len(), len);
                v.extend_from_slice(&cols[1][..len]);
            })
            .unwrap();
            v
        };
        let a = collect(997);
        let b = collect(8192);
        assert_eq!(a.len(), n);
        assert_eq!(a, b);
        let err = (half..n - half)
            .map(|k| (a[k] - om * (om * k as f64 * ts).cos()).abs())
            .fold(0.0, f64::max);
        assert!(err < 0.01 * om, "interior error {err}");
        let edge = (0..half)
            .chain(n - half..n)
            .map(|k| (a[k] - om * (om * k as f64 * ts).cos()).abs())
            .fold(0.0, f64::max);
        assert!(edge < 0.1 * om, "edge error {edge}");
    }

    /// A reversal with a jump of the acceleration (Coulomb friction flips): the plain
    /// smoothing estimate crosses zero late and has the old sign on the first sample after
    /// the true crossing; the reversal fit puts every sample on its side.
    #[test]
    fn reversal_fit_corrects_the_late_crossing_of_a_kink() {
        // Per-sample units: decelerating at 2e-3, turning back at 1.4e-3 after t0.
        let (a1, a2) = (2e-3, 1.4e-3);
        for t0 in [100.05, 100.3, 100.6, 100.9] {
            let x: Vec<f64> = (0..200)
                .map(|k| {
                    let tau = k as f64 - t0;
                    let a = if tau < 0.0 { a1 } else { a2 };
                    0.1 - 0.5 * a * tau * tau
                })
                .collect();
            let v_true = |k: usize| {
                let tau = k as f64 - t0;
                -(if tau < 0.0 { a1 } else { a2 }) * tau
            };
            let d = Differentiator::new(0.4, 100);
            let mut scratch = vec![0.0; 2 * d.half + 1];
            let plain: Vec<f64> = (0..x.len())
                .map(|i| estimate_at(&d, &x, i, &mut scratch))
                .collect();
            let crossing = |v: &[f64]| {
                let j = (60..140).find(|&j| v[j] > 0.0 && v[j + 1] <= 0.0).unwrap();
                j as f64 + v[j] / (v[j] - v[j + 1])
            };
            let late = crossing(&plain) - t0;
            assert!(
                (0.1..1.0).contains(&late),
                "t0 {t0}: plain crossing late by {late}"
            );
            let mut fitted = plain[50..150].to_vec();
            correct_reversals(&x, 0, &plain, 50, &mut fitted);
            for k in 50..150 {
                assert_eq!(
                    fitted[k - 50].signum(),
                    v_true(k).signum(),
                    "t0 {t0}: sample {k}"
                );
            }
            let wrong = (50..150)
                .filter(|&k| plain[k].signum() != v_true(k).signum())
                .count();
            assert!(wrong <= 1, "t0 {t0}: the plain estimate wrong on {wrong}");
        }
    }

    /// A level that rests a third of the time has its reversals fitted, a sinusoid not.
    #[test]
    fn reversals_are_fitted_on_levels_with_rests() {
        let (n, ts) = (20_000usize, 0.001);
        let moving = |k: usize| (3.0 * k as f64 * ts).sin();
        let resting = |k: usize| {
            if (k / 2000).is_multiple_of(3) {
                0.0
            } else {
                moving(k)
            }
        };
        for (name, f, want) in [
            ("sinusoid", &moving as &dyn Fn(usize) -> f64, false),
            ("with rests", &resting, true),
        ] {
            let rec = Record {
                names: vec!["x".into()],
                columns: vec![(0..n).map(f).collect()],
                ts,
                t0: 0.0,
            };
            let src = Src(&rec);
            let est = EstimatedVelocity::design(&src, &[(1, 0)], 1000).unwrap();
            assert_eq!(est.targets[0].3, want, "{name}");
        }
    }

    struct Src<'r>(&'r Record);
    impl LevelSource for Src<'_> {
        fn origin(&self) -> String {
            "test".into()
        }
        fn ts(&self) -> f64 {
            self.0.ts
        }
        fn stream(
            &self,
            max_len: usize,
            sink: &mut dyn FnMut(&[&[f64]], usize),
        ) -> Result<(), DataError> {
            let c = &self.0.columns[0];
            let mut s = 0;
            while s < c.len() {
                let len = max_len.max(1).min(c.len() - s); // progress even for `max_len` 0
                sink(&[&c[s..s + len], &[]], len);
                s += len;
            }
            Ok(())
        }
    }
}
