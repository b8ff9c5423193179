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
/// first; cut at cycles ([`super::cycles`]), in time order.
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
    pub cycles: Option<super::cycles::Cycles>,
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
        if !super::cycles::Cycles::alike_amplitudes(self) {
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
            super::cycles::ALIKE_RATIO
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

/// Why a record cannot be split.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum SplitError {
    #[error("{origin}: cannot judge the amplitude by `{signal}`: the record has no such column (columns: {present})")]
    #[diagnostic(
        code(dynid::split::unknown_signal),
        help("name one of the record's columns with `--split-by SIGNAL`, best a measured response such as a position")
    )]
    UnknownSignal {
        origin: String,
        signal: String,
        present: String,
    },
    #[error("a record is split into {segments} segment(s), but at least 2 are needed")]
    #[diagnostic(
        code(dynid::split::segments),
        help("give `--segments N` with N of at least 2 (3–8 levels make the drift test sharpest)")
    )]
    TooFewSegments { segments: usize },
    #[error("{origin}: `{signal}` has the non-finite value {value} at sample {sample}")]
    #[diagnostic(
        code(dynid::split::non_finite),
        help("repair or cut away the samples with NaN or infinite values")
    )]
    NonFinite {
        origin: String,
        signal: String,
        sample: usize,
        value: f64,
    },
    #[error("{origin}: `{signal}` does not oscillate about its mean ({crossings} crossings; at least {MIN_CROSSINGS} are needed to tell its dominant frequency, which sets the shortest segment)")]
    #[diagnostic(
        code(dynid::split::no_oscillation),
        help("judge the amplitude by a response that the excitation moves (`--split-by SIGNAL`), or record a longer run")
    )]
    NoOscillation {
        origin: String,
        signal: String,
        crossings: usize,
    },
    #[error("{flag} splits a single data file, but {files} files were given")]
    #[diagnostic(
        code(dynid::split::several_files),
        help("give one file to be split into levels, or drop the flag: with several files each file is one level")
    )]
    SeveralFiles { flag: &'static str, files: usize },
    #[error("`{model}` measures no response to judge the amplitude of `{origin}` by")]
    #[diagnostic(
        code(dynid::split::no_response),
        help("measure a position or velocity of a body, or give one file per level")
    )]
    NoResponse { model: String, origin: String },
    #[error("{origin}: no signal repeats at least twice ({checked} checked: autocorrelation below {correlation} at every lag up to half the record)")]
    #[diagnostic(
        code(dynid::split::no_cycles),
        help("cut it by amplitude (`--cut amplitude`), or give one file per level")
    )]
    NoCycles {
        origin: String,
        checked: String,
        correlation: f64,
    },
    #[error("{origin}: `{by}` repeats every {period} s, {count} whole cycles: too few for {segments} segments of whole cycles")]
    #[diagnostic(
        code(dynid::split::few_cycles),
        help("give `--segments {count}` or fewer (whole cycles per segment), or cut by amplitude with `--cut amplitude`")
    )]
    FewCycles {
        origin: String,
        by: String,
        period: String,
        count: usize,
        segments: usize,
    },
    #[error("{origin}: {n} samples are too short for {segments} segments: each needs at least {min_len} samples ({min_duration} s, 80 / ω₀ with the dominant frequency ω₀ = {omega} rad/s of `{signal}`, so that identification's slowest filter settles)")]
    #[diagnostic(code(dynid::split::too_short), help("{help}"))]
    TooShort {
        origin: String,
        signal: String,
        n: usize,
        segments: usize,
        min_len: usize,
        min_duration: String,
        omega: String,
        help: String,
    },
}

/// Where one record is cut into levels (`--cut`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CutAt {
    /// At the cycles of a repeated trajectory when the record repeats with one amplitude,
    /// else by amplitude.
    #[default]
    Auto,
    /// At the cycles of a repeated trajectory (refused when the record does not repeat).
    Cycles,
    /// By the local amplitude of the response.
    Amplitude,
}

