//! Displacement and velocity estimates from measured accelerations, for terms nonlinear in
//! the motion of a body measured only by its acceleration (a cubic spring `k3·s³`, Coulomb
//! friction `r·sign(v)`).
//!
//! Terms linear in such a body's motion never need these estimates: they are formed from
//! the acceleration by band-pass instruments ([`super::plan::BasisMoment::D0Acc`]). A
//! nonlinear term is evaluated sample by sample, so it reads `x̂` or `v̂`, integrals of the
//! measured acceleration `a`, computed on the whole record with one real FFT:
//!
//! ```text
//! X̂(ω) = H(ω) A(ω) / (jω)²,   V̂(ω) = H(ω) A(ω) / (jω),   H(ω) = ω⁴ / (ω⁴ + ω_h⁴)
//! ```
//!
//! **Band-limited integration** (any record). `H` is the squared magnitude of a
//! second-order Butterworth high-pass (the forward–backward filter): real, so the estimate
//! is zero-phase — the zero crossings of `v̂` that `sign(v)` sees are not delayed — and
//! `H/(jω)²` is bounded at `ω → 0`, so neither integral drifts. `x̂` and `v̂` are integrals
//! of the same high-passed acceleration: `v̂` is exactly the derivative of `x̂`. The record
//! (its mean removed) is padded with zeros by eight time constants `1/ω_h` before the
//! transform, so the transform's wrap-around does not join its two ends; within a few
//! `1/ω_h` of either end the estimate is less accurate (the acceleration before and after
//! the record is taken as zero).
//!
//! **The corner `ω_h`** is a quarter of the lowest mode, read from the data: the peak of
//! the displacement spectrum `S_a(ω)/ω⁴` (Welch over Hann segments of the acceleration),
//! searched from the lowest frequency at which the acceleration stands out of its noise
//! floor (four times the median over the top quarter of the band) up to the peak of the
//! acceleration spectrum. Below a lightly damped mode the displacement spectrum is flat
//! (the static compliance) and it peaks at the mode, so the search finds the lowest mode
//! that dominates the displacement; `H = 0.996` there and `H ≥ 0.94` from half of it up.
//! A lower corner lets through more integrated noise (its variance in `x̂` grows as `ω_h⁻³`
//! for white noise on `a`), a higher one removes displacement the springs carry. Where
//! the spectrum has no peak (a record shorter than two segments) the corner is a quarter
//! of the lowest filter corner.
//!
//! **Whole periods** (a multisine's steady state recorded over an integer number of
//! periods, `dynid simulate --signal multisine --periods N`): the record is periodic, its
//! DFT lies on the lines of `p` whole periods (every `p`-th bin), and dividing the DFT by
//! `(jω)ᵏ` with the mean dropped is exact — no padding, no end effects. The
//! bins between the lines hold only noise and are dropped, and so are the lines whose
//! power is below twenty times the mean noise power of those bins (lines below the excited
//! band hold only noise, which `1/ω²` would amplify most): the estimate is the integral of
//! the average period over the lines the acceleration carries.
//! Lines below both the lowest line a measured input excites and the band-limited corner
//! (a quarter of the lowest mode, below) are dropped too: a linear response has nothing
//! there, and what the sampled acceleration holds there is mostly folded down from above
//! the Nyquist frequency. A contact (a clearance closing) puts kinks into the acceleration
//! whose folded content, divided by `ω²` at lines of 0.025–0.2 rad/s under a band from
//! 1.26 rad/s, gave the joint's displacement an error of 14–25 times its RMS at the
//! nonlinear levels (measured once, against the simulated positions) and collapsed the fit
//! of a clearance (`tests/accel_structure.rs`, `clearance_alone_from_accelerations`).
//! A sine sweep excites every line of its period, below its band too (the restart of each
//! sweep; a 0.2–10 Hz log sweep puts 5 % of its strongest line's power on the lowest
//! line), so there the input's lowest line is the period's first, and the response's
//! displacement at those lines is quasi-static and small while the folded content is
//! not: the relative displacement of a joint with clearance and friction, integrated so,
//! was off by 0.3–16 times its RMS over the four levels of a noiseless sweep (measured
//! once against the simulated positions, not a test). So between the input's lowest line
//! and the band-limited corner a line is kept only where its power stands twenty times
//! above the folded level, read as the median line power over the top quarter of the
//! band (what lies just below the Nyquist frequency folds to just above zero; a smooth
//! response has next to nothing there and keeps its lines, a contact's kinks and a
//! friction's jumps do not): in the same check the joint's displacement error fell to
//! 0.07–1.3 times its RMS, as on the multisine's records (0.07–0.92), and its
//! identification from a noiseless sweep to within 1.8 % (r +8.8 %), against the
//! multisine's 0.6 % (r +2.3 %) in the same test (`tests/accel_structure.rs`,
//! `joint_from_a_sweep`). Where the
//! excitation itself reaches the top quarter of the band, that level is the response's
//! own and the lines below the corner are dropped unless they stand out of it: the
//! displacement there is then missing, as with the band-limited integration.
//! Periodicity is read from the data: the largest divisor `p` of the record length (at
//! least 2, with periods of at least 16 samples) for which the bins on that grid hold at
//! least 99 % of the acceleration's energy (white noise puts only `1/p` of its energy
//! there; 5 % noise leaves over 99.7 % on the grid).
//!
//! **What accelerations cannot see.** The mean of `x̂` and `v̂` is zero by construction: a
//! static offset of position (a deflection under gravity, a preload) is invisible in an
//! acceleration. A nonlinearity about a static deflection needs that deflection given in
//! the model (`s - x0` with `x0` known); one about the dynamic zero is identified as is.
//!
//! **Relative motion.** An element between two bodies reads the difference of their
//! estimates; the integration is linear, so that is the integral of the difference of
//! their accelerations.
//!
//! **Memory.** The estimates are held for the whole record (one `f64` per sample and
//! estimated signal): the integration is not causal, and a zero-phase estimate needs the
//! whole record before its first sample.
//!
//! **Bias.** Noise on `a` reaches `x̂` concentrated just above `ω_h` (integrated twice), and
//! a nonlinear column of a noisy signal is biased (`E{(x+e)³} ≠ E{x³}`); displacement below
//! `ω_h` is missing. The figures, against the same records measured by positions, are in
//! `tests/accel_nonlinear.rs`.

