//! The checks of the measuring pass that refuse a request, with what to do: corners that
//! do not fit the data, levels too short for them, too few rows, and the terms a level
//! cannot be measured with (not finite, overflowing).

use crate::data::LevelSource;
use crate::ident::design::{self, Designed};
use crate::ident::first_pass::{LevelSpan, LevelStats};
use crate::ident::plan::Plan;
use crate::ident::types::IdentifyError;
use dynid_ir::ir::ModelIr;

/// Refuse corners that are not positive and finite, or at or above the Nyquist frequency
/// of a level: there the discretised filter aliases and the estimates are wrong without
/// any other sign.
pub(super) fn check_corners(
    corners: &[f64],
    given: bool,
    stats: &[LevelStats],
    span: &LevelSpan,
    levels: &[&dyn LevelSource],
) -> Result<(), IdentifyError> {
    if corners.is_empty() || corners.iter().any(|c| !(c.is_finite() && *c > 0.0)) {
        return Err(IdentifyError::BadOption {
            message: format!("filter corners {corners:?}"),
            help: "corners are positive angular frequencies in rad/s".into(),
        });
    }
    let (ts_min, ts_max) = (span.ts_min, span.ts_max);
    let nyquist = std::f64::consts::PI / ts_max;
    let Some(c) = corners.iter().find(|c| **c >= nyquist) else {
        return Ok(());
    };
    if !given && ts_min < ts_max {
        // No option was given: the corners come from the faster level's rate.
        let at = |ts: f64| {
            stats
                .iter()
                .position(|s| s.ts == ts)
                .map_or_else(String::new, |k| levels[k].origin())
        };
        return Err(IdentifyError::MixedSampleIntervals {
            fast: at(ts_min),
            ts_fast: ts_min,
            slow: at(ts_max),
            ts_slow: ts_max,
            corner: corners.iter().copied().fold(0.0, f64::max),
        });
    }
    Err(IdentifyError::BadOption {
        message: format!(
            "filter corner {} rad/s is at or above the Nyquist frequency π/Ts = {} rad/s \
             of the data (Ts = {} s)",
            dynid_ir::num::sig(*c, 4, false),
            dynid_ir::num::sig(nyquist, 4, false),
            dynid_ir::num::sig(ts_max, 4, false)
        ),
        help: "use corners well below the Nyquist frequency (a few times below it), or \
               leave them out so that they are designed from the data"
            .into(),
    })
}

/// Refuse a level on which the slowest chain does not settle, or too short for the time
/// blocks, with advice: the record length needed, or corners that fit.
pub(super) fn check_lengths(
    stats: &[LevelStats],
    levels: &[&dyn LevelSource],
    corners: &[f64],
    order: usize,
    n_blocks: usize,
    designed: Option<&Designed>,
    span: &LevelSpan,
) -> Result<(), IdentifyError> {
    let tau = design::time_constant(corners, order);
    let settle = design::min_duration(corners, order);
    for (s, src) in stats.iter().zip(levels) {
        let duration = (s.n.saturating_sub(1)) as f64 * s.ts;
        if duration < settle * (1.0 - 1e-9) || s.n < n_blocks.saturating_mul(4) {
            // (Saturating: a corner of 1e-300 rad/s asks for more samples than a count holds.)
            let need = ((settle / s.ts).ceil() as usize)
                .saturating_add(1)
                .max(n_blocks.saturating_mul(4));
            let advice = match designed {
                Some(c) if s.n >= n_blocks.saturating_mul(4) => format!(
                    "record at least {}, or use filter corners that fit this record (the \
                     lowest at least {:.4} rad/s), e.g. `--filter-corners {}`",
                    samples_needed(need, settle),
                    design::min_corner(span.min_duration, order),
                    c.corners
                        .iter()
                        .map(|v| format!("{v:.4}"))
                        .collect::<Vec<_>>()
                        .join(",")
                ),
                _ => {
                    // The fastest corner the design allows at this sample rate.
                    let fast = design::max_corner(s.ts) / 2.0;
                    let t_fast = design::min_duration(&[fast], order);
                    format!(
                        "record at least {}: with {} filter sections even the fastest \
                         corner this sample rate allows ({fast:.4} rad/s) needs {t_fast:.3} s",
                        samples_needed(
                            need.max(((t_fast / s.ts).ceil() as usize).saturating_add(1)),
                            settle.max(t_fast)
                        ),
                        order,
                    )
                }
            };
            return Err(IdentifyError::TooShort {
                origin: src.origin(),
                n: s.n,
                duration,
                tau,
                need,
                advice,
            });
        }
    }
    Ok(())
}

/// Refuse a problem with fewer rows than unknowns.
pub(super) fn check_rows(plan: &Plan, levels: usize) -> Result<(), IdentifyError> {
    let cols = plan.unknowns.len();
    let rows = plan.rows.len() * levels;
    if rows < cols {
        return Err(IdentifyError::TooFewRows { rows, cols });
    }
    Ok(())
}

/// The name of column `col` of `w` (a basis root, a measured signal, or a noise column).
pub(super) fn column_label(ir: &ModelIr, plan: &Plan, col: usize) -> String {
    let n_g = plan.roots.len();
    if col < n_g {
        dynid_ir::print::render_expr(ir, plan.roots[col])
    } else if let Some(s) = plan.y.get(col - n_g) {
        ir.signal(*s).name.clone()
    } else {
        "a noise-correction column".into()
    }
}

/// The error for a basis root that is not finite at sample `k` of `src`.
pub(super) fn non_finite_term(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    root: usize,
    k: usize,
    value: f64,
) -> IdentifyError {
    let e = plan.roots[root];
    let signals = ir
        .expr_signals(e)
        .iter()
        .map(|s| format!("`{}`", ir.signal(*s).name))
        .collect::<Vec<_>>()
        .join(", ");
    let advice = if value.is_nan() {
        format!(
            "the term is undefined for the values of {signals} there (e.g. `sqrt` or `log` of \
             a negative number): write it so that it is defined for every value the data take \
             (e.g. `sqrt(abs(s))`), or check the data"
        )
    } else {
        format!(
            "the term overflows double precision for the values of {signals} there: rescale \
             the data or the term (e.g. `exp(s / s0)` with a larger `s0`, a lower power)"
        )
    };
    IdentifyError::NonFiniteTerm {
        origin: src.origin(),
        term: dynid_ir::print::render_expr(ir, e),
        at: src.locate(k),
        value,
        advice,
    }
}

/// "N samples" for a count a record can have; for a count that no record holds (a corner
/// of 1e-300 rad/s asks for more samples than a 64-bit count) the duration instead.
fn samples_needed(n: usize, seconds: f64) -> String {
    if n < 1 << 53 {
        format!("{n} samples")
    } else {
        format!(
            "{} s of data (more samples than any record holds)",
            dynid_ir::num::sig(seconds, 4, false)
        )
    }
}
