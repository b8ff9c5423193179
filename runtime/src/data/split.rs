//! One record whose amplitude varies (a run-up, a sweep of drive levels) cut into contiguous
//! segments ordered by amplitude, so that detection and diagnosis can treat each segment as
//! one excitation level.
//!
//! **Why contiguous.** Identification filters every level from its first sample and needs
//! the slowest filter chain to forget its start ([`crate::ident::design`]); a level made of
//! pieces gathered from all over the record would restart that transient at every seam. So
//! each segment is one stretch of time and becomes one [`Record`] with its own `t0`.
//!
//! **Amplitude.** The judged response (by default the first measured position, see
//! [`default_response`]) is cut into windows; each window's standard deviation about its
//! own mean is its local RMS, so that a slow offset drift does not count as amplitude. The
//! logarithm of the local RMS is then segmented into `N` contiguous pieces, each as constant
//! as possible: the segmentation minimises the sample-weighted sum of squared deviations
//! of log-RMS from each piece's mean, found exactly by dynamic programming (O(N·W²) for W
//! windows, at most [`MAX_WINDOWS`]). Logarithms, because amplitude levels are ratios: a
//! step from 1 to 2 weighs as much as one from 10 to 20. A least-squares segmentation puts
//! the boundaries where the amplitude changes most, so each segment is as close to one
//! stationary level as the record allows; a steady ramp is cut into pieces of equal
//! log-amplitude span.
//!
//! **Shortest segment.** Identification designs its slowest filter corner at half the
//! lowest dominant frequency of the data, `λ = ω₀/2` ([`crate::ident::design::design_corners`]),
//! and a chain of `n` sections settles only on a record of [`SETTLE`]` · n / λ` seconds; on
//! a shorter one it lifts that corner above the design ([`crate::ident::design::fit_corners`]).
//! So every segment spans at least
//!
//! ```text
//! T_min = SETTLE · n / (ω₀ / 2) = 2 · 10 · 4 / ω₀ = 80 / ω₀   (≈ 12.7 periods of ω₀)
//! ```
//!
//! with `n` = [`SPLIT_ORDER`] = 4 sections (the default order of every model whose
//! velocities are unmeasured; with measured velocities it is 3 and the bound is generous)
//! and `ω₀` the dominant frequency of the judged response, from its mean rate of crossings
//! of its mean (Rice: `ω₀ = π N₀ / T`, as identification estimates it). The window is a
//! tenth of `T_min` (1.3 periods), so boundaries fall to within that.
//! Longer segments give smaller standard errors and a sharper drift test; `T_min` is only
//! the length at which identification runs with its designed filters.

use super::MIN_SAMPLES;
use crate::record::Record;
use crate::settle::SETTLE;
use dynid_ir::ir::{ModelIr, SignalKind};
use dynid_ir::num::sig;
use serde::Serialize;

/// Filter sections assumed for the shortest segment (see the module documentation).
pub const SPLIT_ORDER: usize = 4;

/// Windows per shortest segment: the resolution of the boundaries.
const WINDOWS_PER_MIN: usize = 10;

/// Most windows the segmentation works on (longer records get longer windows).
pub const MAX_WINDOWS: usize = 2000;

/// Fewest mean crossings of the judged response for a dominant frequency.
const MIN_CROSSINGS: usize = 10;

/// Hysteresis of the crossing count, as a fraction of the record's σ (as in detection):
/// noise does not add crossings, while a quiet stretch a few times below the record's σ
/// still counts its own.
const CROSSING_HYSTERESIS: f64 = 0.05;

mod choice;
pub mod cycles;
mod error;

pub use choice::{CutAt, SplitChoice};
pub use error::SplitError;

/// How to split.
#[derive(Clone, Debug, PartialEq)]
pub struct SplitOptions {
    /// Number of segments (at least 2).
    pub segments: usize,
    /// Shortest segment in seconds; `None`: `80 / ω₀` (module documentation).
    pub min_duration: Option<f64>,
}

impl Default for SplitOptions {
    fn default() -> Self {
        Self {
            segments: 3,
            min_duration: None,
        }
    }
}

