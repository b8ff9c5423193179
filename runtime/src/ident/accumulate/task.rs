//! One task of the time-parallel pass: a contiguous run of samples within one time block,
//! filtered from its start state, with its basis values evaluated and its moment sums formed
//! by one matrix product while its data are in cache.

use crate::basis::BasisEval;
use crate::ident::filter::{BankState, FilterBank};
use crate::ident::plan::Plan;
use faer::{Accum, MatMut, MatRef, Par};
use std::time::{Duration, Instant};

/// One contiguous run of samples inside a streamed chunk, within one time block.
#[derive(Clone, Copy, Debug)]
pub(super) struct Task {
    /// First sample, relative to the chunk.
    pub(super) off: usize,
    pub(super) len: usize,
    /// First sample in the record.
    pub(super) global: usize,
    /// The block whose sums it adds to; `None` for the last sample of the record (only a
    /// snapshot).
    pub(super) block: Option<usize>,
    /// Position of the first sample in its block.
    pub(super) tpos: usize,
}

/// The working buffers of a task in pass 2, one set per worker thread (not per task: for
/// a wide model they are megabytes each).
#[derive(Default)]
pub(super) struct TaskScratch {
    /// `ι` sample-major: `iota[k · n_rows + r]`, rows the bank's then the measured signals.
    pub(super) iota: Vec<f64>,
    /// `w` then `(tpos + k) w`, column-major (`w[col · len + k]`).
    pub(super) w: Vec<f64>,
    pub(super) scratch: Vec<f64>,
}

/// The results of one task (kept between chunks).
#[derive(Default)]
pub(super) struct TaskWork {
    /// `Σ ι [w, (tpos + k) w]ᵀ` over the task, row-major `n_rows × 2 n_w`.
    pub(super) part: Vec<f64>,
    /// `ι` (in the plan's row order) and `w` at the first sample.
    pub(super) first_iota: Vec<f64>,
    pub(super) first_w: Vec<f64>,
    /// Pass 1: the state at the end from a zero start; pass 2: the true end state.
    pub(super) end: Option<BankState>,
    pub(super) non_finite: Option<(usize, usize, f64)>,
    pub(super) filter: Duration,
    pub(super) evaluate: Duration,
    pub(super) accumulate: Duration,
}
/// The column of body `b`'s position.
pub(super) fn plan_position(b: dynid_ir::ir::BodyId) -> usize {
    2 * b.index()
}

/// Advance the bank over task `t` from `st` (for the record's first task: at rest at its
/// first sample, whose output is the rest state).
pub(super) fn run_filter(
    bank: &FilterBank,
    st: &mut BankState,
    drivers: &[&[f64]],
    t: &Task,
    out: Option<(&mut [f64], usize)>,
) {
    let skip = usize::from(t.global == 0);
    let out = match out {
        Some((buf, stride)) if skip == 1 => {
            buf[..bank.n_rows()].fill(0.0);
            Some((&mut buf[stride..], stride))
        }
        o => o,
    };
    let ds: Vec<&[f64]> = drivers
        .iter()
        .map(|c| &c[t.off + skip..t.off + t.len])
        .collect();
    bank.advance(st, &ds, t.len - skip, out);
}

/// Whether every value is finite: `v · 0` is zero for a finite `v` and NaN otherwise, summed
/// in eight independent lanes (one pass, no branch per value, vectorised).
pub(super) fn all_finite(c: &[f64]) -> bool {
    let mut acc = [0.0f64; 8];
    let mut chunks = c.chunks_exact(8);
    for ch in &mut chunks {
        for (a, v) in acc.iter_mut().zip(ch) {
            *a += v * 0.0;
        }
    }
    for (a, v) in acc.iter_mut().zip(chunks.remainder()) {
        *a += v * 0.0;
    }
    acc.iter().sum::<f64>() == 0.0
}

/// What pass 2 of every task reads.
pub(super) struct TaskCtx<'c> {
    pub(super) plan: &'c Plan,
    pub(super) eval: &'c dyn BasisEval,
    pub(super) bank: &'c FilterBank,
    pub(super) row_map: &'c [Option<usize>],
    /// The bank's output row of each state column of `w` ([`Plan::state_cols`]).
    pub(super) state_rows: &'c [usize],
    pub(super) extra_width: &'c [f64],
    pub(super) cols: &'c [&'c [f64]],
    pub(super) drivers: &'c [&'c [f64]],
    /// `0, 1, 2, …` up to the task length, as floating-point numbers.
    pub(super) ramp: &'c [f64],
    /// Every root over the chunk (root-major) and the chunk's length, where the column
    /// drivers evaluated them already.
    pub(super) roots: Option<(&'c [f64], usize)>,
}