use crate::data::{DataError, LevelSource};
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

/// Name of the methods, for reports.
pub const METHOD_BAND: &str =
    "zero-phase band-limited integration (FFT, high-pass H = w^4/(w^4+wh^4), wh a quarter \
     of the lowest mode of the displacement spectrum)";
pub const METHOD_PERIODIC: &str =
    "exact frequency-domain integration over whole periods (DFT / (jw)^k on the lines of the \
     period from the corner up: the lowest excited input line or a quarter of the lowest mode, \
     below the latter only lines 20x above what folds down from above Nyquist; mean dropped)";

/// Energy fraction on the grid of `p` periods above which a record counts as periodic.
const PERIODIC_FRACTION: f64 = 0.99;
/// Fewest samples per period for the periodic test.
const MIN_PERIOD: usize = 16;
/// A periodic record's line is kept where its power is this many times the noise's.
const LINE_OVER_NOISE: f64 = 20.0;
/// Zero padding, in time constants `1/ω_h`.
const PAD_TIME_CONSTANTS: f64 = 8.0;

/// How the estimates of one level were made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Integration {
    /// Band-limited, with the high-pass corner `ω_h` in rad/s.
    Band { corner: f64 },
    /// Exact over `periods` whole periods, on the lines at and above `floor` rad/s: the
    /// band-limited corner `corner` (a quarter of the lowest mode) or, where lower, the
    /// lowest line a measured input excites. Below both the sampled acceleration holds
    /// little but what the sampling folds down from above the Nyquist frequency (the kinks
    /// of a contact) and noise, which `1/ω²` would amplify most; between `floor` and
    /// `corner` a line is kept only where it stands out of that folded content.
    Periodic {
        periods: usize,
        floor: f64,
        corner: f64,
    },
}

/// The slots of the model's measured inputs (their lowest excited line bounds the lines a
/// periodic integration keeps).
pub fn measured_inputs(ir: &dynid_ir::ir::ModelIr) -> Vec<usize> {
    ir.signals
        .iter()
        .enumerate()
        .filter(|(_, s)| s.measured && matches!(s.kind, dynid_ir::ir::SignalKind::Input(_)))
        .map(|(i, _)| i)
        .collect()
}

