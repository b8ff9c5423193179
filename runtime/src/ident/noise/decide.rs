//! Which noise corrections an identification makes, decided from the first-pass
//! statistics of every level.

use super::correct::{attach, uncorrected};
use super::fix::form_variance;
use super::{NoiseSummary, SIGNIFICANT};
use crate::ident::first_pass::LevelStats;
use crate::ident::plan::Plan;
use dynid_ir::ir::{ModelIr, SignalId};

/// Whether the noise corrections are attached to the plan: the correction is on and a
/// measured signal carries significant noise at some level (a decision over all levels,
/// which a moment design carries, see [`crate::ident::MomentDesign`]).
pub(crate) fn needs_fixes(plan: &Plan, stats: &[LevelStats], enabled: bool) -> bool {
    enabled && (0..plan.y.len()).any(|k| stats.iter().any(|st| significant(st, k)))
}

/// Whether the noise of measured signal `k` at a level is significant.
fn significant(st: &LevelStats, k: usize) -> bool {
    st.noise_flat[k] && st.std[k] > 0.0 && st.noise_var[k].sqrt() >= SIGNIFICANT * st.std[k]
}

/// Decide the noise corrections from the first-pass statistics: attach them to the plan
/// where `fixes` (see [`needs_fixes`]: a signal in a nonlinear term carries significant
/// noise at some level of the design's data), and return per level the
/// noise variance of each measured signal to correct for (zero where it is not
/// significant or the correction is off), with the summary for the report.
pub(crate) fn decide_designed(
    ir: &ModelIr,
    plan: &mut Plan,
    stats: &[LevelStats],
    enabled: bool,
    fixes: bool,
) -> (Vec<Vec<f64>>, NoiseSummary) {
    let noisy: Vec<SignalId> = (0..plan.y.len())
        .filter(|&k| stats.iter().any(|st| significant(st, k)))
        .map(|k| plan.y[k])
        .collect();
    let mut summary = NoiseSummary {
        fraction: plan
            .y
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let f = stats
                    .iter()
                    .map(|st| {
                        if st.std[k] > 0.0 {
                            st.noise_var[k].sqrt() / st.std[k]
                        } else {
                            0.0
                        }
                    })
                    .fold(0.0, f64::max);
                (ir.signal(*s).name.clone(), f)
            })
            .collect(),
        enabled,
        uncertain: (0..plan.y.len())
            .filter(|&k| stats.iter().any(|st| !st.noise_flat[k]))
            .map(|k| ir.signal(plan.y[k]).name.clone())
            .collect(),
        ..Default::default()
    };
    if fixes {
        attach(plan, ir);
    }
    summary.uncorrected = uncorrected(plan, ir, &noisy);
    let var = stats
        .iter()
        .map(|st| {
            (0..plan.y.len())
                .map(|k| {
                    if enabled && significant(st, k) {
                        st.noise_var[k]
                    } else {
                        0.0
                    }
                })
                .collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>();
    for f in &plan.fixes {
        if var.iter().any(|v| form_variance(&f.lin, v) > 0.0) {
            summary.corrected.push(f.label.clone());
        }
    }
    (var, summary)
}
