//! The acceptance rules and the verdict: when a candidate (or a pair) shrinks the gap
//! materially, when a constant force counts although the statistical gap cannot see it,
//! whether the found effects are needed at all, and what the diagnosis concludes.

use super::effects::Effect;
use super::fit::Fitted;
use super::format::fmt_gap;
use super::types::{CandidateScore, DiagnoseOptions, FoundEffect, ModelGap, Verdict};
use dynid_ir::ir::ModelIr;

/// Statistical gap (%) below which a model matches the data.
pub(super) const CONSISTENT_GAP: f64 = 5.0;

/// Whether the gap falls materially from `before` to `after` (both in %): by more than the
/// absolute and the relative acceptance margins; any finite gap beats a diverged one.
fn material(before: f64, after: f64, opts: &DiagnoseOptions) -> bool {
    let shrink_abs = before - after;
    after.is_finite()
        && (before == f64::INFINITY
            || (shrink_abs > opts.min_abs_shrink && shrink_abs > opts.min_rel_shrink * before))
}

/// The constant-force rule. The statistical gap compares spectra and standard deviations
/// and does not see a signal's mean — all that a constant force changes in a model that
/// holds otherwise. A model with a constant force is therefore judged on the pathwise gap,
/// as long as its statistical gap stays that of a matching model: below
/// [`CONSISTENT_GAP`], or no more than the acceptance margin `min_abs_shrink` above the
/// gap `before` it (this function). The search accepts it when its pathwise gap then falls
/// materially ([`by_mean`]); the whole search keeps it when its pathwise gap is below the
/// nominal model's ([`effects_needed`]).
fn still_matches(before: f64, after: f64, opts: &DiagnoseOptions) -> bool {
    after.is_finite() && (after < CONSISTENT_GAP || after <= before + opts.min_abs_shrink)
}

/// A model holding a constant force, accepted by the constant-force rule from `current`.
fn by_mean(current: &ModelGap, g: &ModelGap, opts: &DiagnoseOptions) -> bool {
    still_matches(current.gap, g.gap, opts) && material(current.pathwise, g.pathwise, opts)
}

/// The candidate a search step accepts among the `results` ranked by the cross-validated
/// covariance residual, of which those in `gaps` have a withheld free-run gap; `current`
/// is the gap of the model the step starts from. Writes each deciding note into the
/// ranking. The best by free-run gap is accepted when its gap falls materially; free-run
/// gaps within 10 % of the best are a tie (a wide dead zone mimics a cubic spring), which
/// the covariance residual, seeing every instrument, breaks. When the best is not
/// material, the constant force with the smallest pathwise gap that the constant-force
/// rule accepts is.
pub(super) fn accept(
    results: &mut [Fitted],
    gaps: &[(usize, ModelGap)],
    current: &ModelGap,
    opts: &DiagnoseOptions,
) -> Option<usize> {
    let best_gap = gaps.iter().map(|g| g.1.gap).fold(f64::INFINITY, f64::min);
    let best = gaps
        .iter()
        .filter(|(_, g)| g.gap <= 1.1 * best_gap)
        .min_by(|a, b| {
            results[a.0]
                .score
                .cv_residual
                .total_cmp(&results[b.0].score.cv_residual)
        })
        .map(|(i, _)| *i);
    let gap_of = |i: usize| &gaps.iter().find(|g| g.0 == i).expect("invariant: scored").1;
    let by_statistics = best.filter(|&i| material(current.gap, gap_of(i).gap, opts));
    let accepted = by_statistics.or_else(|| {
        gaps.iter()
            .map(|g| g.0)
            .filter(|&i| {
                results[i].score.effect == Effect::ConstantForce
                    && by_mean(current, gap_of(i), opts)
            })
            .min_by(|&a, &b| gap_of(a).pathwise.total_cmp(&gap_of(b).pathwise))
    });
    if let Some(i) = best.filter(|&b| Some(b) != accepted) {
        results[i].score.note = format!(
            "gap {} vs {} without it: not a material reduction",
            fmt_gap(gap_of(i).gap),
            fmt_gap(current.gap)
        );
    }
    if let Some(i) = accepted {
        let g = gap_of(i);
        results[i].score.accepted = true;
        results[i].score.note = if Some(i) == by_statistics {
            "accepted".into()
        } else {
            format!(
                "accepted: a mean the statistical gap does not see (pathwise {} → {})",
                fmt_gap(current.pathwise),
                fmt_gap(g.pathwise)
            )
        };
    }
    accepted
}