/// One signal to estimate: its slot, the slot of the acceleration it integrates, and the
/// order of integration (1: velocity, 2: position).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    pub slot: usize,
    pub accel: usize,
    pub order: u8,
}

/// A level source whose position/velocity columns of acceleration-only bodies are filled
/// with integrals of the accelerations.
pub struct IntegratedMotion<'a> {
    inner: &'a dyn LevelSource,
    slots: Vec<usize>,
    values: Vec<Vec<f64>>,
    how: Integration,
    /// Per target: the lowest line its estimate kept (rad/s), over whole periods.
    lowest: Vec<Option<f64>>,
}

/// The largest number of whole periods the record `a` holds (see the module docs), from its
/// spectrum `spec` (`|A_k|²`, `k = 0 … n/2`).
fn whole_periods(n: usize, spec: &[f64]) -> Option<usize> {
    let total: f64 = spec.iter().skip(1).sum();
    if total <= 0.0 || !total.is_finite() {
        return None;
    }
    (2..=n / MIN_PERIOD)
        .rev()
        .filter(|p| n.is_multiple_of(*p))
        .find(|&p| {
            // The grid of `p` periods: bins p, 2p, ….
            let grid: f64 = spec.iter().skip(p).step_by(p).sum();
            grid >= PERIODIC_FRACTION * total
        })
}

/// The high-pass corner (rad/s) for the acceleration `a` (see the module docs), `None`
/// where the record is too short for its spectrum.
fn corner_from_spectrum(a: &[f64], ts: f64) -> Option<f64> {
    let n = a.len();
    let seg = super::velocity::Welch::segment_for(n);
    if n < 2 * seg {
        return None;
    }
    let mut power = crate::fft::SegmentPower::new(seg);
    let mut psd = vec![0.0; seg / 2 + 1];
    let window: Vec<f64> = (0..seg)
        .map(|k| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / seg as f64).cos())
        .collect();
    let mut start = 0;
    while start + seg <= n {
        let x = &a[start..start + seg];
        let mean = x.iter().sum::<f64>() / seg as f64;
        for ((i, v), w) in power.input_mut().iter_mut().zip(x).zip(&window) {
            *i = (v - mean) * w;
        }
        power.add_power(&mut psd, |_| 1.0);
        start += seg / 2;
    }
    let nb = psd.len();
    let mut top: Vec<f64> = psd[(3 * nb) / 4..].to_vec();
    top.sort_by(f64::total_cmp);
    let floor = top[top.len() / 2];
    // Bins 0 and 1 hold the window's leakage of the segment's mean: searched from bin 2.
    let peak = (2..nb).max_by(|&x, &y| psd[x].total_cmp(&psd[y]))?;
    // Down from the peak while the acceleration stands out of its noise floor.
    let mut lo = peak;
    while lo > 2 && psd[lo - 1] > 4.0 * floor {
        lo -= 1;
    }
    let bin = 2.0 * std::f64::consts::PI / (seg as f64 * ts);
    let mode = (lo..=peak).max_by(|&x, &y| {
        let d = |k: usize| psd[k] / (k as f64).powi(4);
        d(x).total_cmp(&d(y))
    })?;
    Some(mode as f64 * bin / 4.0)
}

/// The power `|X_k|²` of the DFT of `x`, `k = 0 … n/2`.
fn power_spectrum(x: &[f64]) -> Vec<f64> {
    let fwd = RealFftPlanner::<f64>::new().plan_fft_forward(x.len());
    let mut buf = x.to_vec();
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut buf, &mut spec)
        .expect("invariant: buffers made by the plan");
    spec.iter().map(|c| c.norm_sqr()).collect()
}

/// The mean of `power` (bin by bin, `k = 0 …`) over the bins between the lines of `p`
/// whole periods (the mean's bin 0 left out): the noise power per bin.
fn between_lines(power: impl Iterator<Item = f64>, p: usize) -> f64 {
    let (sum, count) = power
        .enumerate()
        .filter(|(k, _)| *k > 0 && !k.is_multiple_of(p))
        .fold((0.0, 0usize), |(s, c), (_, v)| (s + v, c + 1));
    sum / count.max(1) as f64
}

