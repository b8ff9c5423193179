//! The memory an identification will take, estimated from the model, the options and the
//! number of levels before any sample is read, so that a model too large for the machine
//! (a chain of hundreds of bodies with every position measured) is refused with the
//! estimate instead of taking memory until the system kills it.
//!
//! What is held at once, in `f64`s (`L` levels, `B` time blocks, `n_i` row signals — the
//! filter states `drivers × corners × order` and the measured signals —, `n_w` column
//! signals, `n_q = n_w` + end-point velocities, `r` rows per level — computable
//! instrument × equation pairs —, `p` unknowns):
//!
//! * the moment sums of every level (see the `moments` module): `Σ ι wᵀ` and `Σ s ι wᵀ`
//!   per block and the snapshots `ι qᵀ` at the block boundaries,
//!   `L (2 B n_i n_w + (B + 1) n_i n_q)`, and each level's whole-record view
//!   `L n_i (n_w + n_q)`;
//! * while the levels are streamed, each task's partial sums (`n_i × 2 n_w`, about
//!   `chunk / 1024 + 2` tasks per chunk) and each thread's task buffers;
//! * the columns of the rows (see the `columns` module): the `p + 1` columns at every level
//!   in the whole record and in each of the `B + 1` hat windows, `(p + 1) L (B + 2) r`;
//! * the stacked least-squares problem (`L r × p`) and its SVD: the gathered rows, the
//!   stacked and the weighted matrix, faer's copy, `U` and the pseudo-inverse, and the
//!   SVD's work space — [`SOLVE_COPIES`] copies;
//! * the standard errors' window rows, `(B + 1) r` per level.
//!
//! The number of blocks is chosen from the record (at most [`super::design::MAX_BLOCKS`],
//! [`super::design::FILTERED_MAX_BLOCKS`] for the rows of the filtered equation) unless it
//! is given, so the estimate takes the largest: an upper bound.
//!
//! The estimate bounds the peak resident memory of `dynid identify` on chains of `N` unit
//! masses, springs and dampers between neighbours, every position measured (the model of
//! this module's tests and of `tests/bounded_work.rs`; the test
//! `estimates_bound_the_measured_peaks` holds the measured peaks, docs/performance.md lists
//! them). Before reading, the estimate takes the most blocks (80; 400 with the filtered
//! rows): a record that chooses fewer (a short one, or slow filter corners) takes less.

use super::accumulate::TASK_LEN;
use super::design;
use super::plan::{build_structure, Plan};
use super::types::{IdentifyError, IdentifyOptions};
use crate::limits::{bytes_in_words, MAX_BYTES};
use dynid_ir::ir::ModelIr;

/// Copies of the stacked `L r × p` matrix alive during the solve (see the module doc).
pub const SOLVE_COPIES: f64 = 8.0;

/// Slack on the sum of the buffers (the allocator's own, rounding of its size classes).
const SLACK: f64 = 1.1;

/// Memory of the process besides the identification's buffers (the program, the model,
/// the thread pool, the readers' and the allocator's buffers): the peak resident memory
/// of `dynid identify models/sdof_linear.dyn` on three levels of 200 s, 59 MB.
const BASE_BYTES: f64 = 6e7;

/// The estimated memory of an identification and what drives it.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryEstimate {
    /// Bytes at the peak (an upper bound).
    pub bytes: f64,
    pub bodies: usize,
    pub levels: usize,
    /// Signals driving the filter bank, corners and sections per chain.
    pub drivers: usize,
    pub corners: usize,
    pub order: usize,
    /// Measured signals.
    pub measured: usize,
    /// Instruments (filter states used as instruments, and balance signals).
    pub instruments: usize,
    /// Least-squares rows per level.
    pub rows: usize,
    pub unknowns: usize,
    /// Time blocks per level (the largest the record may choose, unless given).
    pub blocks: usize,
}

impl MemoryEstimate {
    /// What drives the estimate, in words.
    pub fn drivers_in_words(&self) -> String {
        format!(
            "{} bodies, {} measured signals, a filter bank of {} drivers × {} corners × {} \
             sections, {} rows per level (from {} instruments and {} equations) for {} \
             unknowns, {} time blocks and {} levels",
            self.bodies,
            self.measured,
            self.drivers,
            self.corners,
            self.order,
            self.rows,
            self.instruments,
            self.bodies,
            self.unknowns,
            self.blocks,
            self.levels
        )
    }
}

/// The memory [`super::identify`] (and detection and diagnosis, which measure the same
/// moments) will take on `levels` records of `ir` with `opts`, from the model alone.
/// Option errors that identification would report are reported here too.
pub fn estimate(
    ir: &ModelIr,
    levels: usize,
    opts: &IdentifyOptions,
) -> Result<MemoryEstimate, IdentifyError> {
    let bank = super::bank::choose_bank(ir, opts)?;
    let mut plan = build_structure(ir, opts.balance, &bank)?;
    if opts.noise_correction {
        // Attached only where the data turn out noisy: the estimate assumes they do.
        super::noise::attach(&mut plan, ir);
    }
    let corners = bank.n_corners;
    if corners > 0 {
        // The rows do not depend on the corners' values.
        let placeholder: Vec<f64> = (1..=corners).map(|c| c as f64).collect();
        plan.set_corners(ir, &placeholder);
    }
    let blocks = opts.n_blocks.unwrap_or(design::max_blocks(opts));
    Ok(MemoryEstimate {
        bytes: bytes(&plan, levels, blocks, opts.chunk_len),
        bodies: ir.bodies.len(),
        levels,
        drivers: plan.n_drivers(),
        corners,
        order: plan.order,
        measured: plan.y.len(),
        instruments: plan.instruments.len(),
        rows: plan.rows.len(),
        unknowns: plan.unknowns.len(),
        blocks,
    })
}