/// One segment of the record.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Segment {
    /// First sample (0-based) and number of samples.
    pub start: usize,
    pub len: usize,
    /// Times of the first and the last sample (seconds, on the record's time axis).
    pub t_start: f64,
    pub t_end: f64,
    /// Standard deviation of the judged response over the segment (about its mean).
    pub sigma: f64,
}

/// The segments of a record: cut by amplitude, sorted by [`Segment::sigma`], smallest
/// first; cut at cycles ([`cycles`]), in time order.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Split {
    /// The signal whose amplitude was judged.
    pub signal: String,
    /// Its dominant angular frequency (rad/s); cut at cycles, `2π / period`.
    pub omega: f64,
    /// Shortest segment allowed, in samples; cut at cycles, the shortest segment.
    pub min_len: usize,
    /// Window of the local RMS, in samples; cut at cycles, the period rounded.
    pub window: usize,
    pub segments: Vec<Segment>,
    /// Cut at the cycles of a repeated signal: the period and the cuts (`None`: cut by
    /// amplitude).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cycles: Option<cycles::Cycles>,
}

impl Split {
    /// The segments as records, in the order of [`Split::segments`].
    pub fn records(&self, rec: &Record) -> Vec<Record> {
        self.segments
            .iter()
            .map(|s| Record {
                names: rec.names.clone(),
                columns: rec
                    .columns
                    .iter()
                    .map(|c| c[s.start..s.start + s.len].to_vec())
                    .collect(),
                ts: rec.ts,
                t0: rec.t0 + s.start as f64 * rec.ts,
            })
            .collect()
    }

    /// A label for segment `i` of a record from `origin`: `one.csv [120–240 s]`.
    pub fn label(&self, origin: &str, i: usize) -> String {
        let s = &self.segments[i];
        format!(
            "{origin} [{}–{} s]",
            sig(s.t_start, 6, false),
            sig(s.t_end, 6, false)
        )
    }

    /// What segments cut at the cycles of one trajectory can tell detection: nothing about
    /// an effect when their amplitudes are alike (`None` for a cut by amplitude, or cycles
    /// whose amplitudes differ).
    pub fn cycles_note(&self) -> Option<String> {
        let c = self.cycles.as_ref()?;
        if !cycles::Cycles::alike_amplitudes(self) {
            return None;
        }
        let (lo, hi) = self
            .segments
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), s| {
                (lo.min(s.sigma), hi.max(s.sigma))
            });
        Some(format!(
            "the {} segments are cycles of one repeated trajectory (`{}` every {} s) with one \
             amplitude (σ of `{}` {} to {}, ratio {:.2}, below {}): detection reads an effect \
             from how the linear parameters drift between levels of different amplitude, so these \
             segments cannot show one, and a `linear` verdict from them rules nothing out. Record \
             the trajectory at several speeds or amplitudes (one file each), or run `dynid \
             diagnose`, for which cycles are legitimate pieces",
            self.segments.len(),
            c.signal,
            sig(c.period, 5, false),
            self.signal,
            sig(lo, 4, false),
            sig(hi, 4, false),
            hi / lo,
            cycles::ALIKE_RATIO
        ))
    }

    /// The segments as a table: level, time span, samples, σ.
    pub fn table(&self) -> String {
        let head = match &self.cycles {
            Some(c) => format!(
                "segments at the cycles of a repeated trajectory: {}; σ of `{}`",
                c.describe(),
                self.signal
            ),
            None => format!(
                "segments by the amplitude of `{}` (dominant frequency {} rad/s, shortest \
                 segment {} samples)",
                self.signal,
                sig(self.omega, 4, false),
                self.min_len
            ),
        };
        let mut out = format!("{head}:\n  level  time span (s)           samples   σ\n");
        for (i, s) in self.segments.iter().enumerate() {
            let span = format!("{} – {}", sig(s.t_start, 6, false), sig(s.t_end, 6, false));
            out += &format!(
                "  {:<5}  {span:<22}  {:>8}   {}\n",
                i + 1,
                s.len,
                sig(s.sigma, 4, false)
            );
        }
        out
    }
}