/// Whether a pair (both coefficients significant with a physical sign) with the withheld
/// gap `g` is accepted from `current`: its gap falls materially, or, for a pair holding a
/// constant force, the constant-force rule accepts it.
pub(super) fn accept_pair(
    scores: &[CandidateScore; 2],
    g: &ModelGap,
    current: &ModelGap,
    opts: &DiagnoseOptions,
) -> bool {
    let has_constant_force = scores.iter().any(|c| c.effect == Effect::ConstantForce);
    material(current.gap, g.gap, opts) || (has_constant_force && by_mean(current, g, opts))
}

/// Whether the effects `found` by the whole search, leaving the gap `after`, are needed.
/// Effects that leave the gap larger than the `nominal` model's, where that already
/// matches, are no finding: the re-identified parameters moved away from a model that
/// holds (a biased fit, e.g. on data with a sensor offset), and the effects only made up
/// part of that move (a gap that is not a number is not smaller either). Judged on the
/// whole search, not step by step: a constant force and a friction both missing each
/// leave part of the bias until the other is added. By the constant-force rule
/// ([`still_matches`]) a constant force whose corrected model still matches and follows
/// the measured paths more closely (pathwise gap) is a finding — on a body no force of
/// which depends on its position: on one held by a spring, a zero offset `x0` of the
/// position sensor gives the same mean as a constant force `−k·x0`, and the guard's note
/// names both.
pub(super) fn effects_needed(
    ir: &ModelIr,
    found: &[FoundEffect],
    nominal: &ModelGap,
    after: &ModelGap,
    opts: &DiagnoseOptions,
) -> bool {
    let nominal_matches = nominal.gap < CONSISTENT_GAP;
    if found.is_empty() || !nominal_matches {
        return true;
    }
    let smaller = after.gap < nominal.gap;
    let mean_shown = found.iter().any(|f| {
        f.effect == Effect::ConstantForce
            && !crate::ident::guard::position_dependent(ir, Some(&f.location.b))
    }) && still_matches(nominal.gap, after.gap, opts)
        && after.pathwise < nominal.pathwise;
    smaller || mean_shown
}

/// The note that drops the effects `found` as not needed ([`effects_needed`]).
pub(super) fn unneeded_note(found: &[FoundEffect], nominal: &ModelGap, after: &ModelGap) -> String {
    let names: Vec<String> = found
        .iter()
        .map(|f| format!("{} at {}", f.effect.name(), f.location.label()))
        .collect();
    format!(
        "the nominal model already matches the data (gap {}); the re-identified \
         model with the best effect{} ({}) leaves a larger gap ({}), so no effect is \
         needed — the re-identified parameters are biased (see the identification \
         warnings)",
        fmt_gap(nominal.gap),
        if found.len() > 1 { "s" } else { "" },
        names.join(", "),
        fmt_gap(after.gap)
    )
}

/// What the diagnosis concludes from the gaps of the `nominal` and `reidentified` models
/// and whether an effect was found.
pub(super) fn verdict(
    nominal: &ModelGap,
    reidentified: &ModelGap,
    found_any: bool,
    opts: &DiagnoseOptions,
) -> Verdict {
    let gap_before = nominal.gap;
    if found_any {
        Verdict::MissingEffect
    } else if reidentified.gap < 0.5 * gap_before && gap_before > opts.min_abs_shrink * 2.0 {
        if reidentified.gap < CONSISTENT_GAP {
            Verdict::MistunedParameters
        } else {
            Verdict::Unexplained
        }
    } else if reidentified.gap.min(gap_before) < CONSISTENT_GAP {
        Verdict::Consistent
    } else {
        Verdict::Unexplained
    }
}
