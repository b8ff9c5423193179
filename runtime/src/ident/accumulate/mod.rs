//! Streaming accumulation of the raw cross moments of one excitation level (see
//! [`super::moments`] for what they are and how they are read).
//!
//! Per sample the only work is: evaluate the static basis `g`, advance the filter bank `ζ`,
//! and add `ι wᵀ` (with `ι = [ζ; y]`, `w = [g; y]`) to the sum of the current time block —
//! done per task of about a thousand samples as one matrix product, right after the task's
//! filter states and basis values are formed, while they are in cache. Tasks run in
//! parallel over time: the filter state at a task's start is recovered exactly from the
//! linearity of the filter (see [`LevelAccumulator`]). Every moment the equations need, including those
//! with `ζ'` and `ζ''`, is a fixed linear combination of these (see [`super::plan`]).
//!//! # Layout
//!
//! - this module: [`LevelAccumulator`], which cuts each streamed chunk into tasks and runs
//!   them in two parallel passes with a serial scan between;
//! - `task`: one task's filtering, basis evaluation and moment sums;
//! - `end_velocity`: the velocity estimates at block boundaries that the snapshots `ι qᵀ`
//!   hold for bodies whose velocity is not measured.

mod end_velocity;
mod task;

use super::filter::{BankState, FilterBank, Hold};
use super::moments::{LevelMoments, PhaseTimes};
use super::plan::Plan;
use crate::basis::BasisEval;
use end_velocity::{central_velocity_weights, end_velocity, VHAT_HALF, VHAT_WINDOW};
use std::time::Instant;
use task::{plan_position, run_filter, Task, TaskCtx, TaskScratch, TaskWork};

/// Samples per task of the time-parallel pass (see [`LevelAccumulator`]): its filter states
/// and basis values (about 50 rows of doubles) stay in the second-level cache between
/// filtering and accumulation, and a default chunk of 8192 samples gives 8 tasks.
pub(crate) const TASK_LEN: usize = 1024;
/// Streams the samples of one level through the filter bank and accumulates moments.
///
/// Each streamed chunk is cut into tasks of at most [`TASK_LEN`] samples (and at the block
/// boundaries), processed in parallel in two passes. The filter is linear, so the state at
/// the start of task `t + 1` is exactly `Φ^{len_t} ζ_start[t] + ζ⁰_end[t]`, with `ζ⁰_end[t]`
/// the end state of task `t` run from rest:
///
/// 1. every task runs the bank from rest (no output) for `ζ⁰_end` — in parallel;
/// 2. a serial scan composes the start states (`Φ^m` by binary powering);
/// 3. every task runs the bank from its true start, writing the states of its samples
///    next to the basis values, and adds `Σ ι wᵀ` and `Σ s ι wᵀ` by one matrix product —
///    in parallel, each task's data read once while it is in cache.
///
/// The tasks depend only on the chunk length and the blocks, not on the number of
/// threads, so neither do the results. Against one serial run they differ by rounding
/// only (the start states and the order of the sums): within 1e-12 relative, see
/// `time_parallel_pass_matches_the_serial_recursion`. Memory is a few buffers per chunk,
/// independent of the record length.
pub(crate) struct LevelAccumulator<'a> {
    plan: &'a Plan,
    eval: &'a dyn BasisEval,
    bank: FilterBank,
    task_len: usize,
    /// Plan row of each row of the bank's output then of the measured signals.
    row_map: Vec<Option<usize>>,
    /// The bank's output row of each of the plan's state columns ([`Plan::state_cols`]).
    state_rows: Vec<usize>,
    ts: f64,
    n_total: usize,
    bounds: Vec<usize>,
    kept: Vec<bool>,
    pos: usize,
    /// The bank's state at the last sample fed (meaningless before the first).
    state: Option<BankState>,
    sums: Vec<Vec<f64>>,
    tsums: Vec<Vec<f64>>,
    snaps: Vec<Vec<f64>>,
    tails: Vec<Vec<f64>>,
    work: Vec<TaskWork>,
    /// Pass 2's buffers, one set per worker thread.
    scratch: Vec<std::sync::Mutex<TaskScratch>>,
    /// `0, 1, 2, …, task_len − 1` as floating-point numbers.
    ramp: Vec<f64>,
    qrow: Vec<f64>,
    /// [`central_velocity_weights`].
    vhat_weights: Vec<f64>,
    /// Kernel widths of the plan's extra columns at this level ([`super::noise`]).
    extra_width: Vec<f64>,
    /// The first non-finite basis value met: (root, sample, value).
    pub non_finite: Option<(usize, usize, f64)>,
    pub times: PhaseTimes,
    /// Column drivers ([`super::plan::RootDriver`]): delay in samples of a delayed column
    /// at this level (the velocity differentiator's half-width plus one).
    root_delay: usize,
    /// Per column driver: its values over the last `delay` samples before this chunk.
    root_hist: Vec<Vec<f64>>,
    /// Per column driver: its (delayed) values over the current chunk, driver-major.
    root_buf: Vec<f64>,
    /// With column drivers: every root over the current chunk, root-major, evaluated once
    /// for the drivers and read again by pass 2 (empty without column drivers).
    chunk_roots: Vec<f64>,
}

