//! Driven runs: the model driven by recorded input columns, from rest or from the
//! measured state of the first sample.

use super::config::config_error;
use super::error::SimError;
use super::guard::{check_divergence, divergence_limit, Resolution};
use super::law;
use super::mech::{Mechanics, Rk4};
use super::parameter_values;
use crate::describe::std_dev;
use crate::record::Record;
use dynid_ir::ir::{InputId, ModelIr, SignalKind};

/// Drive `ir` with measured inputs and return its simulated response.
///
/// `input` must contain a column for every model input (matched by name; other columns
/// are ignored). The inputs are interpolated linearly between samples. An input computed by
/// a control law needs no column: the law is evaluated at every sample from the simulated
/// state and the references' columns (which are then required) and held until the next
/// sample, so the loop runs closed around the model (see [`super::law`]); the returned
/// record holds the law's values in that input's column. The model starts
/// at rest at the origin at the first sample, so the beginning of the response contains
/// the transient from rest. The returned record has the same time base (`t0`, `ts`,
/// length) and one column per measured signal in IR order; input columns are copies of
/// the driving data.
pub fn simulate_driven(ir: &ModelIr, input: &Record, substeps: usize) -> Result<Record, SimError> {
    simulate_driven_from(ir, input, substeps, Start::Rest)
}

/// How every free run that dynid scores starts (the refinement's fit and score, `simulate
/// --input`, `identify --test`, `diagnose`): [`Start::Measured`], in words for outputs.
pub const FREE_RUN_START: &str = "measured initial state: positions from the first sample, \
velocities from their column or, where not measured, from the first three positions \
(second-order one-sided difference); unmeasured positions at 0";

/// Where a driven run starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Start {
    /// At rest at the origin.
    #[default]
    Rest,
    /// At the state of the record's first sample: a body's position from its `name.x`
    /// column, its velocity from `name.v` or, without one, from the first three positions
    /// (second-order one-sided difference); a body without a position column starts at 0
    /// with the velocity of its `name.v` column, or at rest without one.
    /// Comparing a model with measured responses then starts without a transient from rest.
    Measured,
}