/// The median of `power` (bin by bin, `k = 0 …`) over the lines of `p` whole periods in the
/// top quarter of the bins: the level at which content from above the Nyquist frequency
/// folds onto the lines near zero.
fn folded_level(power: impl ExactSizeIterator<Item = f64>, p: usize) -> f64 {
    let nb = power.len();
    let mut top: Vec<f64> = power
        .enumerate()
        .filter(|(k, _)| *k >= 3 * nb / 4 && *k > 0 && k.is_multiple_of(p))
        .map(|(_, v)| v)
        .collect();
    if top.is_empty() {
        return 0.0;
    }
    top.sort_by(f64::total_cmp);
    top[top.len() / 2]
}

/// The number of whole periods the record `a` holds, if it is periodic.
fn periods_of(a: &[f64]) -> Option<usize> {
    whole_periods(a.len(), &power_spectrum(a))
}

/// The frequency (rad/s) of the lowest line of `p` whole periods on which the input `u`
/// carries power: above `LINE_OVER_NOISE` times the mean power between the lines and
/// above 10⁻⁶ of the strongest line. `None` where no line does.
fn lowest_input_line(u: &[f64], p: usize, ts: f64) -> Option<f64> {
    let power = power_spectrum(u);
    let top = power.iter().skip(p).step_by(p).copied().fold(0.0, f64::max);
    let bar = (LINE_OVER_NOISE * between_lines(power.iter().copied(), p)).max(1e-6 * top);
    let k = (p..power.len()).step_by(p).find(|&k| power[k] > bar)?;
    Some(k as f64 * 2.0 * std::f64::consts::PI / (u.len() as f64 * ts))
}

/// How the accelerations `accels` of one level are integrated: exactly where all hold the
/// same whole periods, else band-limited with the lowest of their corners (`fallback`
/// where no spectrum gives one). Over whole periods the lines below that corner are kept
/// from the lowest line an input `inputs` excites up (see [`Integration::Periodic`]).
fn choose(accels: &[Vec<f64>], inputs: &[Vec<f64>], ts: f64, fallback: f64) -> Integration {
    let periods: Vec<Option<usize>> = accels.iter().map(|a| periods_of(a)).collect();
    let corner = || {
        accels
            .iter()
            .filter_map(|a| corner_from_spectrum(a, ts))
            .reduce(f64::min)
            .unwrap_or(fallback)
    };
    match periods.first() {
        Some(&Some(p)) if periods.iter().all(|q| *q == Some(p)) => {
            let corner = corner();
            Integration::Periodic {
                periods: p,
                floor: inputs
                    .iter()
                    .filter(|u| u.len() == accels[0].len())
                    .filter_map(|u| lowest_input_line(u, p, ts))
                    .fold(corner, f64::min),
                corner,
            }
        }
        _ => Integration::Band { corner: corner() },
    }
}

