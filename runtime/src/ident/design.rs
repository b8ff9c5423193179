//! The filter design: corners spread over the band where the response has power
//! ([`design_corners`]) and fitted to the record, and the time blocks of the standard
//! errors ([`blocks`]). The bank itself (drivers, order) is chosen in `super::bank`.
//!
//! # Corners that fit the record
//!
//! The spectral design ([`design_corners`]) spreads the corners over the band
//! where the response has power. On a short record its slowest chain may not forget its
//! start: a chain of `n` sections with corner `λ` has time constant `τ = n/λ`, and the record
//! must span at least [`SETTLE`]` · τ`. So the lowest corner is lifted to
//!
//! ```text
//! λ_min = SETTLE · n / T          (T: duration of the shortest level)
//! ```
//!
//! and the highest kept at least eight times above it (the spectral span when the record is
//! long enough), but never above a tenth of the Nyquist frequency, where the
//! piecewise-linear input model stays accurate. A record is too short only when even
//! `λ_min` leaves no room below that cap (`λ_min > cap / 2`).

pub use crate::settle::SETTLE;
use std::f64::consts::PI;

/// Lowest corner (rad/s) that a record of `duration` seconds supports with `order` sections.
pub fn min_corner(duration: f64, order: usize) -> f64 {
    SETTLE * order as f64 / duration
}

/// Highest corner (rad/s) at sample interval `ts`: a tenth of the Nyquist frequency.
pub fn max_corner(ts: f64) -> f64 {
    PI / ts / 10.0
}

/// Log-spaced corners from `lo` to `hi`.
fn spread(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    if count == 1 {
        return vec![(lo * hi).sqrt()];
    }
    (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count - 1) as f64))
        .collect()
}

/// Log-spaced corner frequencies covering the band where the response has power.
///
/// `omegas` are dominant angular frequencies estimated from the data (zero-crossing rates of
/// the positions); the band runs from half the lowest to eight times the highest, and
/// is capped at [`max_corner`] (a tenth of the Nyquist frequency) so that the
/// piecewise-linear input model stays accurate.
pub fn design_corners(omegas: &[f64], ts: f64, count: usize) -> Vec<f64> {
    let finite: Vec<f64> = omegas
        .iter()
        .copied()
        .filter(|w| w.is_finite() && *w > 0.0)
        .collect();
    let nyq = PI / ts;
    let (lo, hi) = if finite.is_empty() {
        (nyq / 1000.0, nyq / 20.0)
    } else {
        let mn = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let mx = finite.iter().copied().fold(0.0, f64::max);
        (mn / 2.0, mx * 8.0)
    };
    let hi = hi.min(max_corner(ts));
    let lo = lo.min(hi / 8.0);
    spread(lo, hi, count)
}

/// Corners from the dominant frequencies `omegas` (see [`design_corners`]),
/// lifted where needed so that chains of `order` sections settle within `duration` seconds.
/// `None` when the record is too short for any corner below the cap.
pub fn fit_corners(
    omegas: &[f64],
    ts: f64,
    duration: f64,
    order: usize,
    count: usize,
) -> Option<Vec<f64>> {
    let base = design_corners(omegas, ts, count);
    // A little above the bound, so that corners printed with four decimals still fit.
    let lmin = min_corner(duration, order) * 1.001;
    let cap = max_corner(ts);
    if !(lmin.is_finite() && lmin <= cap / 2.0) {
        return None;
    }
    let lo = base.iter().copied().fold(f64::INFINITY, f64::min);
    if lo >= lmin {
        return Some(base);
    }
    let hi = base.iter().copied().fold(0.0, f64::max);
    let hi = hi.max(8.0 * lmin).min(cap);
    Some(spread(lmin, hi, count))
}

/// What set the lowest corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LowerBy {
    /// Half the lowest dominant frequency of the drivers (the spectral design).
    Spectrum,
    /// The record length: the slowest chain must settle ([`min_corner`]).
    RecordLength,
}

/// What set the highest corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UpperBy {
    /// Eight times the highest dominant frequency (or the lowest corner), the spectral
    /// design.
    Spectrum,
    /// The cap at a tenth of the Nyquist frequency ([`max_corner`]).
    Nyquist,
}

