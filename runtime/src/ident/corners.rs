//! The corner check: the identification repeated with the highest filter corner moved down
//! and up, and the parameters whose estimates move with it.

use super::identify::identify;
use super::print;
use super::types::{CornerMove, Identification, IdentifyError, IdentifyOptions};
use crate::data::LevelSource;
use dynid_ir::ir::ModelIr;

/// Factor by which [`corner_moves`] moves the highest filter corner down and up.
pub const CORNER_CHECK_FACTOR: f64 = 4.0;

/// The smallest relative move [`CornerMove::moved`] reports: on clean simulated records
/// the discretisation alone moves estimates by about 0.05 % over the corners, many times
/// their standard errors there (`tests/silent_nonsense.rs`), which is no model error worth a
/// warning.
pub const CORNER_CHECK_MIN_REL: f64 = 0.01;

impl CornerMove {
    /// The estimate moves by more than the standard error of either estimate it is
    /// compared with, and by more than [`CornerMove::min_move`] ([`CORNER_CHECK_MIN_REL`]
    /// of its value; of the sample interval for an input's delay: a delay of 50 µs that
    /// moves by 1 µs at 1 kHz is no model error worth a warning).
    pub fn moved(&self) -> bool {
        (0..3).step_by(2).any(|k| {
            let tol = self.stderrs[1].max(self.stderrs[k]).max(self.min_move);
            (self.values[k] - self.values[1]).abs() > tol
        })
    }

    /// One line for the report: the parameter, its range over the corners and its
    /// standard error.
    pub fn describe(&self) -> String {
        let lo = self.values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self
            .values
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        format!(
            "`{}` moves with the filter corners: {} … {} (standard error {}) over the highest \
             corner {} … {} rad/s — a model error at some frequencies, or noise above the band \
             the data carry",
            self.param,
            print::fmt_num(lo),
            print::fmt_num(hi),
            print::fmt_num(self.stderrs[1]),
            print::fmt_num(self.upper[0]),
            print::fmt_num(self.upper[2]),
        )
    }
}

/// The corner check as `dynid identify` and Python's `Model.identify` run it: the
/// [`corner_moves`] of `id` whose estimate moved ([`CornerMove::moved`]), stored in
/// `id.filter.corner_moves`. Skipped for a model with shape parameters (their profile is
/// itself many identifications); a check that fails (a corner the record cannot carry)
/// leaves the list empty and no warning.
pub fn check_corners(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
    id: &mut Identification,
) {
    if !ir.shapes.is_empty() {
        return;
    }
    if let Ok(moves) = corner_moves(ir, levels, opts, id) {
        id.filter.corner_moves = moves.into_iter().filter(CornerMove::moved).collect();
    }
}

