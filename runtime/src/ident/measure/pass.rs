//! The streamed pass of the measuring step: every level once through the filters, its
//! moments accumulated and de-biased; and what the report says of each level.

use super::checks::{column_label, non_finite_term};
use crate::basis::BasisEval;
use crate::data::LevelSource;
use crate::ident::accumulate::LevelAccumulator;
use crate::ident::filtered;
use crate::ident::first_pass::LevelStats;
use crate::ident::moments::{LevelMoments, PhaseTimes};
use crate::ident::noise;
use crate::ident::plan::Plan;
use crate::ident::rests::{self, Intervals, LevelRests, RestSummary};
use crate::ident::types::CENTRED_REL;
use crate::ident::types::{IdentifyError, IdentifyOptions, LevelInfo};
use crate::ident::velocity::EstimatedVelocity;
use dynid_ir::ir::ModelIr;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// What the streamed pass of every level shares.
pub(super) struct Pass<'a> {
    pub(super) ir: &'a ModelIr,
    pub(super) eval: &'a dyn BasisEval,
    pub(super) plan: &'a Plan,
    pub(super) n_blocks: usize,
    pub(super) opts: &'a IdentifyOptions,
}

impl Pass<'_> {
    /// Every level's pass (in parallel): the moments in order and the times summed over
    /// the levels.
    pub(super) fn all(
        &self,
        sources: &[&dyn LevelSource],
        stats: &[LevelStats],
        noise_var: &[Vec<f64>],
        rests: &[LevelRests],
        estimators: &[EstimatedVelocity<'_>],
    ) -> Result<(Vec<LevelMoments>, PhaseTimes), IdentifyError> {
        let results: Vec<(LevelMoments, PhaseTimes)> = crate::first_error_in_order(
            sources
                .par_iter()
                .zip(stats)
                .zip(noise_var)
                .zip(rests)
                .enumerate()
                .map(|(level, (((src, st), var), rest))| {
                    // Delayed column drivers wait out the widest velocity window of the level.
                    let widest = estimators
                        .get(level)
                        .map_or(0, |e| e.designs().iter().map(|d| d.2).max().unwrap_or(0));
                    self.level(*src, st, var, rest.as_ref(), widest)
                }),
        )?;
        let mut times = PhaseTimes::default();
        let mut moments = Vec::new();
        for (m, t) in results {
            times += t;
            moments.push(m);
        }
        Ok((moments, times))
    }

    /// Stream one level through the filters and accumulate its moments, de-biased for the
    /// noise variances `var`; `widest` is the widest velocity window of the level.
    fn level(
        &self,
        src: &dyn LevelSource,
        st: &LevelStats,
        var: &[f64],
        rest: Option<&(Intervals, RestSummary)>,
        widest: usize,
    ) -> Result<(LevelMoments, PhaseTimes), IdentifyError> {
        let (ir, plan, opts) = (self.ir, self.plan, self.opts);
        let mut acc = match rest {
            _ if plan.filtered => {
                let forget =
                    |tol| filtered::forget_samples(plan.corners[0], plan.order, st.ts, tol);
                let r = rest.map_or(&[][..], |(r, _)| &r[..]);
                let (start, after) = (forget(filtered::START_TOL), forget(filtered::REST_TOL));
                let out = filtered::left_out(r, st.n, start, after);
                let (bounds, kept) = rests::layout(st.n, self.n_blocks, &out);
                if kept.iter().filter(|k| **k).count() < 2 {
                    return Err(IdentifyError::BadOption {
                        message: format!(
                            "{}: the rows of the filtered equation leave out the first {start} \
                             samples and each rest with the {after} after it, and too little \
                             of this level remains",
                            src.origin()
                        ),
                        help: "use a higher corner (--filter-corners, rad/s), longer records, \
                               or the instrument rows (the default)"
                            .into(),
                    });
                }
                LevelAccumulator::with_blocks(plan, self.eval, st.ts, st.n, bounds, kept, opts.hold)
            }
            Some((r, summary)) if rests::left_out(r, summary, st.n, self.n_blocks) => {
                let (bounds, kept) = rests::layout(st.n, self.n_blocks, r);
                LevelAccumulator::with_blocks(plan, self.eval, st.ts, st.n, bounds, kept, opts.hold)
            }
            _ => LevelAccumulator::new(plan, self.eval, st.ts, st.n, self.n_blocks, opts.hold),
        };
        acc.set_root_delay(widest + 1);
        acc.set_extra_widths(noise::extra_widths(plan, &st.noise_var, &st.std));
        let mut read = Duration::ZERO;
        let mut t_read = Instant::now();
        src.stream(opts.chunk_len, &mut |cols, len| {
            read += t_read.elapsed();
            acc.push(cols, len);
            t_read = Instant::now();
        })?;
        if let Some((root, k, value)) = acc.non_finite {
            return Err(non_finite_term(ir, plan, src, root, k, value));
        }
        let (mut m, mut t) = acc.finish();
        if let Some(col) = m.overflowed_column() {
            return Err(IdentifyError::Overflow {
                origin: src.origin(),
                term: column_label(ir, plan, col),
            });
        }
        noise::debias(plan, &mut m, var, opts.hold);
        t.read = read;
        Ok((m, t))
    }
}

/// What the report says of each level.
pub(super) fn level_infos(
    ir: &ModelIr,
    plan: &Plan,
    stats: &[LevelStats],
    levels: &[&dyn LevelSource],
    moments: &[LevelMoments],
    rests: &[LevelRests],
) -> Vec<LevelInfo> {
    let named = |values: &[f64], f: fn(f64) -> f64| {
        plan.y
            .iter()
            .zip(values)
            .map(|(sig, v)| (ir.signal(*sig).name.clone(), f(*v)))
            .collect()
    };
    stats
        .iter()
        .zip(levels)
        .zip(moments)
        .zip(rests)
        .map(|(((s, src), m), rest)| LevelInfo {
            origin: src.origin(),
            samples: s.n,
            ts: s.ts,
            std: named(&s.std, |v| v),
            mean: named(&s.mean, |v| v),
            noise: named(&s.noise_var, f64::sqrt),
            blocks: m.kept_blocks(),
            rests: rest.as_ref().map(|(_, summary)| summary.clone()),
        })
        .collect()
}

/// Per level: whether every signal driving the filters has zero mean (see [`CENTRED_REL`]).
pub(super) fn centred_levels(plan: &Plan, stats: &[LevelStats]) -> Vec<bool> {
    stats
        .iter()
        .map(|s| {
            plan.drivers.iter().all(|d| {
                plan.y_of[d.index()].is_none_or(|k| {
                    s.mean[k].abs() <= CENTRED_REL * s.std[k].max(f64::MIN_POSITIVE)
                })
            })
        })
        .collect()
}
