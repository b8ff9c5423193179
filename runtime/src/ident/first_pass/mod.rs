//! The first pass over every level: per measured signal its length, mean and spread, its
//! dominant frequency (from the rate of crossings of a reference band, Rice:
//! `ω₀ = π N₀ / T`), its white-noise floor and the band where it stands above that floor
//! ([`floor`]); and a screen that refuses a level without motion, with a sample far outside
//! its column's spread ([`screen`]) or with a column too small for double precision.
//!
//! The statistics choose the filter corners (see [`super::design`]), the time blocks, and
//! the noise corrections (see [`super::noise`]).

pub mod floor;
pub mod screen;
mod signal;

use super::plan::Plan;
use super::types::IdentifyError;
use crate::data::LevelSource;
use dynid_ir::ir::ModelIr;
use rayon::prelude::*;
use screen::ColumnScreen;
use signal::SignalPass;

/// First-pass statistics of a level: length, spread, dominant frequencies.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct LevelStats {
    pub n: usize,
    pub ts: f64,
    pub std: Vec<f64>,
    /// Mean per measured signal.
    pub mean: Vec<f64>,
    pub omegas: Vec<f64>,
    /// Estimated white-noise variance per measured signal.
    pub noise_var: Vec<f64>,
    /// Whether that estimate comes from a flat floor ([`floor::NoiseFloor::flat`]).
    pub noise_flat: Vec<bool>,
    /// Per measured signal: the highest frequency (rad/s) where it stands above its noise
    /// floor ([`floor::BandFloor::info_bandwidth`]).
    pub info: Vec<Option<f64>>,
}
/// The extent of the levels: the shortest bounds the slowest filter, the fastest and the
/// slowest sampling bound the corners.
pub(crate) struct LevelSpan {
    /// Duration of the shortest level (s).
    pub min_duration: f64,
    /// Shortest and longest sample interval (s).
    pub ts_min: f64,
    pub ts_max: f64,
    /// Samples of the shortest level.
    pub min_samples: usize,
}

impl LevelSpan {
    pub(crate) fn of(stats: &[LevelStats]) -> LevelSpan {
        LevelSpan {
            min_duration: stats
                .iter()
                .map(|s| s.n.saturating_sub(1) as f64 * s.ts)
                .fold(f64::INFINITY, f64::min),
            ts_min: stats.iter().map(|s| s.ts).fold(f64::INFINITY, f64::min),
            ts_max: stats.iter().map(|s| s.ts).fold(0.0, f64::max),
            min_samples: stats.iter().map(|s| s.n).min().unwrap_or(0),
        }
    }
}

/// The first pass over every level (in parallel), each level's statistics in order; on
/// failure the error of the first failing level.
pub(crate) fn all_levels(
    ir: &ModelIr,
    plan: &Plan,
    levels: &[&dyn LevelSource],
    chunk: usize,
) -> Result<Vec<LevelStats>, IdentifyError> {
    crate::first_error_in_order(
        levels
            .par_iter()
            .map(|src| level_stats(ir, plan, *src, chunk)),
    )
}

/// The first pass over one level: its statistics, after the screens.
fn level_stats(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    chunk: usize,
) -> Result<LevelStats, IdentifyError> {
    let ny = plan.y.len();
    let mut n = 0usize;
    // Each signal on its own, and each chunk of it in pieces (in parallel: a level's
    // signals and pieces balance the threads when the levels alone do not).
    let mut sigs: Vec<SignalPass> = (0..ny).map(|_| SignalPass::default()).collect();
    src.stream(chunk, &mut |cols, len| {
        sigs.par_iter_mut()
            .zip(&plan.y)
            .for_each(|(st, s)| st.push(&cols[s.index()][..len], n == 0));
        n += len;
    })?;
    let screens: Vec<ColumnScreen> = sigs
        .iter_mut()
        .map(|st| std::mem::take(&mut st.screen))
        .collect();
    let nf = n.max(1) as f64;
    let std: Vec<f64> = sigs
        .iter()
        .map(|st| {
            let m = st.s1 / nf;
            (st.s2 / nf - m * m).max(0.0).sqrt()
        })
        .collect();
    let mean: Vec<f64> = sigs.iter().map(|st| st.shift + st.s1 / nf).collect();
    check_magnitudes(ir, plan, src, &std, &mean)?;
    screen_level(ir, plan, src, &screens)?;
    let ts = src.ts();
    let duration = (n.max(2) - 1) as f64 * ts;
    Ok(LevelStats {
        n,
        ts,
        std,
        mean,
        omegas: sigs
            .iter()
            .zip(&plan.y)
            .filter(|(st, s)| plan.drivers.contains(s) && st.crossings > 0)
            .map(|(st, _)| std::f64::consts::PI * st.crossings as f64 / duration)
            .collect(),
        noise_var: sigs.iter().map(|st| st.floor.variance()).collect(),
        noise_flat: sigs.iter().map(|st| st.floor.flat()).collect(),
        info: sigs
            .iter()
            .map(|st| st.band.info_bandwidth(st.floor.variance(), ts))
            .collect(),
    })
}

/// Smallest magnitude (larger of spread and mean) of a measured column that is not zero:
/// the moments are products of filtered signals, and below this their squares leave the
/// normal range of double precision (about 2e-308), where precision is lost digit by digit
/// and row weights become infinite.
pub(crate) const TINY_SIGNAL: f64 = 1e-150;

/// Refuse a level with a column so small that the products of its values underflow double
/// precision (units legitimately scale data, but not by 10^-150).
fn check_magnitudes(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    std: &[f64],
    mean: &[f64],
) -> Result<(), IdentifyError> {
    for (k, (s, m)) in std.iter().zip(mean).enumerate() {
        let size = s.max(m.abs());
        if size > 0.0 && size < TINY_SIGNAL {
            return Err(IdentifyError::Underflow {
                origin: src.origin(),
                column: ir.signal(plan.y[k]).name.clone(),
                size,
            });
        }
    }
    Ok(())
}

/// Refuse a level without motion or with a sample far outside its column's spread
/// ([`screen`]).
fn screen_level(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    screens: &[ColumnScreen],
) -> Result<(), IdentifyError> {
    let ir_name = |k: usize| ir.signal(plan.y[k]).name.clone();
    if !screens.is_empty() && screens.iter().all(|s| s.constant()) {
        return Err(IdentifyError::NoExcitation {
            origin: src.origin(),
            columns: (0..screens.len())
                .map(|k| format!("`{}`", ir_name(k)))
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    for (k, sc) in screens.iter().enumerate() {
        if let Some(o) = sc.outlier() {
            let num = |v: f64| dynid_ir::num::sig(v, 4, false);
            return Err(IdentifyError::Outlier {
                origin: src.origin(),
                at: src.locate(o.sample),
                sample: o.sample,
                column: ir_name(k),
                detail: format!(
                    "{} lies {:.1e} robust standard deviations from the column's median \
                     ({}, robust std {})",
                    num(o.value),
                    (o.value - o.median).abs() / o.scale,
                    num(o.median),
                    num(o.scale)
                ),
            });
        }
    }
    Ok(())
}