/// The identification `id` (made with `opts` from `levels`) repeated with the highest
/// corner a factor [`CORNER_CHECK_FACTOR`] below and above, the other corners log-spaced
/// again from the same lowest corner; the raised corner stays below half the Nyquist
/// frequency (the filtered equation's one corner: below `0.5/Tₛ`). Per parameter of `id`
/// estimated in all three. Costs up to two further identifications (none for a corner
/// that a cap keeps where it is).
pub fn corner_moves(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
    id: &Identification,
) -> Result<Vec<CornerMove>, IdentifyError> {
    let c = &id.filter.corners;
    let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = c.iter().copied().fold(0.0, f64::max);
    let ts = id.levels.iter().map(|l| l.ts).fold(f64::INFINITY, f64::min);
    let spread = |top: f64| -> Vec<f64> {
        let n = c.len();
        if n == 1 {
            return vec![top];
        }
        (0..n)
            .map(|i| lo * (top / lo).powf(i as f64 / (n - 1) as f64))
            .collect()
    };
    // The filtered equation's one corner: moved on its own; raised at most to the cap of
    // its design (`0.5/Tₛ`; `0.25/Tₛ` with the inputs' delays on a chain given fewer than
    // six sections), where the force's path between samples starts to bias the mass.
    let (floor, cap) = match opts.filtered {
        true => (0.0, super::filtered::max_lt(opts, id.filter.order) / ts),
        false => (lo * 2.0, 0.5 * std::f64::consts::PI / ts),
    };
    let down = spread((hi / CORNER_CHECK_FACTOR).max(floor).min(hi));
    let up = spread((hi * CORNER_CHECK_FACTOR).min(cap).max(hi));
    let alt = |corners: Vec<f64>| {
        identify(
            ir,
            levels,
            &IdentifyOptions {
                corners: Some(corners),
                ..opts.clone()
            },
        )
    };
    // One after the other: a level read once from a pipe streams its kept copy to one
    // reader at a time. A moved corner that did not move (at a cap) is `id` itself.
    let moved = |corners: &Vec<f64>| -> Result<Option<Identification>, IdentifyError> {
        match corners == c {
            true => Ok(None),
            false => alt(corners.clone()).map(Some),
        }
    };
    let (a, b) = (moved(&down)?, moved(&up)?);
    // A moved corner at which a parameter that `id` identified is not identifiable (the
    // filtered equation's one corner lowered until an offset and a Coulomb friction are no
    // longer told apart, the friction then taking up the offset) compares other models:
    // that side is left out, as a corner that does not move.
    let top = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let (a, lo_top) = side(id, &a, top(&down), hi);
    let (b, hi_top) = side(id, &b, top(&up), hi);
    Ok(id
        .params
        .iter()
        .filter_map(|p| {
            let (pa, pb) = (a.param(&p.name)?, b.param(&p.name)?);
            Some(CornerMove {
                min_move: min_move(&p.name, p.value, ts),
                param: p.name.clone(),
                values: [pa.value, p.value, pb.value],
                stderrs: [pa.stderr, p.stderr, pb.stderr],
                upper: [lo_top, hi, hi_top],
            })
        })
        .collect())
}

/// One side of the corner check: the identification at the moved corner (highest corner
/// `top`) where it identifies at least what `id` did, else `id` itself at its own highest
/// corner `hi` (a corner that did not move, or one that compares another model).
fn side<'a>(
    id: &'a Identification,
    alt: &'a Option<Identification>,
    top: f64,
    hi: f64,
) -> (&'a Identification, f64) {
    match alt {
        Some(a) if a.identifies_as_much_as(id) => (a, top),
        _ => (id, hi),
    }
}

/// The smallest move of parameter `name` (estimated `value`) that [`CornerMove::moved`]
/// counts: [`CORNER_CHECK_MIN_REL`] of the value, or of the sample interval `ts` for an
/// input's delay, whose value may be near zero and whose scale is the sample interval.
fn min_move(name: &str, value: f64, ts: f64) -> f64 {
    let scale = match super::input_delay::is_delay(name) {
        true => ts,
        false => value.abs(),
    };
    CORNER_CHECK_MIN_REL * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The delay of the README's servo record (1 kHz): 5.007e-5 s ± 1.9e-7 s at the
    /// designed corner, 5.085e-5 s with it raised — 1.6 % of its value, 0.08 % of the
    /// sample interval: no warning; a friction coefficient that moves 1.6 % beyond its
    /// standard error is one.
    #[test]
    fn a_delay_moves_on_the_scale_of_the_sample_interval() {
        let mv = |name: &str, values: [f64; 3], se: f64| CornerMove {
            param: name.into(),
            values,
            stderrs: [se; 3],
            upper: [62.5, 250.0, 500.0],
            min_move: min_move(name, values[1], 1e-3),
        };
        assert!(!mv("u.delay", [5.0e-5, 5.007e-5, 5.085e-5], 1.9e-7).moved());
        assert!(mv("u.delay", [5.0e-5, 5.007e-5, 2.5e-4], 1.9e-7).moved());
        assert!(mv("r", [15.0, 15.0, 15.24], 0.01).moved());
        assert!(!mv("r", [15.0, 15.0, 15.1], 0.01).moved());
    }
}
