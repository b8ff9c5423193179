//! One record of a repeated trajectory (a planned cycle of moves, a periodic drive) cut at
//! its cycles, so that diagnosis can withhold a cycle as it withholds a level.
//!
//! **Period.** The signal's autocorrelation about its mean, normalised over the overlap of
//! the record with its shifted copy,
//!
//! ```text
//! r(τ) = Σ x(t) x(t+τ) / √(Σ x(t)² · Σ x(t+τ)²)      (sums over t = 0 … n−1−τ)
//! ```
//!
//! is 1 at every multiple of the period of a signal repeated sample for sample and stays
//! below it elsewhere. Lags run from where `r` first falls below [`DECORRELATED`] (a slow
//! signal is alike to itself at short lags) to half the record (two cycles at least); the
//! period is the shortest lag whose local peak comes within [`PEAK_TOLERANCE`] of the
//! highest (a record of four cycles peaks at one, two and three periods), refined between
//! samples by a parabola through the peak and its neighbours. A peak below
//! [`MIN_CORRELATION`] is no period. The sums come from one zero-padded real FFT.
//!
//! **Where to cut.** Free runs and identification start every piece from its first samples,
//! and a start at rest is the one whose state the data give best (the velocity is zero, no
//! transient is cut in half). So the cuts are `φ + k·P` with the phase `φ ∈ [0, P)` at
//! which the signal moves least, summed over all cycles (its absolute first difference over
//! a window of [`REST_WINDOW`] of the period around each cut). Samples before the first cut
//! and after the last join the first and the last piece, so nothing is dropped.
//!
//! **Cycles of one trajectory have one amplitude.** Detection reads a nonlinearity from how
//! the linear parameters drift with the amplitude; cycles do not differ in amplitude, so
//! they serve diagnosis (a withheld cycle is new data for the same motion) but tell
//! detection nothing ([`Cycles::alike_amplitudes`]).

use super::{Segment, Split};
use crate::data::MIN_SAMPLES;
use crate::record::Record;
use dynid_ir::num::sig;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use serde::Serialize;

/// Autocorrelation below which the signal counts as decorrelated from itself; the period is
/// sought only beyond the first lag where `r` falls below it.
const DECORRELATED: f64 = 0.5;

/// Least autocorrelation at one period for a record to count as repeated.
pub const MIN_CORRELATION: f64 = 0.9;

/// A peak within this of the highest counts as a multiple of the period.
const PEAK_TOLERANCE: f64 = 0.02;

/// Window of the rest search around each cut, as a fraction of the period.
const REST_WINDOW: f64 = 0.01;

/// Cycles whose σ differ by less than this ratio count as one amplitude.
pub const ALIKE_RATIO: f64 = 1.2;

/// How a record repeats: what [`find_period`] found and where the record was cut.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Cycles {
    /// The signal whose repetition was found.
    pub signal: String,
    /// The period in seconds.
    pub period: f64,
    /// Autocorrelation of the signal at one period (1: repeated sample for sample).
    pub correlation: f64,
    /// Whole cycles in the record from the first cut.
    pub cycles: usize,
    /// Time of the first cut (seconds, on the record's time axis): where the signal rests.
    pub first_cut: f64,
    /// Cycles in each segment, in time order.
    pub per_segment: Vec<usize>,
}

impl Cycles {
    /// Whether the segments' σ (of the judged response) are too alike for the level-to-
    /// level drift detection compares: their largest over smallest below [`ALIKE_RATIO`].
    pub fn alike_amplitudes(split: &Split) -> bool {
        let (lo, hi) = split
            .segments
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), s| {
                (lo.min(s.sigma), hi.max(s.sigma))
            });
        // A NaN ratio (no segment, or σ not finite) counts as alike: nothing drifts.
        hi / lo < ALIKE_RATIO || (hi / lo).is_nan()
    }
}

/// Most samples whose autocorrelation is computed directly; a longer record is first
/// averaged over blocks of consecutive samples (its FFT buffers stay below 1 GiB).
const MAX_DIRECT: usize = 1 << 22;

