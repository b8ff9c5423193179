//! Rests: the intervals of a record where a body with a Coulomb term stands still.
//!
//! At rest the friction force of `r·sign(v)` lies anywhere in `±r` (it balances whatever
//! else acts), so the equation of motion the model states does not hold there, and every
//! moment that integrates over a rest carries the violation. The moments therefore leave
//! the rests out: every rest/motion transition is a block boundary, the blocks at rest
//! are dropped, and each run of motion is integrated like a record of its own, with the
//! boundary terms of the finite-record identities at its two ends (see the `moments`
//! module). The instruments are filter states that run through the rests: they are
//! functions of the data like any other, so the identities hold on every motion run
//! whatever the filters remember, and no settling margin is needed.
//!
//! A sample is at rest when the speed of a body that carries a `sign` of its own velocity
//! in a term with an unknown coefficient ([`bodies`]) is
//! at most [`REST_FRACTION`] of that body's RMS speed, and a rest is a run of such samples
//! at least [`MIN_REST`] long (a velocity reversal passes zero in a few samples and is
//! what `sign(v)` describes). The speed is the central difference of the measured
//! position (or the measured velocity), both measured in a first pass over the level.

use crate::data::{DataError, LevelSource};
use dynid_ir::ir::{Basis, BodyId, ExprNode, ModelIr, SignalKind, UnaryOp};
use rayon::prelude::*;
use serde::Serialize;

/// A sample is at rest below this fraction of the RMS speed.
pub const REST_FRACTION: f64 = 0.01;

/// Shortest rest that is left out, in seconds.
pub const MIN_REST: f64 = 0.05;

/// Rests are left out only where they hold at least this share of a level's samples. Rare
/// slow passages of a randomly excited record are mostly velocity reversals, which
/// `sign(v)` describes, and on quantised positions a reversal reads as a short rest
/// (leaving such passages out of the quantised records of `tests/velocity_estimate.rs`
/// moved `d` beyond its bound there); a planned trajectory with dwells rests for 19–40 %
/// of its samples. The velocity estimate fits its reversals on the same levels
/// ([`super::velocity`]).
pub const MIN_REST_SHARE: f64 = 0.05;

/// Rest intervals of a level: half-open sample ranges `[a, b)`, in order.
pub(crate) type Intervals = Vec<(usize, usize)>;

/// The rests left out of one level's moments.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct RestSummary {
    /// Rest intervals left out.
    pub intervals: usize,
    /// Samples inside them.
    pub samples: usize,
    /// Speed threshold per body (`(name, m/s or the unit of the position per second)`).
    pub threshold: Vec<(String, f64)>,
}

/// The bodies whose own velocity (against the ground) is the argument of a `sign` in a
/// term with an unknown coefficient (a friction to identify): a rest of such a body breaks
/// the model being fitted. (A `sign` of a relative velocity, between two bodies, is not
/// looked at: its rests are those of the difference, not of either body. A `sign` in a
/// known force, a guide's friction ripple of given size, is not either: leaving the rests
/// out for it would fit the model's unknowns on the motion alone, which only the friction
/// the model identifies needs — without that friction in the model, on a record with
/// dwells, the fit on motion alone is far worse than on the whole record.)
pub(crate) fn bodies(ir: &ModelIr) -> Vec<BodyId> {
    let unknown = ir.unknowns();
    let mut out = Vec::new();
    let identified = ir
        .equations
        .iter()
        .flat_map(|e| &e.terms)
        .filter(|t| t.coef.param.is_some_and(|p| unknown.contains(&p)))
        .filter_map(|t| match t.basis {
            Basis::Expr(x) => Some(x),
            Basis::Deriv { .. } => None,
        });
    for r in identified {
        let needed = ir.needed_nodes(&[r]);
        for (i, _) in needed.iter().enumerate().filter(|(_, n)| **n) {
            if let ExprNode::Unary(UnaryOp::Sign, a) = ir.exprs[i] {
                if let [s] = ir.expr_signals(a)[..] {
                    if let SignalKind::Velocity(b) = ir.signal(s).kind {
                        if !out.contains(&b) {
                            out.push(b);
                        }
                    }
                }
            }
        }
    }
    out.sort();
    out
}

