//! The entry points: identify pooled (with the guard's warnings), per level, or return the
//! stacked system; each measures the levels once (see [`super::measure`](fn@super::measure)).

use super::guard;
use super::input_delay;
use super::measure::measure;
use super::measurement::Measurement;
use super::shape;
use super::types::{Identification, IdentifyError, IdentifyOptions, LinearSystem};
use crate::basis::BasisEval;
use crate::data::LevelSource;
use crate::tape::Tape;
use dynid_ir::ir::ModelIr;

/// Identify the unknown parameters of `ir` from records at one or more excitation levels,
/// pooling all levels into one least-squares problem (Schiehlen & Krause, see
/// docs/method.md, References, eq. 9).
pub fn identify(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let ir = &*input_delay::model(ir, opts)?;
    if !ir.shapes.is_empty() {
        return Ok(shape::profile(ir, levels, opts)?.1);
    }
    let tape = Tape::compile(ir, &ir.eval_roots());
    let m = measure(ir, &tape, levels, opts)?;
    Ok(guarded(&m, levels, opts))
}
/// The pooled identification with the guard's warnings (see [`guard`]).
fn guarded(
    m: &Measurement<'_>,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Identification {
    let mut id = m.identify_pooled();
    id.fit_warnings = guard::check(m, &id, levels, opts);
    id
}

/// As [`identify`], with a caller-supplied basis evaluator (e.g. macro-generated code).
pub fn identify_with(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let ir = &*input_delay::model(ir, opts)?;
    let m = measure(ir, eval, levels, opts)?;
    Ok(guarded(&m, levels, opts))
}

/// Identify separately at each level (for detection: an equivalent-linear parameter that
/// drifts with the level reveals a hidden nonlinearity).
pub fn identify_per_level(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Vec<Identification>, IdentifyError> {
    let ir = &*input_delay::model(ir, opts)?;
    let tape = Tape::compile(ir, &ir.eval_roots());
    let m = measure(ir, &tape, levels, opts)?;
    Ok((0..levels.len()).map(|i| m.identify_level(i)).collect())
}

/// The stacked system `C p = c` of all levels.
pub fn assemble(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<LinearSystem, IdentifyError> {
    let ir = &*input_delay::model(ir, opts)?;
    Ok(measure(ir, eval, levels, opts)?.system())
}