/// The period of `x` (samples, fractional) and the autocorrelation there, or `None` when
/// the record does not repeat at least twice (see the module documentation).
pub fn find_period(x: &[f64]) -> Option<(f64, f64)> {
    if x.len() > MAX_DIRECT {
        let f = x.len().div_ceil(MAX_DIRECT);
        let means: Vec<f64> = x
            .chunks_exact(f)
            .map(|c| c.iter().sum::<f64>() / f as f64)
            .collect();
        return find_period(&means).map(|(p, r)| (p * f as f64, r));
    }
    let n = x.len();
    if n < 2 * MIN_SAMPLES || x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let len = (2 * n).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(len);
    let inv = planner.plan_fft_inverse(len);
    let mut buf = fwd.make_input_vec();
    for (b, v) in buf.iter_mut().zip(x) {
        *b = v - mean;
    }
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut buf, &mut spec)
        .expect("invariant: buffers made by the plan");
    for c in spec.iter_mut() {
        *c = Complex::new(c.norm_sqr(), 0.0);
    }
    let mut acf = inv.make_output_vec();
    inv.process(&mut spec, &mut acf)
        .expect("invariant: buffers made by the plan");
    // Energies of the overlaps: head(τ) = Σ_{t<n−τ} x², tail(τ) = Σ_{t≥τ} x².
    let mut cum = vec![0.0; n + 1];
    for (k, v) in x.iter().enumerate() {
        cum[k + 1] = cum[k] + (v - mean).powi(2);
    }
    let total = cum[n];
    if total <= 0.0 {
        return None;
    }
    let r = |tau: usize| {
        let head = cum[n - tau];
        let tail = total - cum[tau];
        let d = (head * tail).sqrt();
        if d > 0.0 {
            acf[tau] / len as f64 / d
        } else {
            0.0
        }
    };
    let last = n / 2;
    let first = (1..=last).find(|&t| r(t) < DECORRELATED)?;
    let first = first.max(MIN_SAMPLES);
    if first + 1 >= last {
        return None;
    }
    let rs: Vec<f64> = (first..=last).map(r).collect();
    let best = rs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if best < MIN_CORRELATION {
        return None;
    }
    // The shortest lag whose local peak comes within the tolerance of the highest.
    let k = (1..rs.len() - 1)
        .find(|&k| rs[k] >= best - PEAK_TOLERANCE && rs[k] >= rs[k - 1] && rs[k] >= rs[k + 1])?;
    let (a, b, c) = (rs[k - 1], rs[k], rs[k + 1]);
    let curv = a - 2.0 * b + c;
    let shift = if curv < 0.0 {
        (0.5 * (a - c) / curv).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    Some(((first + k) as f64 + shift, b))
}

/// Cut `rec` at the cycles of its column `signal` into `segments` pieces of whole cycles
/// (one per cycle when `None`), judging each piece's σ by `response`. `None` when `signal`
/// does not repeat at least twice; `Err(cycles)` when it repeats fewer than `segments`
/// times.
pub fn cut_cycles(
    rec: &Record,
    signal: &str,
    response: &str,
    segments: Option<usize>,
) -> Option<Result<Split, usize>> {
    let x = rec.column(signal)?;
    let y = rec.column(response)?;
    let (period, correlation) = find_period(x)?;
    let n = x.len();
    let p = period.round() as usize;
    // The phase at which the signal moves least over all cycles.
    let w = ((REST_WINDOW * period).round() as usize).max(1);
    let mut cum = vec![0.0; n + 1];
    for k in 1..n {
        cum[k + 1] = cum[k] + (x[k] - x[k - 1]).abs();
    }
    let activity = |phi: usize| {
        let mut s = 0.0;
        let mut k = 0.0;
        loop {
            let c = (phi as f64 + k * period).round() as usize;
            if c >= n {
                break s;
            }
            s += cum[(c + w + 1).min(n)] - cum[c.saturating_sub(w)];
            k += 1.0;
        }
    };
    let phi = (0..p.min(n))
        .map(|phi| (phi, activity(phi)))
        .fold((0, f64::INFINITY), |b, a| if a.1 < b.1 { a } else { b })
        .0;
    let count = ((n - phi) as f64 / period).floor() as usize;
    if count < 2 {
        return None;
    }
    let pieces = segments.unwrap_or(count);
    if pieces > count {
        return Some(Err(count));
    }
    let per_segment: Vec<usize> = (0..pieces)
        .map(|i| count / pieces + usize::from(i < count % pieces))
        .collect();
    let cut = |cycle: usize| (phi as f64 + cycle as f64 * period).round() as usize;
    let mut segs = Vec::with_capacity(pieces);
    let mut cycle = 0;
    for (i, c) in per_segment.iter().enumerate() {
        let start = if i == 0 { 0 } else { cut(cycle) };
        cycle += c;
        let end = if i + 1 == pieces { n } else { cut(cycle) };
        let ys = &y[start..end];
        let m = ys.iter().sum::<f64>() / ys.len() as f64;
        let sigma = (ys.iter().map(|v| (v - m).powi(2)).sum::<f64>() / ys.len() as f64).sqrt();
        segs.push(Segment {
            start,
            len: end - start,
            t_start: rec.t0 + start as f64 * rec.ts,
            t_end: rec.t0 + (end - 1) as f64 * rec.ts,
            sigma,
        });
    }
    let min_len = segs.iter().map(|s| s.len).min().unwrap_or(0);
    Some(Ok(Split {
        signal: response.into(),
        omega: 2.0 * std::f64::consts::PI / (period * rec.ts),
        min_len,
        window: p,
        segments: segs,
        cycles: Some(Cycles {
            signal: signal.into(),
            period: period * rec.ts,
            correlation,
            cycles: count,
            first_cut: rec.t0 + phi as f64 * rec.ts,
            per_segment,
        }),
    }))
}