impl CutAt {
    /// The spellings of the command line and of Python: `auto`, `cycles`, `amplitude`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "auto" => Some(Self::Auto),
            "cycles" => Some(Self::Cycles),
            "amplitude" => Some(Self::Amplitude),
            _ => None,
        }
    }
}

/// How one record is cut into levels: the choices of `--segments`, `--split-by` and
/// `--cut` (Python: `segments=`, `split_by=`, `cut=`), shared by every front end so that
/// the same record gives the same levels and the same errors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplitChoice {
    /// Number of segments; `None`: one per cycle of a repeated trajectory, else 3 by
    /// amplitude.
    pub segments: Option<usize>,
    /// The signal whose amplitude is judged; `None`: [`default_response`].
    pub split_by: Option<String>,
    pub cut: CutAt,
}

impl SplitChoice {
    /// Whether `files` records are cut into levels: one record always is; several never,
    /// and a split option given with several is an error.
    #[allow(clippy::result_large_err)] // an error is built once, on the way out
    pub fn applies(&self, files: usize) -> Result<bool, SplitError> {
        if files <= 1 {
            return Ok(files == 1);
        }
        let flag = match (&self.segments, &self.split_by, self.cut) {
            (Some(_), _, _) => "--segments",
            (None, Some(_), _) => "--split-by",
            (None, None, CutAt::Auto) => return Ok(false),
            (None, None, _) => "--cut",
        };
        Err(SplitError::SeveralFiles { flag, files })
    }

    /// The response whose amplitude is judged (checked before the record is read).
    #[allow(clippy::result_large_err)]
    pub fn response(&self, ir: &ModelIr, origin: &str) -> Result<String, SplitError> {
        match &self.split_by {
            Some(s) => Ok(s.clone()),
            None => default_response(ir).ok_or_else(|| SplitError::NoResponse {
                model: ir.name.clone(),
                origin: origin.into(),
            }),
        }
    }

    /// Cut `record` (all columns of one file; `origin` names it in errors) into levels:
    /// at the cycles of a repeated trajectory when [`Self::cut`] allows it and a signal
    /// repeats (in auto mode only with one amplitude over the cycles), else by amplitude
    /// ([`split_record`]).
    #[allow(clippy::result_large_err)]
    pub fn split(&self, ir: &ModelIr, record: &Record, origin: &str) -> Result<Split, SplitError> {
        if let Some(segments) = self.segments.filter(|&n| n < 2) {
            return Err(SplitError::TooFewSegments { segments });
        }
        let response = self.response(ir, origin)?;
        if let Some(split) = self.at_cycles(ir, record, origin, &response)? {
            return Ok(split);
        }
        let opts = SplitOptions {
            segments: self.segments.unwrap_or(3),
            ..Default::default()
        };
        split_record(record, origin, &response, &opts)
    }