/// The response to judge the amplitude by when the user names none: the first measured
/// position (every force element acts through positions), else the first measured signal
/// that is not an input.
pub fn default_response(ir: &ModelIr) -> Option<String> {
    let measured = ir.measured_signals();
    let first = |pick: &dyn Fn(&SignalKind) -> bool| {
        measured
            .iter()
            .map(|s| ir.signal(*s))
            .find(|s| pick(&s.kind))
            .map(|s| s.name.clone())
    };
    first(&|k| matches!(k, SignalKind::Position(_)))
        .or_else(|| first(&|k| !matches!(k, SignalKind::Input(_))))
}

/// Mean and standard deviation (about the mean) of `x`.
fn mean_std(x: &[f64]) -> (f64, f64) {
    let n = x.len().max(1) as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n;
    (m, v.sqrt())
}

/// Crossings of the mean of `x` with a hysteresis of `h` on either side.
fn crossings(x: &[f64], mean: f64, h: f64) -> usize {
    let (mut side, mut count) = (0i8, 0usize);
    for &v in x {
        let now = if v > mean + h {
            1
        } else if v < mean - h {
            -1
        } else {
            0
        };
        if now != 0 && now != side {
            if side != 0 {
                count += 1;
            }
            side = now;
        }
    }
    count
}

/// Cut `rec` into `opts.segments` contiguous segments by the amplitude of its column
/// `signal` (see the module documentation); `origin` names the record in errors.
///
/// Slightly longer than most functions here: each check of the record ends in its own
/// error, named with the record and the signal.
#[allow(clippy::result_large_err)] // an error is built once, on the way out
pub fn split_record(
    rec: &Record,
    origin: &str,
    signal: &str,
    opts: &SplitOptions,
) -> Result<Split, SplitError> {
    let segments = opts.segments;
    if segments < 2 {
        return Err(SplitError::TooFewSegments { segments });
    }
    let x = rec
        .column(signal)
        .ok_or_else(|| SplitError::UnknownSignal {
            origin: origin.into(),
            signal: signal.into(),
            present: rec.names.join(", "),
        })?;
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(SplitError::NonFinite {
            origin: origin.into(),
            signal: signal.into(),
            sample: i + 1,
            value: x[i],
        });
    }
    let n = x.len();
    let ts = rec.ts;
    let (mean, std) = mean_std(x);
    let n_cross = if std > 0.0 {
        crossings(x, mean, CROSSING_HYSTERESIS * std)
    } else {
        0
    };
    if n_cross < MIN_CROSSINGS {
        return Err(SplitError::NoOscillation {
            origin: origin.into(),
            signal: signal.into(),
            crossings: n_cross,
        });
    }
    let duration = (n - 1) as f64 * ts;
    let omega = std::f64::consts::PI * n_cross as f64 / duration;
    let t_min = opts
        .min_duration
        .unwrap_or(2.0 * SETTLE * SPLIT_ORDER as f64 / omega);
    // A segment of `min_len` samples spans `(min_len − 1)·ts ≥ t_min` seconds.
    let min_len = ((t_min / ts).ceil() as usize)
        .saturating_add(1)
        .max(MIN_SAMPLES);
    if n < segments.saturating_mul(min_len) {
        let help = too_short_help(n, min_len, ts);
        return Err(SplitError::TooShort {
            origin: origin.into(),
            signal: signal.into(),
            n,
            segments,
            min_len,
            min_duration: sig(t_min, 4, false),
            omega: sig(omega, 4, false),
            help,
        });
    }

    // Windows of `w` samples; the last one takes the remainder.
    let w = min_len
        .div_ceil(WINDOWS_PER_MIN)
        .max(n.div_ceil(MAX_WINDOWS))
        .max(1);
    let nw = n / w;
    let bounds = |k: usize| window_bounds(k, w, nw, n);
    let cuts = least_squares_cuts(x, w, min_len.div_ceil(w), segments, std);
    let mut segs: Vec<Segment> = cuts
        .windows(2)
        .map(|c| {
            let start = bounds(c[0]).0;
            let end = if c[1] == nw { n } else { bounds(c[1]).0 };
            Segment {
                start,
                len: end - start,
                t_start: rec.t0 + start as f64 * ts,
                t_end: rec.t0 + (end - 1) as f64 * ts,
                sigma: mean_std(&x[start..end]).1,
            }
        })
        .collect();
    segs.sort_by(|a, b| a.sigma.total_cmp(&b.sigma).then(a.start.cmp(&b.start)));
    Ok(Split {
        signal: signal.into(),
        omega,
        min_len,
        window: w,
        segments: segs,
        cycles: None,
    })
}