impl Cycles {
    /// The line that says what was cut and why.
    pub fn describe(&self) -> String {
        let per: Vec<String> = self.per_segment.iter().map(|c| c.to_string()).collect();
        format!(
            "`{}` repeats every {} s (autocorrelation {} at one period): {} whole cycles \
             from t = {} s, where it rests; cut into {} segments of {} cycle(s)",
            self.signal,
            sig(self.period, 5, false),
            sig(self.correlation, 4, false),
            self.cycles,
            sig(self.first_cut, 5, false),
            self.per_segment.len(),
            per.join(" + ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cycle of `p` samples: rest, a smooth move out, rest, back; repeated over `n`
    /// samples from `offset` into the cycle, with a small deterministic wobble.
    fn moves(n: usize, p: usize, offset: usize) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let ph = ((k + offset) % p) as f64 / p as f64;
                let pos = if ph < 0.1 {
                    0.0
                } else if ph < 0.4 {
                    0.5 - 0.5 * (std::f64::consts::PI * (ph - 0.1) / 0.3).cos()
                } else if ph < 0.6 {
                    1.0
                } else if ph < 0.9 {
                    0.5 + 0.5 * (std::f64::consts::PI * (ph - 0.6) / 0.3).cos()
                } else {
                    0.0
                };
                pos + 1e-3 * ((k as f64) * 0.77).sin()
            })
            .collect()
    }

    fn record(x: Vec<f64>) -> Record {
        let n = x.len();
        Record {
            names: vec!["m.x".into(), "u".into()],
            columns: vec![x, vec![0.0; n]],
            ts: 0.01,
            t0: 1.0,
        }
    }

    #[test]
    fn the_period_of_a_repeated_cycle_is_found() {
        let (p, r) = find_period(&moves(2500, 618, 0)).unwrap();
        assert!((p - 618.0).abs() < 0.5, "{p}");
        assert!(r > 0.99, "{r}");
    }

    #[test]
    fn random_noise_has_no_period() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let x: Vec<f64> = (0..5000).map(|_| rng.random_range(-1.0..1.0)).collect();
        assert_eq!(find_period(&x), None);
        // Two cycles at least: 1.5 cycles are not a period.
        assert_eq!(find_period(&moves(900, 618, 0)), None);
    }

    #[test]
    fn cuts_fall_where_the_signal_rests_and_keep_every_sample() {
        // The record starts a third into the cycle (mid-move).
        let rec = record(moves(2500, 618, 200));
        let s = cut_cycles(&rec, "m.x", "m.x", None).unwrap().unwrap();
        let c = s.cycles.as_ref().unwrap();
        assert_eq!(c.cycles, 3, "{c:?}");
        assert_eq!(s.segments.len(), 3);
        // Rests are at phases 0.9–0.1 of the cycle: 418 ± 62 samples into the record.
        let first = s.segments[1].start as f64 - 618.0;
        assert!((first - 418.0).abs() < 62.0, "{:?}", s.segments);
        assert_eq!(s.segments.iter().map(|g| g.len).sum::<usize>(), 2500);
        assert_eq!(s.segments[0].start, 0);
        assert!(s.segments[1].len.abs_diff(618) <= 1, "{:?}", s.segments);
        assert!(Cycles::alike_amplitudes(&s), "{:?}", s.segments);
        // Grouped: three cycles in two pieces, 2 + 1.
        let two = cut_cycles(&rec, "m.x", "m.x", Some(2)).unwrap().unwrap();
        assert_eq!(two.cycles.as_ref().unwrap().per_segment, [2, 1]);
        assert_eq!(cut_cycles(&rec, "m.x", "m.x", Some(4)), Some(Err(3)));
        assert!(c.describe().contains("3 whole cycles"), "{}", c.describe());
    }
}