/// Integrate `a` (sample interval `ts`) as `how` says into the estimates `out[k]` of
/// orders `orders[k]`; the lowest line kept (rad/s) over whole periods, `None` where none
/// is or the integration is band-limited.
fn integrate(
    a: &[f64],
    ts: f64,
    how: Integration,
    orders: &[u8],
    out: &mut [Vec<f64>],
) -> Option<f64> {
    let n = a.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let len = match how {
        Integration::Periodic { .. } => n,
        Integration::Band { corner } => {
            let pad = (PAD_TIME_CONSTANTS / (corner * ts)).ceil() as usize;
            (n + pad).next_multiple_of(2)
        }
    };
    let fwd = planner.plan_fft_forward(len);
    let mean = a.iter().sum::<f64>() / n as f64;
    let mut buf = vec![0.0; len];
    for (b, v) in buf.iter_mut().zip(a) {
        *b = v - mean;
    }
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut buf, &mut spec)
        .expect("invariant: buffers made by the plan");
    // Periodic: the noise power per bin, from the bins between the lines; a line is kept
    // where it stands out of it (white noise passes 20 times its mean with probability
    // e⁻²⁰), so that lines below the band, noise only, are not amplified by 1/ω².
    let noise = match how {
        Integration::Periodic { periods, .. } => {
            LINE_OVER_NOISE * between_lines(spec.iter().map(|c| c.norm_sqr()), periods)
        }
        Integration::Band { .. } => 0.0,
    };
    // Periodic, below the band-limited corner: what folds down from above the Nyquist
    // frequency lands on the lines themselves, where the noise test cannot see it; a line
    // there is kept where it stands out of the folded level, read as the median line power
    // over the top quarter of the band (what lies just below the Nyquist frequency folds
    // to just above zero).
    let folded = match how {
        Integration::Periodic { periods, .. } => {
            LINE_OVER_NOISE * folded_level(spec.iter().map(|c| c.norm_sqr()), periods)
        }
        Integration::Band { .. } => 0.0,
    };
    let inv = planner.plan_fft_inverse(len);
    let dw = 2.0 * std::f64::consts::PI / (len as f64 * ts);
    let last = spec.len() - 1;
    let mut work = vec![Complex::new(0.0, 0.0); spec.len()];
    let mut time = vec![0.0; len];
    let mut lowest: Option<f64> = None;
    for (o, est) in orders.iter().zip(out.iter_mut()) {
        for (k, (w, s)) in work.iter_mut().zip(&spec).enumerate() {
            let om = k as f64 * dw;
            let h = match how {
                Integration::Band { corner } => {
                    let (o4, c4) = (om.powi(4), corner.powi(4));
                    o4 / (o4 + c4)
                }
                Integration::Periodic { .. } => 1.0,
            };
            // Mean dropped; the Nyquist bin of an even length dropped too (a velocity's
            // would be imaginary there, which a real inverse transform cannot hold).
            // Periodic: only the lines of the period carry the signal, every other bin is
            // noise (which 1/ω² would amplify most at the lowest bins): dropped. So are
            // the lines below the floor: there the sampled acceleration holds little but
            // what the sampling folds down from above the Nyquist frequency (a contact's
            // kinks) or the noise, and `1/ω²` amplifies it most.
            let off_grid = matches!(how, Integration::Periodic { periods, floor, corner }
                    if !k.is_multiple_of(periods)
                        || om < floor
                        || (om < corner && s.norm_sqr() <= folded))
                || s.norm_sqr() < noise;
            *w = if k == 0 || off_grid || (k == last && len.is_multiple_of(2)) {
                Complex::new(0.0, 0.0)
            } else {
                if matches!(how, Integration::Periodic { .. }) {
                    lowest = Some(lowest.map_or(om, |l: f64| l.min(om)));
                }
                let jw = Complex::new(0.0, om);
                let d = if *o == 1 { jw } else { jw * jw };
                *s * (h / len as f64) / d
            };
        }
        inv.process(&mut work, &mut time)
            .expect("invariant: buffers made by the plan");
        est.clear();
        est.extend_from_slice(&time[..n]);
    }
    lowest
}

impl<'a> IntegratedMotion<'a> {
    /// Read the accelerations of `targets` from `inner` and integrate them; `corner` is
    /// the band-limited integration's high-pass corner in rad/s where the record is too
    /// short to read one from its spectrum. The record's accelerations and estimates are
    /// held whole (see the module doc): above `limit` bytes (`None`: no limit; callers
    /// give each of the levels integrated side by side its share of
    /// [`crate::limits::MAX_BYTES`] unless told to allow large work) it is refused
    /// (`dynid::data::too_large`), having read the record but held none of it beyond the
    /// limit.
    pub fn design(
        inner: &'a dyn LevelSource,
        targets: &[Target],
        inputs: &[usize],
        corner: f64,
        chunk: usize,
        limit: Option<f64>,
    ) -> Result<Self, DataError> {
        use crate::limits::bytes_in_words;
        let limit = limit.unwrap_or(f64::INFINITY);
        let mut accels: Vec<usize> = targets.iter().map(|t| t.accel).collect();
        accels.sort_unstable();
        accels.dedup();
        // Per sample: each acceleration and each estimate, and the transform's padded real
        // buffer and half-length complex spectrum (about three more words, padding aside).
        let per_sample = 8.0 * (accels.len() + inputs.len() + targets.len() + 3) as f64;
        let mut samples = 0usize;
        let mut data: Vec<Vec<f64>> = vec![Vec::new(); accels.len()];
        let mut forces: Vec<Vec<f64>> = vec![Vec::new(); inputs.len()];
        inner.stream(chunk, &mut |cols, len| {
            samples += len;
            if samples as f64 * per_sample > limit {
                return;
            }
            for (d, &s) in data.iter_mut().zip(&accels) {
                d.extend_from_slice(&cols[s][..len]);
            }
            for (d, &s) in forces.iter_mut().zip(inputs) {
                if let Some(c) = cols.get(s) {
                    d.extend_from_slice(&c[..len.min(c.len())]);
                }
            }
        })?;
        let bytes = samples as f64 * per_sample;
        if bytes > limit {
            return Err(DataError::TooLarge {
                path: inner.origin(),
                estimate: bytes_in_words(bytes),
                rows: format!("{:.1e}", samples as f64),
                columns: accels.len() + targets.len(),
                limit: bytes_in_words(limit),
            });
        }
        let ts = inner.ts();
        let mut values = vec![Vec::new(); targets.len()];
        let mut lowest = vec![None; targets.len()];
        let short = data.iter().any(|d| d.len() < 4);
        let how = if short {
            Integration::Band { corner }
        } else {
            choose(&data, &forces, ts, corner)
        };
        for (k, t) in targets.iter().enumerate() {
            let d = &data[accels
                .iter()
                .position(|&s| s == t.accel)
                .expect("invariant: read")];
            let mut out = [Vec::new()];
            if short {
                out[0] = vec![0.0; d.len()];
            } else {
                lowest[k] = integrate(d, ts, how, &[t.order], &mut out);
            }
            let [o] = out;
            values[k] = o;
        }
        Ok(IntegratedMotion {
            inner,
            slots: targets.iter().map(|t| t.slot).collect(),
            values,
            how,
            lowest,
        })
    }