impl<'a> LevelAccumulator<'a> {
    pub fn new(
        plan: &'a Plan,
        eval: &'a dyn BasisEval,
        ts: f64,
        n_total: usize,
        n_blocks: usize,
        hold: Hold,
    ) -> Self {
        let n_blocks = n_blocks.clamp(1, (n_total - 1).max(1));
        let bounds: Vec<usize> = (0..=n_blocks)
            .map(|b| ((b as u128 * (n_total - 1) as u128) / n_blocks as u128) as usize)
            .collect();
        Self::with_blocks(plan, eval, ts, n_total, bounds, vec![true; n_blocks], hold)
    }

    /// As [`Self::new`] with given block boundaries (`0 … n_total − 1`, increasing) and,
    /// per block, whether its moments count (see [`super::rests`]).
    pub fn with_blocks(
        plan: &'a Plan,
        eval: &'a dyn BasisEval,
        ts: f64,
        n_total: usize,
        bounds: Vec<usize>,
        kept: Vec<bool>,
        hold: Hold,
    ) -> Self {
        assert_eq!(
            bounds.len(),
            kept.len() + 1,
            "invariant: one flag per block"
        );
        let n_blocks = kept.len();
        let bank = FilterBank::new(&plan.corners, plan.n_drivers(), plan.order, ts, hold);
        let (n_row_signals, n_col_signals, n_snap_cols) = (
            plan.n_row_signals(),
            plan.n_col_signals(),
            plan.n_snap_cols(),
        );
        let mut row_map = vec![None; bank.n_rows()];
        for d in 0..plan.n_drivers() {
            for c in 0..plan.corners.len() {
                for i in 0..plan.order {
                    row_map[bank.row(d, c, i)] = Some(plan.state(d, c, i));
                }
            }
        }
        row_map.extend((plan.n_filter_states()..n_row_signals).map(Some));
        let state_rows = plan
            .state_cols
            .iter()
            .map(|&p| {
                let (dc, i) = (p / plan.order, p % plan.order);
                let (d, c) = (dc / plan.corners.len(), dc % plan.corners.len());
                bank.row(d, c, i)
            })
            .collect();
        let mut acc = LevelAccumulator {
            plan,
            eval,
            bank,
            task_len: 0,
            row_map,
            state_rows,
            ts,
            n_total,
            bounds,
            kept,
            pos: 0,
            state: None,
            sums: vec![vec![0.0; n_row_signals * n_col_signals]; n_blocks],
            tsums: vec![vec![0.0; n_row_signals * n_col_signals]; n_blocks],
            snaps: vec![vec![0.0; n_row_signals * n_snap_cols]; n_blocks + 1],
            tails: vec![Vec::with_capacity(VHAT_WINDOW); plan.vhat_bodies.len()],
            work: Vec::new(),
            scratch: (0..rayon::current_num_threads().max(1))
                .map(|_| Default::default())
                .collect(),
            ramp: Vec::new(),
            qrow: vec![0.0; n_snap_cols],
            vhat_weights: central_velocity_weights(),
            extra_width: vec![1.0; plan.extra.len()],
            non_finite: None,
            times: PhaseTimes::default(),
            root_delay: 0,
            root_hist: vec![Vec::new(); plan.root_drivers.len()],
            root_buf: Vec::new(),
            chunk_roots: Vec::new(),
        };
        acc.set_task_len(TASK_LEN);
        acc
    }

    /// Samples per task of the time-parallel pass (at least 1; [`TASK_LEN`] by default).
    pub fn set_task_len(&mut self, task_len: usize) {
        self.task_len = task_len.max(1);
        self.ramp = (0..self.task_len).map(|k| k as f64).collect();
        self.bank.prepare_propagation(self.task_len);
    }

