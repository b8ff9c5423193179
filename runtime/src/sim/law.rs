//! Control laws of the modelling language (`control u = …`): inputs computed in closed
//! loop from the state and the references.
//!
//! A law is evaluated at the start of each controller update from the bodies' simulated
//! positions and velocities and the references' current values, and its value is held
//! over the update interval (zero-order hold), as a digital drive does. The state the law
//! reads is the true one: a law written with `m.v` uses the simulated velocity, whether
//! or not the data hold a velocity column (a drive estimating its velocity from an encoder
//! differs from this by its estimator's lag and noise). In [`super::simulate`] the
//! controller updates on the input grid (`sample / input_oversample`); in a driven run
//! ([`super::simulate_driven`]) once per sample, with the references read from the data.

use crate::tape::Tape;
use dynid_ir::ir::ModelIr;

/// The compiled control laws of a model, with their scratch space (one per run).
pub(crate) struct Laws {
    tape: Tape,
    /// The input each law computes (index into the model's inputs), in law order.
    inputs: Vec<usize>,
    n_bodies: usize,
    n_inputs: usize,
    signals: Vec<f64>,
    regs: Vec<f64>,
    out: Vec<f64>,
}

impl Laws {
    /// `None` when the model has no control law.
    pub(crate) fn new(ir: &ModelIr) -> Option<Laws> {
        if ir.controls.is_empty() {
            return None;
        }
        let roots: Vec<_> = ir.controls.iter().map(|c| c.law).collect();
        let tape = Tape::compile(ir, &roots);
        Some(Laws {
            regs: vec![0.0; tape.ops.len()],
            out: vec![0.0; roots.len()],
            signals: vec![0.0; ir.signals.len()],
            tape,
            inputs: ir.controls.iter().map(|c| c.input.index()).collect(),
            n_bodies: ir.bodies.len(),
            n_inputs: ir.inputs.len(),
        })
    }

    /// Hold every law's value over the next step: copy it from `from` into `to`.
    pub(crate) fn hold(&self, from: &[f64], to: &mut [f64]) {
        for &i in &self.inputs {
            to[i] = from[i];
        }
    }

    /// Write every law's value into `u[input]`, from positions `x`, velocities `v` and
    /// reference values `r` (other inputs in `u` are left as they are and not read).
    ///
    /// Returns the index (in `ir.controls`) of the first law whose value is not finite
    /// while everything it reads is (`sqrt` of a negative error, a division by a signal
    /// that is zero): the law's own fault, which the caller reports as such rather than as
    /// a diverging model.
    #[must_use]
    pub(crate) fn apply(
        &mut self,
        x: &[f64],
        v: &[f64],
        r: &[f64],
        u: &mut [f64],
    ) -> Option<usize> {
        let nb = self.n_bodies;
        for b in 0..nb {
            self.signals[2 * b] = x[b];
            self.signals[2 * b + 1] = v[b];
        }
        let refs = 2 * nb + self.n_inputs;
        self.signals[refs..refs + r.len()].copy_from_slice(r);
        self.tape
            .eval_point(&self.signals, &mut self.regs, &mut self.out);
        for (&i, &value) in self.inputs.iter().zip(&self.out) {
            u[i] = value;
        }
        let read_finite = || self.signals.iter().all(|s| s.is_finite());
        match self.out.iter().position(|o| !o.is_finite()) {
            Some(k) if read_finite() => Some(k),
            _ => None,
        }
    }
}

/// The error for law `k` of `ir` giving `value` at `context`, `when` (in words).
pub(crate) fn law_error(
    ir: &ModelIr,
    k: usize,
    value: f64,
    context: String,
    when: String,
) -> super::SimError {
    let c = &ir.controls[k];
    super::SimError::ControlLaw {
        law: format!(
            "{} = {}",
            ir.inputs[c.input.index()].name,
            dynid_ir::print::render_expr(ir, c.law)
        ),
        value: if value.is_nan() {
            "NaN".into()
        } else {
            format!("{value}")
        },
        context,
        when,
    }
}

/// A time of the run in words: seconds since the run started, and where the record is.
pub(crate) fn run_time(time: f64, record_start: f64) -> String {
    let t = dynid_ir::num::sig(time, 6, false);
    if time < record_start {
        format!(
            "{t} s after the start, during the warm-up (the record starts at {} s)",
            dynid_ir::num::sig(record_start, 6, false)
        )
    } else {
        format!(
            "{t} s after the start, t = {} s in the record",
            dynid_ir::num::sig(time - record_start, 6, false)
        )
    }
}

/// The inputs of `ir` that a control law computes.
pub(crate) fn controlled(ir: &ModelIr) -> Vec<bool> {
    let mut out = vec![false; ir.inputs.len()];
    for c in &ir.controls {
        out[c.input.index()] = true;
    }
    out
}