/// The speed of one body: central differences of its position, or its measured velocity.
struct Speed {
    col: usize,
    from_velocity: bool,
    /// The last two positions before the current chunk (oldest first).
    prev: Vec<f64>,
}

impl Speed {
    /// `f(k, |v_k|)` for every sample whose speed is known once the chunk is read: a
    /// central difference knows sample `k` once `k + 1` is read, so every call reports
    /// samples `pos − 1 … pos + len − 2` (a measured velocity is reported with the same
    /// delay); the record's first and last samples get the one-sided difference.
    fn each(
        &mut self,
        cols: &[&[f64]],
        len: usize,
        pos: usize,
        ts: f64,
        f: &mut dyn FnMut(usize, f64),
    ) {
        let Some(c) = cols[self.col].get(..len) else {
            return; // (a signal the plan measures always has its column)
        };
        for (k, &x) in c.iter().enumerate() {
            let at = pos + k;
            match (self.from_velocity, self.prev.len()) {
                (_, 0) => {}
                (true, _) => f(at - 1, self.prev[self.prev.len() - 1].abs()),
                (false, 1) => f(at - 1, (x - self.prev[0]).abs() / ts),
                (false, _) => f(at - 1, (x - self.prev[0]).abs() / (2.0 * ts)),
            }
            if self.prev.len() == 2 {
                self.prev.remove(0);
            }
            self.prev.push(x);
        }
    }

    /// The last sample's speed, once the record has ended.
    fn last(&self, n: usize, ts: f64, f: &mut dyn FnMut(usize, f64)) {
        match (self.from_velocity, self.prev.len()) {
            (true, l) if l > 0 => f(n - 1, self.prev[l - 1].abs()),
            (false, 2) => f(n - 1, (self.prev[1] - self.prev[0]).abs() / ts),
            _ => {}
        }
    }
}

/// The rest intervals of one level as half-open sample ranges `[a, b)`, in order, with
/// their summary: runs below the threshold at least `min_rest` seconds (and two samples)
/// long, or with `min_rest` 0 every sample below it (the slow samples of the rows of the
/// filtered equation). Two passes over the level: the RMS speed of each body, then the runs below the
/// threshold.
///
/// Long: the two streamed passes share the per-body state they build.
pub(crate) fn find(
    ir: &ModelIr,
    bodies: &[BodyId],
    src: &dyn LevelSource,
    chunk: usize,
    min_rest: f64,
) -> Result<(Intervals, RestSummary), crate::data::DataError> {
    let ts = src.ts();
    let speeds = || -> Vec<Speed> {
        bodies
            .iter()
            .map(|&b| {
                let v = ir.velocity(b);
                let from_velocity = ir.signal(v).measured;
                Speed {
                    col: if from_velocity {
                        v.index()
                    } else {
                        ir.position(b).index()
                    },
                    from_velocity,
                    prev: Vec::with_capacity(2),
                }
            })
            .collect()
    };
    // Pass 1: RMS speed per body.
    let mut sp = speeds();
    let mut sum2 = vec![0.0; bodies.len()];
    let mut n = 0usize;
    src.stream(chunk, &mut |cols, len| {
        for (s, acc) in sp.iter_mut().zip(sum2.iter_mut()) {
            s.each(cols, len, n, ts, &mut |_, v| *acc += v * v);
        }
        n += len;
    })?;
    for (s, acc) in sp.iter().zip(sum2.iter_mut()) {
        s.last(n, ts, &mut |_, v| *acc += v * v);
    }
    let thr: Vec<f64> = sum2
        .iter()
        .map(|s| REST_FRACTION * (s / n.max(1) as f64).sqrt())
        .collect();
    // Pass 2: runs at rest (any body below its threshold). Samples arrive in order, one
    // body after the other per chunk, so the per-sample flags of a chunk are gathered first.
    // A rest needs two samples below the threshold; the slow samples of the filtered rows
    // (`min_rest` 0) count one by one, as a reversal between two samples often has one.
    let min_len = if min_rest > 0.0 {
        ((min_rest / ts).ceil() as usize).max(2)
    } else {
        1
    };
    let mut sp = speeds();
    let mut out = Vec::new();
    let mut run: Option<usize> = None;
    let mut flags: Vec<bool> = Vec::new();
    let mut close = |k: usize, at_rest: bool, run: &mut Option<usize>| match (at_rest, *run) {
        (true, None) => *run = Some(k),
        (false, Some(a)) => {
            if k - a >= min_len {
                out.push((a, k));
            }
            *run = None;
        }
        _ => {}
    };
    let mut pos = 0usize;
    src.stream(chunk, &mut |cols, len| {
        if len == 0 {
            return;
        }
        // Samples `lo .. hi` are reported by every body in this chunk.
        let lo = pos.saturating_sub(1);
        let hi = pos + len - 1;
        flags.clear();
        flags.resize(hi - lo, false);
        for (s, &t) in sp.iter_mut().zip(&thr) {
            s.each(cols, len, pos, ts, &mut |k, v| flags[k - lo] |= v <= t);
        }
        for (i, &f) in flags.iter().enumerate() {
            close(lo + i, f, &mut run);
        }
        pos += len;
    })?;
    if n > 0 {
        let mut last = false;
        for (s, &t) in sp.iter().zip(&thr) {
            s.last(n, ts, &mut |_, v| last |= v <= t);
        }
        close(n - 1, last, &mut run);
        close(n, false, &mut run);
    }
    let summary = RestSummary {
        intervals: out.len(),
        samples: out.iter().map(|(a, b)| b - a).sum(),
        threshold: bodies
            .iter()
            .zip(&thr)
            .map(|(b, t)| (ir.bodies[b.index()].name.clone(), *t))
            .collect(),
    };
    Ok((out, summary))
}

