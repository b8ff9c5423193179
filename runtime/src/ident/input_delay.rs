//! The delay of a measured input as an unknown ([`super::types::IdentifyOptions::input_delay`]).
//!
//! A force that acts `τ` later than it is recorded enters its equation as
//! `c u(t − τ) ≈ c u(t) − c τ u̇(t)` (first order in `τ`, which is a fraction of the sample
//! interval where it matters). The known term `c u` stays; `τ` is one more unknown whose
//! term is `−c u̇` — a derivative of a measured signal, formed on the instruments as the
//! velocity of a body measured by its position is (`⟨a u̇⟩ = −⟨a' u⟩ + [a u]/T`; in the rows
//! of the filtered equation `F u̇ = (F u)'`). No derivative of the data is taken.
//!
//! The same term stands for a force that changes between samples in a way the filters'
//! first-order hold does not follow: a current loop updated several times per recorded
//! sample gives a staircase whose path lags the straight line between samples by a fixed
//! fraction of the interval, which biases the damping (the servo bench's axis: 1.4 % in
//! the rows of the filtered equation at ten updates per sample).

use super::types::{IdentifyError, IdentifyOptions};
use dynid_ir::ir::{InputId, ModelIr, ParamId, ParamIr, ParamKind};
use std::borrow::Cow;

/// The delay parameter of input `u` is named `u.delay`: a dotted name, which no parameter
/// a model declares can have.
const SUFFIX: &str = ".delay";

/// The name of input `input`'s delay parameter.
pub(crate) fn name(input: &str) -> String {
    format!("{input}{SUFFIX}")
}

/// Whether `param` names an input's delay (`u.delay`).
pub(crate) fn is_delay(param: &str) -> bool {
    param.ends_with(SUFFIX)
}

/// The model identification solves: `ir` itself, or with the inputs' delays where
/// [`IdentifyOptions::input_delay`] asks for them; refused where that leaves no input
/// with a delay (none is measured).
pub(crate) fn model<'a>(
    ir: &'a ModelIr,
    opts: &IdentifyOptions,
) -> Result<Cow<'a, ModelIr>, IdentifyError> {
    if !opts.input_delay {
        return Ok(Cow::Borrowed(ir));
    }
    let out = extend(ir);
    if !(0..out.inputs.len()).any(|i| param_of(&out, InputId(i as u32)).is_some()) {
        return Err(IdentifyError::NoInputToDelay {
            model: ir.name.clone(),
        });
    }
    Ok(Cow::Owned(out))
}

/// Whether input `i` is measured: an input that can be given a delay ([`extend`]).
fn delayable(ir: &ModelIr, i: usize) -> bool {
    ir.signal(ir.input_signal(InputId(i as u32))).measured
}

/// Whether `ir` has an input that can be given a delay (a measured one).
pub(crate) fn any_delayable(ir: &ModelIr) -> bool {
    (0..ir.inputs.len()).any(|i| delayable(ir, i))
}

/// The model with an unknown delay `u.delay` (seconds) for each measured input that has
/// none yet, appended after the model's own parameters (their columns keep their order).
pub(crate) fn extend(ir: &ModelIr) -> ModelIr {
    let mut out = ir.clone();
    for (i, input) in ir.inputs.iter().enumerate() {
        let name = name(&input.name);
        if delayable(ir, i) && !out.params.iter().any(|p| p.name == name) {
            out.params.push(ParamIr {
                name,
                kind: ParamKind::Unknown { nominal: None },
            });
        }
    }
    out
}

/// The delay parameter of input `i`, if the model has one ([`extend`]).
pub(crate) fn param_of(ir: &ModelIr, i: InputId) -> Option<ParamId> {
    let name = name(&ir.inputs.get(i.index())?.name);
    ir.params
        .iter()
        .position(|p| p.name == name)
        .map(|k| ParamId(k as u32))
}