    /// The record cut at its cycles, when [`Self::cut`] allows it and a signal repeats;
    /// `None`: cut by amplitude.
    #[allow(clippy::result_large_err)]
    fn at_cycles(
        &self,
        ir: &ModelIr,
        record: &Record,
        origin: &str,
        response: &str,
    ) -> Result<Option<Split>, SplitError> {
        if self.cut == CutAt::Amplitude {
            return Ok(None);
        }
        // A reference is the planned trajectory itself; the response follows it; an input
        // repeats with it.
        let names = |pick: fn(&SignalKind) -> bool| -> Vec<String> {
            ir.signals
                .iter()
                .filter(|s| pick(&s.kind) && s.name != response)
                .filter(|s| record.column(&s.name).is_some())
                .map(|s| s.name.clone())
                .collect()
        };
        let mut candidates = names(|k| matches!(k, SignalKind::Reference(_)));
        candidates.push(response.to_string());
        candidates.extend(names(|k| matches!(k, SignalKind::Input(_))));
        let found = candidates.iter().find_map(|c| {
            super::cycles::cut_cycles(record, c, response, None)
                .and_then(Result::ok)
                .map(|s| (c, s))
        });
        let Some((by, per_cycle)) = found else {
            if self.cut == CutAt::Cycles {
                return Err(SplitError::NoCycles {
                    origin: origin.into(),
                    checked: candidates.join(", "),
                    correlation: super::cycles::MIN_CORRELATION,
                });
            }
            return Ok(None);
        };
        if self.cut == CutAt::Auto && !super::cycles::Cycles::alike_amplitudes(&per_cycle) {
            return Ok(None);
        }
        match self.segments {
            None => Ok(Some(per_cycle)),
            Some(n) => match super::cycles::cut_cycles(record, by, response, Some(n)) {
                Some(Ok(split)) => Ok(Some(split)),
                _ => {
                    let cycles = per_cycle.cycles.as_ref();
                    Err(SplitError::FewCycles {
                        origin: origin.into(),
                        by: by.clone(),
                        period: sig(cycles.map_or(0.0, |c| c.period), 5, false),
                        count: cycles.map_or(0, |c| c.cycles),
                        segments: n,
                    })
                }
            },
        }
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
        let fit = n / min_len;
        let help = if fit >= 2 {
            format!(
                "split into at most {fit} segments (`--segments {fit}`), or record a longer run"
            )
        } else {
            format!(
                "record at least {} samples ({} s) for 2 segments, or give one file per level",
                min_len.saturating_mul(2),
                sig(2.0 * min_len as f64 * ts, 4, false)
            )
        };
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
    let bounds = |k: usize| (k * w, if k + 1 == nw { n } else { (k + 1) * w });
    // Windows per shortest segment: at least `min_len` samples.
    let lw = min_len.div_ceil(w);
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A record of a lightly damped oscillation (ω ≈ 2 rad/s) driven by noise, whose
    /// envelope follows `gain(t)`, at Ts = 0.05 s.
    fn oscillation(n: usize, seed: u64, gain: impl Fn(f64) -> f64) -> Record {
        let ts = 0.05;
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let (w, zeta) = (2.0f64, 0.1);
        let (mut x, mut v) = (0.0f64, 0.0f64);
        let mut col = Vec::with_capacity(n);
        for k in 0..n {
            let f: f64 = rng.random_range(-1.0..1.0) * 3.0;
            // Semi-implicit Euler with 10 sub-steps: plenty for a test signal.
            for _ in 0..10 {
                v += (f - 2.0 * zeta * w * v - w * w * x) * ts / 10.0;
                x += v * ts / 10.0;
            }
            col.push(gain(k as f64 * ts) * x + 0.3);
        }
        Record {
            names: vec!["m.x".into(), "u".into()],
            columns: vec![col, vec![0.0; n]],
            ts,
            t0: 2.0,
        }
    }

    #[test]
    fn steps_of_amplitude_are_found_and_sorted() {
        // Three plateaus, loud – quiet – middle, 200 s each.
        let rec = oscillation(12_000, 1, |t| match t {
            t if t < 200.0 => 8.0,
            t if t < 400.0 => 1.0,
            _ => 3.0,
        });
        let s = split_record(&rec, "r", "m.x", &SplitOptions::default()).unwrap();
        assert!((s.omega - 2.0).abs() < 0.3, "{}", s.omega);
        let starts: Vec<usize> = s.segments.iter().map(|g| g.start).collect();
        // Quietest first: the middle plateau, then the last, then the first.
        assert_eq!(starts[2], 0);
        for (seg, at) in [(&s.segments[0], 4000), (&s.segments[1], 8000)] {
            // Boundaries within one window of the true step.
            assert!(seg.start.abs_diff(at) <= s.window, "{} vs {at}", seg.start);
        }
        assert!(s.segments.windows(2).all(|p| p[0].sigma < p[1].sigma));
        assert_eq!(s.segments.iter().map(|g| g.len).sum::<usize>(), 12_000);
        let recs = s.records(&rec);
        assert_eq!(recs[2].t0, 2.0);
        assert!((recs[0].t0 - (2.0 + s.segments[0].start as f64 * 0.05)).abs() < 1e-9);
        assert_eq!(recs[1].len(), s.segments[1].len);
        let table = s.table();
        assert!(
            table.contains("`m.x`") && table.lines().count() == 5,
            "{table}"
        );
    }

    #[test]
    fn a_ramp_is_cut_into_pieces_of_equal_log_amplitude() {
        // The envelope rises by ×27 over 600 s: three pieces of ×3 each, 200 s apiece.
        let rec = oscillation(12_000, 2, |t| 27f64.powf(t / 600.0));
        let s = split_record(&rec, "r", "m.x", &SplitOptions::default()).unwrap();
        let mut by_time = s.segments.clone();
        by_time.sort_by_key(|g| g.start);
        assert_eq!(by_time, s.segments, "a rising ramp is sorted by time too");
        for (g, at) in s.segments.iter().zip([0, 4000, 8000]) {
            // Random envelopes wander: boundaries within 15 % of a piece.
            assert!(g.start.abs_diff(at) <= 600, "{:?}", s.segments);
        }
        let r = s.segments[2].sigma / s.segments[0].sigma;
        assert!(r > 5.0, "σ ratio {r}");
    }

    #[test]
    fn every_segment_is_long_enough_for_identification() {
        let rec = oscillation(12_000, 3, |t| 27f64.powf(t / 600.0));
        let opts = SplitOptions {
            segments: 8,
            ..Default::default()
        };
        let s = split_record(&rec, "r", "m.x", &opts).unwrap();
        // 80 / ω₀ with ω₀ ≈ 2 rad/s: about 40 s, 800 samples.
        assert!((700..=950).contains(&s.min_len), "{}", s.min_len);
        assert!(s.segments.iter().all(|g| g.len >= s.min_len));
        assert_eq!(s.segments.len(), 8);
    }

    #[test]
    fn errors_name_the_problem() {
        let rec = oscillation(2_000, 4, |_| 1.0);
        let e = split_record(&rec, "r.csv", "m.x", &SplitOptions::default()).unwrap_err();
        let SplitError::TooShort { min_len, .. } = &e else {
            panic!("{e}")
        };
        assert!(e.to_string().contains("too short for 3 segments"), "{e}");
        // 2000 samples hold two segments of ~800.
        assert!(2 * min_len <= 2000);
        let two = SplitOptions {
            segments: 2,
            ..Default::default()
        };
        assert!(split_record(&rec, "r.csv", "m.x", &two).is_ok());
        let e = split_record(&rec, "r.csv", "m.y", &two).unwrap_err();
        assert!(matches!(e, SplitError::UnknownSignal { .. }), "{e}");
        assert!(e.to_string().contains("m.x, u"), "{e}");
        let e = split_record(&rec, "r.csv", "u", &two).unwrap_err();
        assert!(matches!(e, SplitError::NoOscillation { .. }), "{e}");
        let one = SplitOptions {
            segments: 1,
            ..Default::default()
        };
        let e = split_record(&rec, "r.csv", "m.x", &one).unwrap_err();
        assert!(matches!(e, SplitError::TooFewSegments { .. }), "{e}");
        let mut bad = rec.clone();
        bad.columns[0][7] = f64::NAN;
        let e = split_record(&bad, "r.csv", "m.x", &two).unwrap_err();
        assert!(matches!(e, SplitError::NonFinite { sample: 8, .. }), "{e}");
    }

    #[test]
    fn the_default_response_is_the_first_measured_position() {
        let ir = dsl_parser::compile_str(
            "m",
            "model m {\n body a = 1.0\n body b = 1.0\n input u on a\n damper d (ground, a) ~ 1.0\n spring k (ground, b) ~ 1.0\n measure a.v, b.x, u\n}\n",
        );
        let ir = match ir {
            Ok(ir) => ir,
            Err(e) => panic!("{e:?}"),
        };
        assert_eq!(default_response(&ir).as_deref(), Some("b.x"));
    }
}