/// [`simulate_driven`] from a chosen initial state.
///
/// Longer than most functions here: after the checks of the input record, the loop is the
/// driven run's inner loop (control laws, recording, hold, RK4), whose state every stage
/// shares, as in the excited run's level loop.
pub fn simulate_driven_from(
    ir: &ModelIr,
    input: &Record,
    substeps: usize,
    start: Start,
) -> Result<Record, SimError> {
    if substeps == 0 {
        return Err(config_error("substeps is 0", "use at least 1 sub-step"));
    }
    if !(input.ts.is_finite() && input.ts > 0.0) {
        return Err(SimError::BadInputData {
            what: format!("sample interval {} is not positive", input.ts),
        });
    }
    if input.len() < 2 {
        return Err(SimError::BadInputData {
            what: format!("{} samples (at least 2 needed)", input.len()),
        });
    }
    let params = parameter_values(ir)?;
    let mech = Mechanics::new(ir, &params)?;
    let by_law = law::controlled(ir);
    let column = |name: &str| -> Result<&[f64], SimError> {
        let col = input
            .column(name)
            .ok_or_else(|| SimError::MissingInputColumn {
                input: name.to_string(),
                found: input.names.join(", "),
            })?;
        if let Some(i) = col.iter().position(|x| !x.is_finite()) {
            return Err(SimError::BadInputData {
                what: format!(
                    "column `{name}` has the non-finite value {} at sample {i}",
                    col[i]
                ),
            });
        }
        Ok(col)
    };
    // A controlled input reads no column: an empty slice stands for it.
    let mut cols: Vec<&[f64]> = Vec::with_capacity(ir.inputs.len());
    for (inp, &law) in ir.inputs.iter().zip(&by_law) {
        cols.push(if law { &[] } else { column(&inp.name)? });
    }
    let refs: Vec<&[f64]> = ir
        .references
        .iter()
        .map(|r| column(&r.name))
        .collect::<Result<_, _>>()?;
    let n = input.len();
    let limit = divergence_limit(
        cols.iter()
            .chain(&refs)
            .filter(|c| !c.is_empty())
            .map(|c| std_dev(c)),
    );
    let mut rk = Rk4::new(&mech);
    if start == Start::Measured {
        set_measured_state(ir, input, &mut rk);
    }
    let mut res = Resolution::new(mech.n_bodies);
    let measured = ir.measured_signals();
    let has_acc = measured
        .iter()
        .any(|&s| matches!(ir.signal(s).kind, SignalKind::Acceleration(_)));
    let mut out: Vec<Vec<f64>> = measured.iter().map(|_| Vec::with_capacity(n)).collect();
    let mut u0 = vec![0.0; cols.len()];
    let mut u1 = vec![0.0; cols.len()];
    let mut r = vec![0.0; ir.references.len()];
    let mut laws = law::Laws::new(ir);
    for k in 0..n {
        for (j, c) in cols.iter().enumerate() {
            if !by_law[j] {
                u0[j] = c[k];
            }
        }
        for (v, c) in r.iter_mut().zip(&refs) {
            *v = c[k];
        }
        if let Some(laws) = &mut laws {
            if let Some(bad) = laws.apply(&rk.x, &rk.v, &r, &mut u0) {
                let value = u0[ir.controls[bad].input.index()];
                let t = input.t0 + k as f64 * input.ts;
                let when = format!("t = {} s", dynid_ir::num::sig(t, 6, false));
                return Err(law::law_error(
                    ir,
                    bad,
                    value,
                    "the driven run".into(),
                    when,
                ));
            }
        }
        if has_acc {
            rk.refresh_accel(&mech, &u0);
        }
        for (col, &s) in out.iter_mut().zip(&measured) {
            col.push(signal_value(ir, s, &rk, &u0, &r));
        }
        if k + 1 == n {
            break;
        }
        for (j, c) in cols.iter().enumerate() {
            // A law's value is held over the sample interval.
            u1[j] = if by_law[j] { u0[j] } else { c[k + 1] };
        }
        rk.advance(&mech, &u0, &u1, input.ts, substeps);
        res.add(&rk.x);
        check_divergence(
            &rk,
            limit,
            || "the driven run".into(),
            || {
                format!(
                    "t = {} s",
                    dynid_ir::num::sig(input.t0 + (k + 1) as f64 * input.ts, 6, false)
                )
            },
        )?;
    }
    Ok(Record {
        names: measured
            .iter()
            .map(|&s| ir.signal(s).name.clone())
            .collect(),
        columns: out,
        ts: input.ts,
        t0: input.t0,
    })
}

#[inline]
/// Initial positions and velocities from the first samples of `rec` (see [`Start::Measured`]).
fn set_measured_state(ir: &ModelIr, rec: &Record, rk: &mut Rk4) {
    let finite = |c: &[f64]| c.iter().take(3).all(|x| x.is_finite());
    for b in 0..ir.bodies.len() {
        let name = |k: usize| ir.signals[2 * b + k].name.as_str();
        let Some(x) = rec.column(name(0)).filter(|c| c.len() >= 3 && finite(c)) else {
            if let Some(v) = rec.column(name(1)).filter(|c| !c.is_empty() && finite(c)) {
                rk.v[b] = v[0];
            }
            continue;
        };
        rk.x[b] = x[0];
        rk.v[b] = match rec.column(name(1)).filter(|c| finite(c)) {
            Some(v) => v[0],
            None => (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * rec.ts),
        };
    }
}

/// The value of signal `s` given the state, the inputs `u` and the references `r`.
pub(super) fn signal_value(
    ir: &ModelIr,
    s: dynid_ir::ir::SignalId,
    rk: &Rk4,
    u: &[f64],
    r: &[f64],
) -> f64 {
    match ir.signal(s).kind {
        SignalKind::Position(b) => rk.x[b.index()],
        SignalKind::Velocity(b) => rk.v[b.index()],
        SignalKind::Input(InputId(i)) => u[i as usize],
        SignalKind::Reference(k) => r.get(k.index()).copied().unwrap_or(0.0),
        // Current after `Rk4::refresh_accel` at this state and these inputs.
        SignalKind::Acceleration(b) => rk.acc[b.index()],
    }
}