/// Designed corners and what chose them.
#[derive(Clone, Debug, PartialEq)]
pub struct Designed {
    pub corners: Vec<f64>,
    pub lower: LowerBy,
    pub upper: UpperBy,
    /// The measured driver whose information bandwidth set the upper corner, with it (rad/s).
    pub info_signal: Option<(String, f64)>,
}

/// As [`fit_corners`], with what chose the lowest and highest corner, and `info` — the
/// highest frequency (rad/s) at which the measured driver with the narrowest such band
/// stands above its noise floor, with its name — carried along for the report.
///
/// The information bandwidth does not move the corners: raising the highest corner to it
/// (1.6 … 628 rad/s instead of 1.6 … 136 rad/s on the random servo records of the bench
/// `servo_precision`, seeds 1–48) multiplied the RMS errors of the defaults by 1.8 to 10.5
/// (mass 0.021 → 0.22 %, damping 0.90 → 1.76 %, Coulomb friction 2.54 → 4.83 %, offset
/// 1.46 → 2.67 %): a moment
/// `⟨ι'' x⟩` at a high corner weighs the encoder's rounding by `λ²` and more, while a
/// regression of the filtered equation weighs it by the regressor's own size
/// (docs/method.md §2).
pub fn fit_corners_info(
    omegas: &[f64],
    info: Option<(String, f64)>,
    ts: f64,
    duration: f64,
    order: usize,
    count: usize,
) -> Option<Designed> {
    let base = fit_corners(omegas, ts, duration, order, count)?;
    let spectral = design_corners(omegas, ts, count);
    let lo = base.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = base.iter().copied().fold(0.0, f64::max);
    let lower = if spectral == base || lo > min_corner(duration, order) * 1.002 {
        LowerBy::Spectrum
    } else {
        LowerBy::RecordLength
    };
    Some(Designed {
        upper: if hi >= max_corner(ts) * (1.0 - 1e-12) {
            UpperBy::Nyquist
        } else {
            UpperBy::Spectrum
        },
        corners: base,
        lower,
        info_signal: info,
    })
}

/// Fewest time blocks per level of the standard errors when they are chosen from the record.
pub const MIN_BLOCKS: usize = 20;
/// Most time blocks per level of the standard errors when they are chosen from the record.
pub const MAX_BLOCKS: usize = 80;

/// [`MAX_BLOCKS`] for the rows of the filtered equation, whose one chain forgets within a
/// few of its time constants (`6/λ` = 12 ms at 500 rad/s): on a planned record, where the
/// mass's information sits in the few windows that hold a move's start or end, more
/// windows give its standard error more degrees of freedom. The planned servo records cut
/// into their 6.18 s cycles (`tests/servo_planned.rs`, seeds 1–12,
/// `planned_cycles_agree_with_the_filtered_rows_and_delay`): χ²/dof of the cycles about
/// their mean m 1.50, d 1.59, r 2.20, f0 0.81 with at most 80 blocks (measured once before
/// the change), 1.35, 1.15, 1.77, 0.73 with 400; on the whole records of the bench
/// `servo_precision` (48 seeds, at the designed corner, the bench's table before the
/// corner search of `identify`) the same estimates, covered on 90–98 % against 88–92 %
/// (planned) and 90–100 % against 90–98 % (random).
pub const FILTERED_MAX_BLOCKS: usize = 400;

/// The most blocks chosen from the record for `opts`: [`FILTERED_MAX_BLOCKS`] for the rows
/// of the filtered equation, else [`MAX_BLOCKS`].
pub fn max_blocks(opts: &super::types::IdentifyOptions) -> usize {
    match opts.filtered {
        true => FILTERED_MAX_BLOCKS,
        false => MAX_BLOCKS,
    }
}