/// What to do when `n` samples of interval `ts` hold fewer than the segments asked for, each
/// of at least `min_len` samples.
fn too_short_help(n: usize, min_len: usize, ts: f64) -> String {
    let fit = n / min_len;
    if fit >= 2 {
        format!("split into at most {fit} segments (`--segments {fit}`), or record a longer run")
    } else {
        format!(
            "record at least {} samples ({} s) for 2 segments, or give one file per level",
            min_len.saturating_mul(2),
            sig(2.0 * min_len as f64 * ts, 4, false)
        )
    }
}

/// Window `k` of `w` samples out of `nw` over `n` samples, as a sample range; the last one
/// takes the remainder.
fn window_bounds(k: usize, w: usize, nw: usize, n: usize) -> (usize, usize) {
    (k * w, if k + 1 == nw { n } else { (k + 1) * w })
}

/// The least-squares segmentation of the module documentation: the window indices
/// `0 = c₀ < c₁ < … < c_segments = nw` that cut the log local RMS of `x` (windows of `w`
/// samples) into `segments` pieces of at least `lw` windows each, minimising the
/// sample-weighted squared deviation of every window from its piece's mean (dynamic
/// programming, O(segments · nw²)). `std` is the record's σ (a floor for quiet windows).
fn least_squares_cuts(x: &[f64], w: usize, lw: usize, segments: usize, std: f64) -> Vec<usize> {
    let n = x.len();
    let nw = n / w;
    let bounds = |k: usize| window_bounds(k, w, nw, n);
    let floor = 1e-12 * std;
    let mut cw = vec![0.0; nw + 1];
    let mut cy = vec![0.0; nw + 1];
    let mut cyy = vec![0.0; nw + 1];
    for k in 0..nw {
        let (a, b) = bounds(k);
        let c = (b - a) as f64;
        let y = mean_std(&x[a..b]).1.max(floor).ln();
        cw[k + 1] = cw[k] + c;
        cy[k + 1] = cy[k] + c * y;
        cyy[k + 1] = cyy[k] + c * y * y;
    }
    // Weighted squared deviation of windows i..j from their mean.
    let cost = |i: usize, j: usize| {
        let c = cw[j] - cw[i];
        let s = cy[j] - cy[i];
        (cyy[j] - cyy[i] - s * s / c).max(0.0)
    };
    // best[m][j]: the least cost of windows 0..j in m + 1 pieces; from[m][j]: where the
    // last piece starts.
    let inf = f64::INFINITY;
    let mut best = vec![vec![inf; nw + 1]; segments];
    let mut from = vec![vec![0usize; nw + 1]; segments];
    for (j, b) in best[0].iter_mut().enumerate().skip(lw) {
        *b = cost(0, j);
    }
    for m in 1..segments {
        for j in (m + 1) * lw..=nw {
            for i in m * lw..=j - lw {
                let c = best[m - 1][i] + cost(i, j);
                if c < best[m][j] {
                    best[m][j] = c;
                    from[m][j] = i;
                }
            }
        }
    }
    let mut cuts = vec![nw];
    let mut j = nw;
    for m in (1..segments).rev() {
        j = from[m][j];
        cuts.push(j);
    }
    cuts.push(0);
    cuts.reverse();
    cuts
}

#[cfg(test)]
mod tests;