/// Bytes at the peak (see the module doc); in `f64` so that no count can overflow.
fn bytes(plan: &Plan, levels: usize, blocks: usize, chunk: usize) -> f64 {
    let l = levels as f64;
    let b = blocks as f64;
    let (n_row_signals, n_col_signals, n_snap_cols) = (
        plan.n_row_signals() as f64,
        plan.n_col_signals() as f64,
        plan.n_snap_cols() as f64,
    );
    let r = plan.rows.len() as f64;
    let p = plan.unknowns.len() as f64;
    let threads = rayon::current_num_threads().max(1) as f64;
    let task = TASK_LEN as f64;
    let moments =
        l * (2.0 * b * n_row_signals * n_col_signals + (b + 1.0) * n_row_signals * n_snap_cols);
    let views = l * n_row_signals * (n_col_signals + n_snap_cols);
    let tasks = (chunk as f64 / task).ceil() + 2.0;
    let streaming = l.min(threads) * tasks * n_row_signals * 2.0 * n_col_signals
        + threads * task * (n_row_signals + 3.0 * n_col_signals);
    let columns = (p + 1.0) * l * (b + 2.0) * r;
    let solve = SOLVE_COPIES * l * r * (p + 1.0);
    let windows = l * (b + 1.0) * r;
    BASE_BYTES + SLACK * 8.0 * (moments + views + streaming + columns + solve + windows)
}

/// Refuse, before any sample is read, an identification whose estimated memory plus
/// `extra` bytes (records the caller holds whole) is above [`MAX_BYTES`], unless
/// `opts.allow_large`; `what` names the work in the message ("identification").
pub fn check(
    ir: &ModelIr,
    levels: usize,
    opts: &IdentifyOptions,
    extra: f64,
    what: &str,
) -> Result<(), IdentifyError> {
    if opts.allow_large {
        return Ok(());
    }
    let est = estimate(ir, levels, opts)?;
    let total = est.bytes + extra;
    if total <= MAX_BYTES {
        return Ok(());
    }
    let held = if extra > 0.0 {
        format!(
            " ({} of it for the records read whole)",
            bytes_in_words(extra)
        )
    } else {
        String::new()
    };
    Err(IdentifyError::TooLarge {
        what: what.to_string(),
        estimate: format!("{} of memory{held}", bytes_in_words(total)),
        limit: bytes_in_words(MAX_BYTES),
        drivers: est.drivers_in_words(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`crate::sim::test_models::chain_source`], compiled.
    fn chain(n: usize) -> ModelIr {
        dsl_parser::compile_str("chain.dyn", &crate::sim::test_models::chain_source(n)).unwrap()
    }

    #[test]
    fn estimates_bound_the_measured_peaks() {
        // Peak resident memory measured as in the module doc: (N, blocks, bytes).
        for (n, blocks, peak) in [(10, 80, 156.9e6), (20, 48, 454.3e6)] {
            let ir = chain(n);
            let chosen = IdentifyOptions {
                n_blocks: Some(blocks),
                ..Default::default()
            };
            let e = estimate(&ir, 3, &chosen).unwrap();
            let ratio = e.bytes / peak;
            assert!((1.0..1.25).contains(&ratio), "chain {n}: {ratio}");
            let before = estimate(&ir, 3, &IdentifyOptions::default()).unwrap();
            let ratio = before.bytes / peak;
            assert!((1.0..2.0).contains(&ratio), "chain {n}: {ratio}");
            assert_eq!(before.blocks, design::MAX_BLOCKS);
        }
    }

    #[test]
    fn a_chain_of_500_bodies_is_estimated_in_terabytes() {
        let e = estimate(&chain(500), 3, &IdentifyOptions::default()).unwrap();
        assert_eq!((e.bodies, e.measured, e.unknowns), (500, 501, 1000));
        // Filter instruments of 501 drivers × 6 corners × 2 degrees, each row of nearly
        // every equation.
        assert_eq!(e.instruments, 6012);
        assert!(e.rows <= 6012 * 500 && e.rows > 6000 * 500, "{}", e.rows);
        assert!(e.bytes > 1e12, "{}", e.bytes);
        let err = check(
            &chain(500),
            3,
            &IdentifyOptions::default(),
            0.0,
            "identification",
        );
        assert!(
            matches!(err, Err(IdentifyError::TooLarge { .. })),
            "{err:?}"
        );
        let allowed = IdentifyOptions {
            allow_large: true,
            ..Default::default()
        };
        assert!(check(&chain(500), 3, &allowed, 0.0, "identification").is_ok());
    }
}