/// Time blocks per level for the batch-means standard errors (see [`super::stats`]), from
/// the shortest level's `duration` and `samples` and the slowest chain's time constant
/// `tau`: blocks of at least `tau / 2`, as many as that allows between [`MIN_BLOCKS`] and
/// [`MAX_BLOCKS`], and at least four samples each.
///
/// Each level's hat windows are centred on the level's total, which takes a share of the
/// variance that shrinks as the blocks grow in number: on the SDOF benchmark (3 × 200 s,
/// 5 % noise, 20 seeds; `ident::tests::estimates::standard_errors_cover_the_error`) 20 blocks of
/// 10 s gave standard errors about a fifth low (rms z 1.19–1.31), 80 blocks within 1 % of
/// 160 (rms z 1.03–1.05). Blocks much shorter than the slowest chain's time constant
/// overstated them on the closed-loop servo record (25 s, τ = 2.5 s; the 12 seeds of
/// `tests/servo.rs`, rms z of d and r 0.58–0.66 with 80 blocks of 0.31 s, 0.81–0.83 with
/// 20 of 1.25 s). Both comparisons force the count through `IdentifyOptions::n_blocks`.
pub fn blocks(duration: f64, tau: f64, samples: usize) -> usize {
    blocks_up_to(duration, tau, samples, MAX_BLOCKS)
}

/// [`blocks`] with at most `max` blocks instead of [`MAX_BLOCKS`].
pub fn blocks_up_to(duration: f64, tau: f64, samples: usize, max: usize) -> usize {
    let by_memory = if tau > 0.0 && duration.is_finite() {
        (2.0 * duration / tau).floor().min(max as f64) as usize
    } else {
        MIN_BLOCKS
    };
    by_memory
        .clamp(MIN_BLOCKS, max)
        .min((samples / 4).max(MIN_BLOCKS))
}

/// The time constant of the slowest chain, `order / λ_min`: the slowest section must
/// forget its start within a small part of the record.
pub fn time_constant(corners: &[f64], order: usize) -> f64 {
    let lam_min = corners.iter().copied().fold(f64::INFINITY, f64::min);
    order as f64 / lam_min
}

/// Shortest record (seconds) on which `corners` settle with `order` sections.
pub fn min_duration(corners: &[f64], order: usize) -> f64 {
    let lo = corners.iter().copied().fold(f64::INFINITY, f64::min);
    SETTLE * order as f64 / lo
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_at_least_half_the_slowest_time_constant() {
        // 200 s, τ = 4 s: 100 blocks of τ/2 fit, capped at 80.
        assert_eq!(blocks(200.0, 4.0, 20_000), MAX_BLOCKS);
        // 25 s, τ = 2.5 s: 20 blocks of 1.25 s.
        assert_eq!(blocks(25.0, 2.5, 25_000), 20);
        // 60 s, τ = 3 s: 40 blocks of 1.5 s.
        assert_eq!(blocks(60.0, 3.0, 6_000), 40);
        // Never fewer than 20, nor more than a quarter of the samples (unless that is < 20).
        assert_eq!(blocks(5.0, 4.0, 500), MIN_BLOCKS);
        assert_eq!(blocks(1000.0, 1.0, 60), MIN_BLOCKS);
        assert_eq!(blocks(1000.0, 1.0, 240), 60);
        assert_eq!(blocks(f64::INFINITY, 1.0, 10_000), MIN_BLOCKS);
    }

    #[test]
    fn long_records_keep_the_spectral_design() {
        let w = [2.0, 9.0];
        let base = super::design_corners(&w, 0.01, 6);
        assert_eq!(fit_corners(&w, 0.01, 2000.0, 4, 6), Some(base));
    }

    #[test]
    fn short_records_lift_the_slowest_corner_and_keep_the_span() {
        let w = [2.0, 9.0];
        let c = fit_corners(&w, 0.001, 25.0, 4, 6).unwrap();
        assert!((c[0] - 1.6 * 1.001).abs() < 1e-12, "{c:?}");
        assert!(min_duration(&c, 4) <= 25.0 + 1e-9);
        assert!(c[5] >= 8.0 * c[0] - 1e-9 && c[5] <= max_corner(0.001));
        // 1 s at 1 kHz still fits (λ_min = 40 rad/s, cap 314 rad/s); 0.2 s does not.
        assert!(fit_corners(&w, 0.001, 1.0, 4, 6).is_some());
        assert!(fit_corners(&w, 0.001, 0.2, 4, 6).is_none());
    }
}