impl TaskCtx<'_> {
    /// Pass 2 of one task: filter from the true start `st`, evaluate the basis, and form
    /// the task's moment sums.
    ///
    /// Long: the three phases (filter, evaluate, accumulate) share the task's buffers and
    /// are timed one by one; each is one block below.
    pub(super) fn run(&self, t: &Task, wk: &mut TaskWork, sc: &mut TaskScratch, mut st: BankState) {
        let plan = self.plan;
        let (n_col_signals, n_g, n_y) = (plan.n_col_signals(), plan.roots.len(), plan.y.len());
        let (len, n_rows, n_zr) = (t.len, self.row_map.len(), self.bank.n_rows());
        let view: Vec<&[f64]> = self
            .cols
            .iter()
            .map(|c| {
                if c.is_empty() {
                    *c
                } else {
                    &c[t.off..t.off + len]
                }
            })
            .collect();

        let clock = Instant::now();
        sc.iota.resize(n_rows * len, 0.0);
        run_filter(
            self.bank,
            &mut st,
            self.drivers,
            t,
            Some((&mut sc.iota[..], n_rows)),
        );
        wk.end = Some(st);
        // The measured signals after the bank's rows, all in one sweep over the samples.
        let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
        for (k, row) in sc.iota.chunks_exact_mut(n_rows).enumerate() {
            for (d, y) in row[n_zr..n_zr + ys.len()].iter_mut().zip(&ys) {
                *d = y[k];
            }
        }
        wk.filter += clock.elapsed();

        let clock = Instant::now();
        sc.w.resize(2 * n_col_signals * len, 0.0);
        let (w_g, w_rest) = sc.w.split_at_mut(n_g * len);
        match self.roots {
            Some((g, chunk)) => {
                for (r, dst) in w_g.chunks_exact_mut(len).enumerate() {
                    // shape: `g` is n_g × chunk and the task lies inside the chunk.
                    dst.copy_from_slice(&g[r * chunk + t.off..r * chunk + t.off + len]);
                }
            }
            None if n_g > 0 => self.eval.eval_block(&view, len, w_g, &mut sc.scratch),
            None => {}
        }
        for (k, s) in plan.y.iter().enumerate() {
            w_rest[k * len..(k + 1) * len].copy_from_slice(view[s.index()]);
        }
        if !plan.extra.is_empty() {
            let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
            crate::ident::noise::fix::fill_extra(
                &plan.extra,
                self.extra_width,
                &ys,
                len,
                &mut w_rest[n_y * len..(n_y + plan.extra.len()) * len],
            );
        }
        // The state columns: copies of the bank's rows, for the products of the filtered
        // equation's rows.
        let n_base = n_y + plan.extra.len();
        for (k, &r) in self.state_rows.iter().enumerate() {
            let dst = &mut w_rest[(n_base + k) * len..(n_base + k + 1) * len];
            for (s, d) in dst.iter_mut().enumerate() {
                *d = sc.iota[s * n_rows + r];
            }
        }
        wk.non_finite = w_g
            .chunks_exact(len)
            .enumerate()
            .find(|(_, c)| !all_finite(c))
            .and_then(|(r, c)| {
                let i = c.iter().position(|v| !v.is_finite())?;
                Some((r, t.global + i, c[i]))
            });
        wk.evaluate += clock.elapsed();

        let clock = Instant::now();
        wk.first_w.clear();
        wk.first_w
            .extend(sc.w.chunks_exact(len).take(n_col_signals).map(|c| c[0]));
        wk.first_iota.resize(plan.n_row_signals(), 0.0);
        for (r, m) in self.row_map.iter().enumerate() {
            if let Some(m) = m {
                wk.first_iota[*m] = sc.iota[r];
            }
        }
        if t.block.is_some() {
            // Position of each sample in its block, for the hat contributions: `tpos + k`
            // as the sum of two floating-point integers (exact), so the loop vectorises.
            let (w, w_t) = sc.w.split_at_mut(n_col_signals * len);
            let (t0, ramp) = (t.tpos as f64, &self.ramp[..len]);
            for (dst, src) in w_t.chunks_exact_mut(len).zip(w.chunks_exact(len)) {
                for ((d, s), r) in dst.iter_mut().zip(src).zip(ramp) {
                    *d = (t0 + r) * s;
                }
            }
            wk.part.resize(n_rows * 2 * n_col_signals, 0.0);
            let a = MatRef::from_column_major_slice(&sc.iota[..], n_rows, len);
            let b = MatRef::from_column_major_slice(&sc.w[..], len, 2 * n_col_signals);
            let dst = MatMut::from_row_major_slice_mut(&mut wk.part[..], n_rows, 2 * n_col_signals);
            faer::linalg::matmul::matmul(dst, Accum::Replace, a, b, 1.0, Par::Seq);
        }
        wk.accumulate += clock.elapsed();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_finite_finds_every_kind_of_non_finite_value_anywhere() {
        for len in [0, 1, 7, 8, 9, 23, 1024] {
            let c: Vec<f64> = (0..len).map(|k| (k as f64 - 3.0) * 1e300).collect();
            assert!(all_finite(&c), "len {len}");
            for at in 0..len {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut d = c.clone();
                    d[at] = bad;
                    assert!(!all_finite(&d), "len {len}, {bad} at {at}");
                }
            }
        }
    }
}