    /// [`Self::design`] for every level, side by side; each level gets its share of
    /// [`crate::limits::MAX_BYTES`] unless `allow_large`. The first error in level order.
    pub fn design_all(
        levels: &[&'a dyn LevelSource],
        targets: &[Target],
        inputs: &[usize],
        corner: f64,
        chunk: usize,
        allow_large: bool,
    ) -> Result<Vec<Self>, DataError> {
        use rayon::prelude::*;
        let limit = (!allow_large).then(|| crate::limits::MAX_BYTES / levels.len().max(1) as f64);
        crate::first_error_in_order(
            levels
                .par_iter()
                .map(|src| Self::design(*src, targets, inputs, corner, chunk, limit)),
        )
    }

    /// How the estimates of the level were made (one way for all its accelerations, so that
    /// the relative motion of two bodies is the integral of the relative acceleration).
    pub fn how(&self) -> Integration {
        self.how
    }

    /// The lowest line target `k`'s estimate kept (rad/s), where it was integrated over
    /// whole periods and kept any.
    pub fn lowest_line(&self, k: usize) -> Option<f64> {
        self.lowest.get(k).copied().flatten()
    }
}

impl LevelSource for IntegratedMotion<'_> {
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
        let mut at = 0usize;
        let top = self.slots.iter().copied().max().map_or(0, |s| s + 1);
        self.inner.stream(max_len, &mut |inner, len| {
            // One small vector of slices per chunk, none per sample.
            let mut cols: Vec<&[f64]> = inner.to_vec();
            if cols.len() < top {
                cols.resize(top, &[]);
            }
            for (&s, v) in self.slots.iter().zip(&self.values) {
                let end = (at + len).min(v.len());
                cols[s] = &v[at.min(end)..end];
            }
            at += len;
            sink(&cols, len);
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn lines_below_the_excited_band_and_the_corner_are_left_out() {
        // 4 periods of 250 samples; the input excites lines 3 and 7 of the period, the
        // acceleration holds them and a small line 1 (what a contact's kinks fold down),
        // which `1/ω²` would make the largest part of the displacement.
        let (n, ts) = (1000, 0.01);
        let f0 = 2.0 * PI / (250.0 * ts);
        let wave = |k: f64, p: f64, t: f64| (k * f0 * t + p).sin();
        let u: Vec<f64> = (0..n)
            .map(|i| wave(3.0, 0.2, i as f64 * ts) + wave(7.0, 0.9, i as f64 * ts))
            .collect();
        let x = |t: f64| wave(3.0, 0.3, t) + wave(7.0, 1.1, t);
        let a: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 * ts;
                -(3.0 * f0).powi(2) * wave(3.0, 0.3, t) - (7.0 * f0).powi(2) * wave(7.0, 1.1, t)
                    + 0.05 * wave(1.0, 0.0, t)
            })
            .collect();
        // The input's lowest line bounds the lines kept from above (the corner read from
        // this short record's spectrum is coarse and may lie below it).
        let how = choose(
            std::slice::from_ref(&a),
            std::slice::from_ref(&u),
            ts,
            100.0,
        );
        let Integration::Periodic {
            periods: 4, floor, ..
        } = how
        else {
            panic!("{how:?}")
        };
        assert!(floor <= 3.0 * f0 * (1.0 + 1e-12), "{floor}");
        let error = |floor: f64| {
            let mut out = vec![Vec::new()];
            let how = Integration::Periodic {
                periods: 4,
                floor,
                corner: floor,
            };
            integrate(&a, ts, how, &[2], &mut out);
            (0..n)
                .map(|i| (out[0][i] - x(i as f64 * ts)).abs())
                .fold(0.0, f64::max)
        };
        // Floor at the input's lowest line: line 1 left out, the displacement exact.
        assert!(error(3.0 * f0) < 1e-10, "{}", error(3.0 * f0));
        // Floor below line 1: it is kept, and its displacement 0.05/ω² is the error.
        let kept = error(0.5 * f0);
        assert!((kept / (0.05 / f0.powi(2)) - 1.0).abs() < 1e-3, "{kept}");
    }