    /// Delay of the delayed column drivers at this level, in samples (see
    /// [`super::plan::RootDriver`]); set before the first chunk.
    pub fn set_root_delay(&mut self, delay: usize) {
        assert_eq!(
            self.pos, 0,
            "invariant: the delay is set before the first chunk"
        );
        self.root_delay = delay;
    }

    /// Fill `root_buf` with the column drivers' values over the next `len` samples: the
    /// basis evaluated over the chunk into `chunk_roots` (in tasks, in parallel; pass 2
    /// reads it instead of evaluating again), each delayed column shifted
    /// by the delay through `root_hist` (before the record's first sample a column holds
    /// its first value, as the filters start at rest there).
    fn fill_root_drivers(&mut self, cols: &[&[f64]], len: usize) {
        use rayon::prelude::*;
        let plan = self.plan;
        let n_g = plan.roots.len();
        if plan.root_drivers.is_empty() || n_g == 0 {
            return;
        }
        let step = self.task_len;
        let mut g = std::mem::take(&mut self.chunk_roots);
        g.resize(n_g * len, 0.0);
        let pieces: Vec<(usize, usize)> = (0..len)
            .step_by(step)
            .map(|o| (o, step.min(len - o)))
            .collect();
        let parts: Vec<Vec<f64>> = pieces
            .par_iter()
            .map(|&(o, l)| {
                let view: Vec<&[f64]> = cols
                    .iter()
                    .map(|c| if c.is_empty() { *c } else { &c[o..o + l] })
                    .collect();
                let mut out = vec![0.0; n_g * l];
                self.eval.eval_block(&view, l, &mut out, &mut Vec::new());
                out
            })
            .collect();
        for (&(o, l), part) in pieces.iter().zip(&parts) {
            for r in 0..n_g {
                // shape: `part` is n_g × l column-major, `g` is n_g × len.
                g[r * len + o..r * len + o + l].copy_from_slice(&part[r * l..(r + 1) * l]);
            }
        }
        self.root_buf.resize(plan.root_drivers.len() * len, 0.0);
        for (k, rd) in plan.root_drivers.iter().enumerate() {
            // shape: `g` holds every root over the chunk; `rd.root < n_g`.
            let col = &g[rd.root * len..(rd.root + 1) * len];
            let dst = &mut self.root_buf[k * len..(k + 1) * len];
            let delay = if rd.delayed { self.root_delay } else { 0 };
            if delay == 0 {
                dst.copy_from_slice(col);
                continue;
            }
            let hist = &mut self.root_hist[k];
            if self.pos == 0 {
                hist.clear();
                hist.resize(delay, col.first().copied().unwrap_or(0.0));
            }
            // The concatenation `hist ++ col`: the chunk's driver is its first `len`
            // values, the next history its last `delay`.
            let mut all = std::mem::take(hist);
            all.extend_from_slice(col);
            dst.copy_from_slice(&all[..len]);
            *hist = all[len..].to_vec();
        }
        self.chunk_roots = g;
    }

    /// Set the kernel widths of the plan's extra columns for this level.
    pub fn set_extra_widths(&mut self, widths: Vec<f64>) {
        assert_eq!(widths.len(), self.plan.extra.len());
        self.extra_width = widths;
    }