/// Block boundaries (`0 ..= n − 1`, in samples) and which blocks are kept: every rest
/// `[a, b)` is one dropped block from its first sample `a` to the first sample in motion
/// `b`, and every run of motion between them is cut into blocks of about
/// `(n − 1) / n_blocks` samples (at least one). (Boundaries one sample further inside the
/// rests, with the velocity there from a central difference — zero for a body that
/// sticks — gave a larger mass error on the planned servo records: 0.12 % against
/// 0.09 % RMS.)
pub(crate) fn layout(
    n: usize,
    n_blocks: usize,
    rests: &[(usize, usize)],
) -> (Vec<usize>, Vec<bool>) {
    let last = n - 1;
    let target = (last as f64 / n_blocks.max(1) as f64).max(1.0);
    let mut bounds = vec![0usize];
    let mut kept = Vec::new();
    let motion = |from: usize, to: usize, bounds: &mut Vec<usize>, kept: &mut Vec<bool>| {
        if to <= from {
            return;
        }
        let len = to - from;
        let k = ((len as f64 / target).round() as usize).clamp(1, len);
        for i in 1..=k {
            bounds.push(from + (i as u128 * len as u128 / k as u128) as usize);
            kept.push(true);
        }
    };
    let mut at = 0usize;
    for &(a, b) in rests {
        let (a, b) = (a.min(last), b.min(last));
        if b <= a {
            continue;
        }
        motion(at, a, &mut bounds, &mut kept);
        bounds.push(b);
        kept.push(false);
        at = b;
    }
    motion(at, last, &mut bounds, &mut kept);
    if kept.is_empty() {
        // A record of one sample interval: one (kept) block.
        bounds.push(last.max(1));
        kept.push(true);
    }
    (bounds, kept)
}

/// A level's rests to leave out (`None`: none are looked for), with their summary.
pub(crate) type LevelRests = Option<(Intervals, RestSummary)>;

/// Rests are left out only where they are a real share of the level
/// ([`MIN_REST_SHARE`]) and enough motion remains for the blocks of the standard
/// errors (a record that hardly moves is identified as it is).
pub(crate) fn left_out(
    r: &[(usize, usize)],
    summary: &RestSummary,
    n: usize,
    n_blocks: usize,
) -> bool {
    !r.is_empty()
        && summary.samples as f64 >= MIN_REST_SHARE * n as f64
        && n.saturating_sub(summary.samples) >= n_blocks.saturating_mul(4)
}