    #[test]
    fn lines_below_the_corner_are_kept_only_above_the_folded_level() {
        // 4 periods of 250 samples: lines 3 and 7 of the period, small lines over the top
        // quarter of the band (what folds down from above the Nyquist frequency lands at
        // that level near zero too), and line 1, below the corner (line 2), at `c1`.
        let (n, ts) = (1000, 0.01);
        let f0 = 2.0 * PI / (250.0 * ts);
        let wave = |k: f64, p: f64, t: f64| (k * f0 * t + p).sin();
        let top: Vec<f64> = (94..125).map(f64::from).collect();
        let lines = |c1: f64| {
            let mut l = vec![(1.0, 0.4, c1), (3.0, 0.3, 1.0), (7.0, 1.1, 1.0)];
            l.extend(top.iter().map(|&k| (k, 0.1 * k, 1e-3)));
            l
        };
        // The displacement of the lines `l` and the acceleration of every line of `c1`.
        let x = |l: &[(f64, f64, f64)], t: f64| -> f64 {
            l.iter()
                .map(|&(k, p, c)| c / (k * f0).powi(2) * wave(k, p, t))
                .sum()
        };
        let error = |c1: f64, keep_line_1: bool| {
            let all = lines(c1);
            let a: Vec<f64> = (0..n)
                .map(|i| {
                    let t = i as f64 * ts;
                    -all.iter().map(|&(k, p, c)| c * wave(k, p, t)).sum::<f64>()
                })
                .collect();
            let truth: Vec<(f64, f64, f64)> = if keep_line_1 {
                all.clone()
            } else {
                all[1..].to_vec()
            };
            let mut out = vec![Vec::new()];
            let how = Integration::Periodic {
                periods: 4,
                floor: 0.5 * f0,
                corner: 2.0 * f0,
            };
            integrate(&a, ts, how, &[2], &mut out);
            (0..n)
                .map(|i| (out[0][i] - x(&truth, i as f64 * ts)).abs())
                .fold(0.0, f64::max)
        };
        // The top lines' acceleration amplitude is 1e-3: line 1 at 3e-3 has 9 times their
        // power, below twenty — left out; at 1e-2, 100 times — kept.
        assert!(error(3e-3, false) < 1e-10, "{}", error(3e-3, false));
        assert!(error(1e-2, true) < 1e-10, "{}", error(1e-2, true));
        // Kept or not, the in-band lines above the corner are exact.
        assert!(error(0.0, false) < 1e-10, "{}", error(0.0, false));
    }

