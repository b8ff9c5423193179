//! Driven runs: the model driven by recorded input columns, from rest or from the
//! measured state of the first sample.

use super::*;

/// Drive `ir` with measured inputs and return its simulated response.
///
/// `input` must contain a column for every model input (matched by name; other columns
/// are ignored). The inputs are interpolated linearly between samples. The model starts
/// at rest at the origin at the first sample, so the beginning of the response contains
/// the transient from rest. The returned record has the same time base (`t0`, `ts`,
/// length) and one column per measured signal in IR order; input columns are copies of
/// the driving data.
pub fn simulate_driven(ir: &ModelIr, input: &Record, substeps: usize) -> Result<Record, SimError> {
    simulate_driven_from(ir, input, substeps, Start::Rest)
}

/// Where a driven run starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Start {
    /// At rest at the origin.
    #[default]
    Rest,
    /// At the state of the record's first sample: a body's position from its `name.x`
    /// column, its velocity from `name.v` or, without one, from the first three positions
    /// (second-order one-sided difference); a body without a position column starts at rest.
    /// Comparing a model with measured responses then starts without a transient from rest.
    Measured,
}

/// [`simulate_driven`] from a chosen initial state.
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
    let mut cols: Vec<&[f64]> = Vec::with_capacity(ir.inputs.len());
    for inp in &ir.inputs {
        let col = input
            .column(&inp.name)
            .ok_or_else(|| SimError::MissingInputColumn {
                input: inp.name.clone(),
                found: input.names.join(", "),
            })?;
        if let Some(i) = col.iter().position(|x| !x.is_finite()) {
            return Err(SimError::BadInputData {
                what: format!(
                    "column `{}` has the non-finite value {} at sample {i}",
                    inp.name, col[i]
                ),
            });
        }
        cols.push(col);
    }
    let n = input.len();
    let limit = divergence_limit(cols.iter().map(|c| std_dev(c)));
    let mut rk = Rk4::new(&mech);
    if start == Start::Measured {
        set_measured_state(ir, input, &mut rk);
    }
    let mut res = Resolution::new(mech.n_bodies);
    let measured = ir.measured_signals();
    let mut out: Vec<Vec<f64>> = measured.iter().map(|_| Vec::with_capacity(n)).collect();
    let mut u0 = vec![0.0; cols.len()];
    let mut u1 = vec![0.0; cols.len()];
    for k in 0..n {
        for (j, c) in cols.iter().enumerate() {
            u0[j] = c[k];
        }
        for (col, &s) in out.iter_mut().zip(&measured) {
            col.push(signal_value(ir, s, &rk, &u0));
        }
        if k + 1 == n {
            break;
        }
        for (j, c) in cols.iter().enumerate() {
            u1[j] = c[k + 1];
        }
        rk.advance(&mech, &u0, &u1, input.ts, substeps);
        res.add(&rk.x);
        check_divergence(
            &rk,
            limit,
            || "the driven run".into(),
            input.t0 + (k + 1) as f64 * input.ts,
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
            continue;
        };
        rk.x[b] = x[0];
        rk.v[b] = match rec.column(name(1)).filter(|c| finite(c)) {
            Some(v) => v[0],
            None => (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * rec.ts),
        };
    }
}

pub(super) fn signal_value(ir: &ModelIr, s: dynid_ir::ir::SignalId, rk: &Rk4, u: &[f64]) -> f64 {
    match ir.signal(s).kind {
        SignalKind::Position(b) => rk.x[b.index()],
        SignalKind::Velocity(b) => rk.v[b.index()],
        SignalKind::Input(InputId(i)) => u[i as usize],
    }
}
