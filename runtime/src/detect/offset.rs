//! A mean the linear model cannot explain: a constant force on a body.
//!
//! Detection reads nonlinearities from the drift of equivalent-linear parameters over the
//! levels; a constant force (gravity on an inclined axis, a cable, an amplifier's bias)
//! does not drift and is no equivalent-linear parameter, but it puts a mean into every
//! level's equation that no linear term produces. The method uses raw, not centred,
//! moments, so the column of a constant force is the mean of each filter output: the
//! model with an unknown constant force on each body that has none (the element
//! `force off (ground, body) = f0`) is fitted at each level (the linear fits of the
//! detection, each on its own level: a pooled fit of a linear model that misses a
//! level-dependent effect is biased), and a constant force that every level finds with the
//! same sign, clear of its standard error, is reported with its size, the weighted mean of
//! the levels' estimates. Data without a mean (centred records) leave that column zero:
//! identification names it unidentifiable, and nothing is reported.

use super::fit::weighted_mean;
use super::types::{ConstantForceFinding, FromDataError};
use crate::data::LevelSource;
use crate::ident::{measure, IdentifyOptions};
use crate::tape::Tape;
use dynid_ir::edit::NewTerm;
use dynid_ir::ir::{Basis, ModelIr};

/// The weighted mean of the levels' constant forces must be this many of its standard
/// errors from zero, and every level's at least [`LEVEL_T`] of its own, with the mean's
/// sign. A model that holds on data without a constant force gives |f0|/σ within 3 (the
/// finite record's mean, `zero_offset_in_the_data_is_estimated_near_zero_not_removed`,
/// tests/constant_force.rs).
pub const MEAN_T: f64 = 6.0;
/// See [`MEAN_T`].
pub const LEVEL_T: f64 = 2.0;

/// Whether the equation of body `b` (index) already has a constant term.
fn has_constant(ir: &ModelIr, b: usize) -> bool {
    ir.equations
        .iter()
        .filter(|e| e.body.index() == b)
        .flat_map(|e| &e.terms)
        .any(|t| matches!(t.basis, Basis::Expr(e) if ir.is_constant(e)))
}

/// The constant forces the `levels` show on the bodies of `ir` that have none (see the
/// module doc). One more pass over the data; empty when every body has a constant force.
pub fn unexplained_means(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Vec<ConstantForceFinding>, FromDataError> {
    let mut probe = ir.clone();
    let one = |a: &mut dynid_ir::ir::ExprArena, _, _| a.constant(1.0);
    let mut added: Vec<(String, String)> = Vec::new();
    for (b, body) in ir.bodies.iter().enumerate() {
        if has_constant(ir, b) {
            continue;
        }
        let name = probe.fresh_name("offset");
        let param = probe.fresh_name("f0");
        let ok = probe
            .add_force(
                &name,
                ("ground", &body.name),
                &[NewTerm {
                    param: &param,
                    nominal: Some(0.0),
                    basis: &one,
                }],
            )
            .is_ok();
        if ok {
            added.push((body.name.clone(), param));
        }
    }
    if added.is_empty() {
        return Ok(Vec::new());
    }
    let tape = Tape::compile(&probe, &probe.eval_roots());
    let m = measure(&probe, &tape, levels, opts)?;
    let per: Vec<_> = (0..levels.len()).map(|i| m.identify_level(i)).collect();
    let mut out = Vec::new();
    for (body, p) in added {
        let own: Option<Vec<(f64, f64)>> = per
            .iter()
            .map(|f| {
                f.param(&p)
                    .filter(|x| x.value.is_finite() && x.stderr.is_finite() && x.stderr > 0.0)
                    .map(|x| (x.value, x.stderr))
            })
            .collect();
        let Some(own) = own else { continue };
        let (y, se): (Vec<f64>, Vec<f64>) = own.iter().copied().unzip();
        let (value, stderr) = weighted_mean(&y, &se);
        let agree = own
            .iter()
            .all(|&(v, s)| v.signum() == value.signum() && v.abs() >= LEVEL_T * s);
        if !(value.is_finite() && stderr > 0.0) || value.abs() < MEAN_T * stderr || !agree {
            continue;
        }
        let e = crate::ident::ParamEstimate {
            name: p.clone(),
            value,
            stderr,
            significant: true,
        };
        let f = dynid_ir::num::pm(e.value, e.stderr);
        let v3 = dynid_ir::num::sig(e.value, 3, false);
        let message = format!(
            "constant force at (ground, {body}): {f} N — a mean the linear model cannot \
             explain, found at every level ({}): an unmodelled constant force (gravity, a \
             cable, an amplifier's bias) or a zero offset of a position sensor; add it to the \
             model (`force off (ground, {body}) = f0 ~ {v3}`) before reading the curves",
            own.iter()
                .map(|(v, s)| dynid_ir::num::pm(*v, *s))
                .collect::<Vec<_>>()
                .join(", ")
        );
        out.push(ConstantForceFinding {
            body,
            value: e.value,
            stderr: e.stderr,
            per_level: own,
            message,
        });
    }
    Ok(out)
}
