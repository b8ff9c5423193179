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

/// A level source whose unmeasured velocity columns are filled with estimates from the
/// measured positions.
pub struct EstimatedVelocity<'a> {
    inner: &'a dyn LevelSource,
    /// `(velocity slot, position slot, differentiator)`.
    targets: Vec<(usize, usize, Differentiator)>,
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
        inner.stream(chunk, &mut |_, len| n += len)?;
        let seg = Welch::segment_for(n);
        let mut welch: Vec<Welch> = targets.iter().map(|_| Welch::new(seg)).collect();
        inner.stream(chunk, &mut |cols, len| {
            for (w, &(_, p)) in welch.iter_mut().zip(targets) {
                w.push(&cols[p][..len]);
            }
        })?;
        let max_half = (n.saturating_sub(1) / 2).max(2);
        let targets = targets
            .iter()
            .zip(&welch)
            .map(|(&(v, p), w)| {
                let wc = w.cutoff().unwrap_or(MAX_CUTOFF);
                (v, p, Differentiator::new(wc, max_half))
            })
            .collect();
        Ok(EstimatedVelocity { inner, targets })
    }

    /// `(velocity slot, cutoff in rad/s, half-width)` per estimated velocity.
    pub fn designs(&self) -> Vec<(usize, f64, usize)> {
        let ts = self.inner.ts();
        self.targets
            .iter()
            .map(|(v, _, d)| (*v, d.cutoff / ts, d.half))
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
        // Delay line: `buf[s]` holds samples `base ..` of slot `s`; samples before `emitted`
        // have been passed on, and `2H` of them are kept as the past of the window.
        let mut buf: Vec<Vec<f64>> = Vec::new();
        let mut vel: Vec<Vec<f64>> = vec![Vec::new(); self.targets.len()];
        let mut scratch = vec![0.0; 2 * hmax + 1];
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
            for (k, (_, p, d)) in self.targets.iter().enumerate() {
                let x = &buf[*p];
                let v = &mut vel[k];
                v.clear();
                for i in from..to {
                    // `x[0]` is the record start while `base = 0`; later the buffer keeps
                    // 2H past samples, and during the stream H future ones.
                    v.push(estimate_at(d, x, i, &mut scratch) / ts);
                }
            }
            {
                let mut cols: Vec<&[f64]> = buf
                    .iter()
                    .zip(present)
                    .map(|(c, &ok)| if ok { &c[from..to] } else { &[][..] })
                    .collect();
                for (k, (vs, _, _)) in self.targets.iter().enumerate() {
                    cols[*vs] = &vel[k];
                }
                sink(&cols, len);
            }
            *emitted = upto;
            // Keep 2H past samples for the next windows.
            let keep_from = emitted.saturating_sub(2 * hmax).max(*base);
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
            // Samples with H samples of future in hand can go.
            let upto = received.saturating_sub(hmax);
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