    /// The pieces of the next `len` samples between block boundaries: `(offset, length)`.
    fn pieces(&self, len: usize) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        let mut off = 0;
        while off < len {
            let p0 = self.pos + off;
            // Split at the next block boundary strictly after p0 (and at the last sample).
            let next_bound = self
                .bounds
                .iter()
                .copied()
                .find(|&b| b > p0)
                .unwrap_or(self.n_total);
            let piece = (len - off).min(next_bound - p0);
            out.push((off, piece));
            off += piece;
        }
        out
    }

    /// The tasks of a chunk's `pieces`: runs of at most the task length within one block.
    fn tasks(&self, pieces: &[(usize, usize)]) -> Vec<Task> {
        let mut tasks = Vec::new();
        for &(off, plen) in pieces {
            let global = self.pos + off;
            let block = self.bounds.iter().rposition(|&b| b <= global).unwrap_or(0);
            let block = (block < self.sums.len()).then_some(block);
            let b0 = block.map_or(global, |b| self.bounds[b]);
            let mut o = 0;
            while o < plen {
                let tl = (plen - o).min(self.task_len);
                tasks.push(Task {
                    off: off + o,
                    len: tl,
                    global: global + o,
                    block,
                    tpos: global + o - b0,
                });
                o += tl;
            }
        }
        tasks
    }

    /// Feed the next `len` samples; `cols[s]` is signal `s` (by `SignalId`).
    ///
    /// Longer than most functions here: the two parallel passes over the chunk's tasks and
    /// the serial scan between them share the chunk's borrowed driving columns and the
    /// start states, which named pieces would have to pass back and forth.
    pub fn push(&mut self, cols: &[&[f64]], len: usize) {
        use rayon::prelude::*;
        if len == 0 {
            return;
        }
        let plan = self.plan;
        let pieces = self.pieces(len);
        let tasks = self.tasks(&pieces);
        if self.work.len() < tasks.len() {
            self.work.resize_with(tasks.len(), TaskWork::default);
        }
        self.fill_root_drivers(cols, len);
        let root_buf = std::mem::take(&mut self.root_buf);
        let chunk_roots = std::mem::take(&mut self.chunk_roots);
        let mut drivers: Vec<&[f64]> = plan.drivers.iter().map(|d| cols[d.index()]).collect();
        if !plan.root_drivers.is_empty() {
            drivers.extend(root_buf.chunks_exact(len));
        }
        let bank = &self.bank;
        let at = |k: usize| -> Vec<f64> { drivers.iter().map(|c| c[k]).collect() };
        // The state before each task's first sample; the record's first task starts at rest
        // at its own first sample.
        let start_of = |t: &Task, carried: Option<&BankState>| match (t.global, carried) {
            (0, _) => bank.state(&at(t.off)),
            (_, Some(s)) if t.off == 0 => s.clone(),
            _ => bank.state(&at(t.off - 1)),
        };
        let carried = self.state.take();
        let mut starts = vec![start_of(&tasks[0], carried.as_ref())];
        if tasks.len() > 1 {
            // Pass 1: each task from rest (the first from its true start).
            let work = &mut self.work[..tasks.len()];
            let first = &starts[0];
            tasks
                .par_iter()
                .zip(work.par_iter_mut())
                .enumerate()
                .for_each(|(i, (t, wk))| {
                    let clock = Instant::now();
                    let mut st = if i == 0 {
                        first.clone()
                    } else {
                        start_of(t, None)
                    };
                    run_filter(bank, &mut st, &drivers, t, None);
                    wk.end = Some(st);
                    wk.filter += clock.elapsed();
                });
            let clock = Instant::now();
            for (i, t) in tasks.iter().enumerate().take(tasks.len() - 1) {
                let end = self.work[i]
                    .end
                    .take()
                    .expect("invariant: pass 1 ran for every task");
                let next = if i == 0 {
                    end
                } else {
                    bank.compose(&starts[i], t.len, &end)
                };
                starts.push(next);
            }
            self.times.filter += clock.elapsed();
        }

        // Pass 2: from the true starts, with the moments.
        let n_col_signals = plan.n_col_signals();
        let ctx = TaskCtx {
            plan,
            eval: self.eval,
            bank,
            row_map: &self.row_map,
            state_rows: &self.state_rows,
            extra_width: &self.extra_width,
            cols,
            drivers: &drivers,
            ramp: &self.ramp,
            roots: (!chunk_roots.is_empty()).then_some((&chunk_roots[..], len)),
        };
        let pool = &self.scratch;
        tasks
            .par_iter()
            .zip(self.work[..tasks.len()].par_iter_mut())
            .zip(starts.into_par_iter())
            .for_each(|((t, wk), st)| {
                // The worker's own buffers, kept between tasks and chunks (grown once, never
                // zeroed again). Another thread of a pool larger than the one the
                // accumulator was made for may find them taken: it then uses its own.
                let slot = rayon::current_thread_index().unwrap_or(0) % pool.len();
                match pool[slot].try_lock() {
                    Ok(mut sc) => ctx.run(t, wk, &mut sc, st),
                    Err(_) => ctx.run(t, wk, &mut TaskScratch::default(), st),
                }
            });

        // In order: snapshots, block sums, velocity tails.
        let mut ti = 0;
        for &(off, plen) in &pieces {
            let p0 = self.pos + off;
            let clock = Instant::now();
            if let Some(b) = self.bounds.iter().position(|&b| b == p0) {
                self.snapshot(b, ti, cols, off, plen);
            }
            while ti < tasks.len() && tasks[ti].off < off + plen {
                let (t, wk) = (&tasks[ti], &mut self.work[ti]);
                if self.non_finite.is_none() {
                    self.non_finite = wk.non_finite;
                }
                if let Some(b) = t.block {
                    add_task_sums(
                        &mut self.sums[b],
                        &mut self.tsums[b],
                        &wk.part,
                        &self.row_map,
                        n_col_signals,
                    );
                }
                self.times.filter += std::mem::take(&mut wk.filter);
                self.times.evaluate += std::mem::take(&mut wk.evaluate);
                self.times.accumulate += std::mem::take(&mut wk.accumulate);
                ti += 1;
            }
            // Keep the most recent positions for end-point velocity estimates.
            for (k, body) in plan.vhat_bodies.iter().enumerate() {
                let x = &cols[plan_position(*body)][off..off + plen];
                let tail = &mut self.tails[k];
                let take = x.len().min(VHAT_WINDOW - 1);
                let keep = (VHAT_WINDOW - 1 - take).min(tail.len());
                tail.drain(..tail.len() - keep);
                tail.extend_from_slice(&x[x.len() - take..]);
            }
            self.times.accumulate += clock.elapsed();
        }
        self.state = self.work[tasks.len() - 1].end.take();
        self.pos += len;
        self.root_buf = root_buf;
        self.chunk_roots = chunk_roots;
    }

    /// The snapshot `ι qᵀ` at block boundary `b`, the first sample of the piece
    /// `cols[..][off .. off + plen]`, whose first task is `self.work[task]`.
    fn snapshot(&mut self, b: usize, task: usize, cols: &[&[f64]], off: usize, plen: usize) {
        let plan = self.plan;
        let (n_row_signals, n_col_signals, n_snap_cols) = (
            plan.n_row_signals(),
            plan.n_col_signals(),
            plan.n_snap_cols(),
        );
        let wk = &self.work[task];
        self.qrow[..n_col_signals].copy_from_slice(&wk.first_w);
        for (k, body) in plan.vhat_bodies.iter().enumerate() {
            let x = &cols[plan_position(*body)][off..off + plen];
            let tail = &self.tails[k];
            // Interior boundary with enough samples on both sides in hand: centred fit.
            // (A boundary within a few samples of a chunk end keeps the one-sided fit.)
            if tail.len() >= VHAT_HALF && x.len() > VHAT_HALF {
                let win = tail[tail.len() - VHAT_HALF..]
                    .iter()
                    .chain(&x[..=VHAT_HALF]);
                self.qrow[n_col_signals + k] =
                    win.zip(&self.vhat_weights).map(|(x, w)| x * w).sum::<f64>() / self.ts;
            } else {
                let mut win: Vec<f64> = tail.clone();
                win.push(x[0]);
                self.qrow[n_col_signals + k] = end_velocity(&win, self.ts);
            }
        }
        let snap = &mut self.snaps[b];
        for i in 0..n_row_signals {
            let ii = wk.first_iota[i];
            for k in 0..n_snap_cols {
                snap[i * n_snap_cols + k] = ii * self.qrow[k];
            }
        }
    }

    pub fn finish(self) -> (LevelMoments, PhaseTimes) {
        assert_eq!(self.pos, self.n_total, "record ended early");
        let lens = self.bounds.windows(2).map(|w| w[1] - w[0]).collect();
        (
            LevelMoments {
                n_row_signals: self.plan.n_row_signals(),
                n_col_signals: self.plan.n_col_signals(),
                n_snap_cols: self.plan.n_snap_cols(),
                ts: self.ts,
                sums: self.sums,
                tsums: self.tsums,
                lens,
                snaps: self.snaps,
                kept: self.kept,
            },
            self.times,
        )
    }
}

/// Add one task's partial sums `part` (per bank or measured row, `Σ ι w` then `Σ s ι w`,
/// `2 n_col_signals` each) to its block's sums, in the plan's row order.
fn add_task_sums(
    sums: &mut [f64],
    tsums: &mut [f64],
    part: &[f64],
    row_map: &[Option<usize>],
    n_col_signals: usize,
) {
    for (r, part) in part
        .chunks_exact(2 * n_col_signals)
        .enumerate()
        .take(row_map.len())
    {
        if let Some(m) = row_map[r] {
            let (ps, pt) = part.split_at(n_col_signals);
            for (d, p) in sums[m * n_col_signals..(m + 1) * n_col_signals]
                .iter_mut()
                .zip(ps)
            {
                *d += p;
            }
            for (d, p) in tsums[m * n_col_signals..(m + 1) * n_col_signals]
                .iter_mut()
                .zip(pt)
            {
                *d += p;
            }
        }
    }
}