/// Rests of bodies with a Coulomb term, per level (see the module documentation): found, and emptied where
/// they are not left out ([`rests_left_out`]). For the rows of the filtered equation
/// (`slow`) every slow sample counts, however short its run (a reversal too: there the
/// filtered `sign(v̂)` carries the estimate's timing error for the filter's memory), and
/// every level leaves them out.
pub(crate) fn find_levels(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    samples: &[usize],
    n_blocks: usize,
    keep_rests: bool,
    slow: bool,
    chunk: usize,
) -> Result<Vec<LevelRests>, DataError> {
    let rest_bodies = if keep_rests { Vec::new() } else { bodies(ir) };
    let found: Vec<LevelRests> = if rest_bodies.is_empty() {
        vec![None; levels.len()]
    } else {
        crate::first_error_in_order(levels.par_iter().map(|src| {
            let min_rest = if slow { 0.0 } else { MIN_REST };
            find(ir, &rest_bodies, *src, chunk, min_rest).map(Some)
        }))?
    };
    Ok(found
        .into_iter()
        .zip(samples)
        .map(|(f, &n)| {
            f.map(|(r, summary)| {
                if slow || r.is_empty() || left_out(&r, &summary, n, n_blocks) {
                    (r, summary)
                } else {
                    (
                        Vec::new(),
                        RestSummary {
                            intervals: 0,
                            samples: 0,
                            ..summary
                        },
                    )
                }
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_puts_every_transition_on_a_boundary_and_drops_the_rests() {
        let (b, k) = layout(1001, 10, &[(0, 50), (300, 420), (990, 1001)]);
        assert_eq!(b.first(), Some(&0));
        assert_eq!(b.last(), Some(&1000));
        assert_eq!(b.len(), k.len() + 1);
        assert!(b.windows(2).all(|w| w[1] > w[0]));
        for (i, w) in b.windows(2).enumerate() {
            let rest = (w[0] == 0 && w[1] == 50) || (w[0] == 300 && w[1] == 420) || w[0] == 990;
            assert_eq!(k[i], !rest, "block {w:?}");
        }
        // Without rests: the uniform blocks.
        let (b, k) = layout(1001, 10, &[]);
        assert_eq!(b, (0..=10).map(|i| i * 100).collect::<Vec<_>>());
        assert!(k.iter().all(|k| *k));
    }

    /// A reversal between two samples leaves one slow sample (the central difference that
    /// straddles it): a rest needs two and `MIN_REST`, the filtered rows' slow samples
    /// count it alone.
    #[test]
    fn a_single_slow_sample_counts_only_for_the_filtered_rows() {
        // Position and force measured, Coulomb friction on `m`.
        let ir = crate::sim::test_models::ServoAxis::standard().model();
        // A triangle wave of position, 1 mm per sample up then down: the central
        // difference is zero at each turn, and 1 m/s everywhere else.
        let ts = 1e-3;
        let x: Vec<f64> = (0..400)
            .map(|k| {
                let p = k % 100;
                1e-3 * if p <= 50 { p } else { 100 - p } as f64
            })
            .collect();
        let rec = crate::record::Record {
            names: vec!["m.x".into(), "u".into()],
            columns: vec![x, vec![0.0; 400]],
            ts,
            t0: 0.0,
        };
        let src = crate::data::RecordSource::new(&rec, &ir, "axis").expect("valid record");
        let bodies = bodies(&ir);
        let (rests, _) = find(&ir, &bodies, &src, 64, MIN_REST).unwrap();
        assert!(rests.is_empty(), "{rests:?}");
        let (slow, summary) = find(&ir, &bodies, &src, 64, 0.0).unwrap();
        // The turns at 50, 150, 250, 350 (at 100, 200, 300 the wave turns too).
        assert_eq!(slow.len(), 7, "{slow:?}");
        assert!(slow.iter().all(|(a, b)| b - a == 1), "{slow:?}");
        assert_eq!(summary.samples, 7);
    }
}