    #[test]
    fn whole_periods_of_a_multisine_integrate_exactly() {
        // Three lines, 4 periods of 250 samples: x = Σ sin(ω t + φ), a = −Σ ω² sin(…).
        let (n, ts) = (1000, 0.01);
        let f0 = 2.0 * PI / (250.0 * ts);
        let lines = [(3.0, 0.3), (7.0, 1.1), (20.0, 2.0)];
        let x = |t: f64| {
            lines
                .iter()
                .map(|(k, p)| (k * f0 * t + p).sin())
                .sum::<f64>()
        };
        let v = |t: f64| {
            lines
                .iter()
                .map(|(k, p)| k * f0 * (k * f0 * t + p).cos())
                .sum::<f64>()
        };
        let a: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 * ts;
                lines
                    .iter()
                    .map(|(k, p)| -(k * f0).powi(2) * (k * f0 * t + p).sin())
                    .sum()
            })
            .collect();
        let mut out = vec![Vec::new(), Vec::new()];
        // The force that drives it has the same lines: the lowest bounds the lines kept.
        let u: Vec<f64> = (0..n).map(|i| x(i as f64 * ts)).collect();
        let how = choose(std::slice::from_ref(&a), std::slice::from_ref(&u), ts, 0.1);
        assert!(
            matches!(how, Integration::Periodic { periods: 4, .. }),
            "{how:?}"
        );
        integrate(&a, ts, how, &[2, 1], &mut out);
        for (i, (xe, ve)) in out[0].iter().zip(&out[1]).enumerate() {
            let t = i as f64 * ts;
            assert!((xe - x(t)).abs() < 1e-9, "x at {i}");
            assert!((ve - v(t)).abs() < 1e-9, "v at {i}");
        }
    }

    #[test]
    fn band_limited_integration_recovers_a_sine_away_from_the_ends() {
        // A sine of 2 rad/s over 600 s, not a whole number of periods; corner 0.1 rad/s:
        // H(2) = 1 − 6e-6, and the estimate is zero-phase.
        let (n, ts, w) = (60_000, 0.01, 2.0);
        let a: Vec<f64> = (0..n)
            .map(|i| -w * w * (w * i as f64 * ts + 0.4).sin())
            .collect();
        let mut out = vec![Vec::new(), Vec::new()];
        assert_eq!(periods_of(&a), None);
        integrate(&a, ts, Integration::Band { corner: 0.1 }, &[2, 1], &mut out);
        // Away from the ends (the transient of the record's edges decays as e^(−ω_h t/√2):
        // 25 time constants), within 1e-3 of the unit amplitude.
        let middle = out[0].iter().zip(&out[1]).enumerate();
        for (i, (xe, ve)) in middle.skip(25_000).take(n - 50_000) {
            let t = i as f64 * ts;
            assert!((xe - (w * t + 0.4).sin()).abs() < 1e-3, "x at {i}");
            assert!((ve - w * (w * t + 0.4).cos()).abs() < 2e-3, "v at {i}");
        }
    }

    #[test]
    fn white_noise_is_not_periodic() {
        let mut s = 1u64;
        let a: Vec<f64> = (0..4096)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        assert_eq!(periods_of(&a), None);
    }

    /// One acceleration column `a`, streamed in chunks.
    struct Accel(Vec<f64>);
    impl LevelSource for Accel {
        fn origin(&self) -> String {
            "level 1".into()
        }
        fn ts(&self) -> f64 {
            0.01
        }
        fn stream(
            &self,
            max_len: usize,
            sink: &mut dyn FnMut(&[&[f64]], usize),
        ) -> Result<(), DataError> {
            for c in self.0.chunks(max_len.max(1)) {
                sink(&[c, &[]], c.len());
            }
            Ok(())
        }
    }

    #[test]
    fn a_record_above_its_share_of_memory_is_refused_before_it_is_held() {
        let src = Accel((0..10_000).map(|i| (0.02 * i as f64).sin()).collect());
        let target = [Target {
            slot: 1,
            accel: 0,
            order: 2,
        }];
        // Five words per sample here (the acceleration, the estimate, the transform):
        // 400 kB for 10 000 samples.
        match IntegratedMotion::design(&src, &target, &[], 0.1, 1000, Some(1e5)) {
            Err(DataError::TooLarge { path, rows, .. }) => {
                assert_eq!(path, "level 1");
                assert_eq!(rows, "1.0e4");
            }
            Err(e) => panic!("another error: {e}"),
            Ok(_) => panic!("held a record above its limit"),
        }
        let held = IntegratedMotion::design(&src, &target, &[], 0.1, 1000, Some(1e6))
            .expect("within the limit");
        assert_eq!(held.values[0].len(), 10_000);
        assert!(IntegratedMotion::design(&src, &target, &[], 0.1, 1000, None).is_ok());
    }
}
