//! The FRF of a model's linear part: `M`, `D`, `K`, `B` from the equations (expression
//! terms linearised at the origin), then `H(jω) = −(−ω²M + jωD + K)⁻¹ B` per frequency.

use dynid_ir::ir::{Basis, ModelIr, ParamKind, SignalId};
use nalgebra::{Complex as NComplex, DMatrix, DVector};
use std::f64::consts::PI;

/// The linear part of a model at parameter values `values` (index = `ParamId`): the
/// equations `M ẍ + D ẋ + K x + B u = 0`, one row per body, `B` one column per input.
/// Expression terms are linearised at the origin (central differences), so a nonlinear
/// model gives its tangent model there.
pub struct LinearModel {
    pub m: DMatrix<f64>,
    pub d: DMatrix<f64>,
    pub k: DMatrix<f64>,
    pub b: DMatrix<f64>,
}

impl LinearModel {
    pub fn new(ir: &ModelIr, values: &[f64]) -> Self {
        let nb = ir.bodies.len();
        let ni = ir.inputs.len();
        let mut lm = LinearModel {
            m: DMatrix::zeros(nb, nb),
            d: DMatrix::zeros(nb, nb),
            k: DMatrix::zeros(nb, nb),
            b: DMatrix::zeros(nb, ni),
        };
        let mut sig = vec![0.0; ir.signals.len()];
        for eq in &ir.equations {
            let row = eq.body.index();
            for t in &eq.terms {
                let c = t.coef.scale * t.coef.param.map_or(1.0, |p| values[p.index()]);
                match t.basis {
                    Basis::Deriv { body, order: 2 } => lm.m[(row, body.index())] += c,
                    Basis::Deriv { body, .. } => lm.d[(row, body.index())] += c,
                    Basis::Expr(e) => {
                        let h = 1e-4;
                        for (s, slot) in (0..ir.signals.len()).map(|s| (s, classify(ir, s))) {
                            let Some(slot) = slot else { continue };
                            sig[s] = h;
                            let up = ir.eval_scalar(e, &sig);
                            sig[s] = -h;
                            let dn = ir.eval_scalar(e, &sig);
                            sig[s] = 0.0;
                            let g = c * (up - dn) / (2.0 * h);
                            if g == 0.0 || !g.is_finite() {
                                continue;
                            }
                            match slot {
                                Slot::X(j) => lm.k[(row, j)] += g,
                                Slot::V(j) => lm.d[(row, j)] += g,
                                Slot::U(i) => lm.b[(row, i)] += g,
                            }
                        }
                    }
                }
            }
        }
        lm
    }

    /// `H(jω)` of every body's position to input `input`: `−(−ω²M + jωD + K)⁻¹ B[:, input]`
    /// (the equations' sign convention), `None` where the matrix is singular.
    pub fn position_frf(&self, input: usize, omega: f64) -> Option<Vec<NComplex<f64>>> {
        let n = self.m.nrows();
        let a = DMatrix::from_fn(n, n, |i, j| {
            NComplex::new(
                self.k[(i, j)] - omega * omega * self.m[(i, j)],
                omega * self.d[(i, j)],
            )
        });
        let rhs = DVector::from_fn(n, |i, _| NComplex::new(-self.b[(i, input)], 0.0));
        let x = a.lu().solve(&rhs)?;
        Some(x.iter().copied().collect())
    }
}

enum Slot {
    X(usize),
    V(usize),
    U(usize),
}

fn classify(ir: &ModelIr, s: usize) -> Option<Slot> {
    let nb = ir.bodies.len();
    if s < 2 * nb {
        Some(if s.is_multiple_of(2) {
            Slot::X(s / 2)
        } else {
            Slot::V(s / 2)
        })
    } else if s < 2 * nb + ir.inputs.len() {
        Some(Slot::U(s - 2 * nb))
    } else {
        None
    }
}

/// Value of every parameter: `known` for a known one, else `estimate(name)`, else its
/// nominal; `None` when an unknown parameter has neither.
pub fn parameter_values(ir: &ModelIr, estimate: impl Fn(&str) -> Option<f64>) -> Option<Vec<f64>> {
    ir.params
        .iter()
        .map(|p| match p.kind {
            ParamKind::Known(v) => Some(v),
            ParamKind::Unknown { nominal } => estimate(&p.name).or(nominal),
        })
        .collect()
}

/// The model's FRF to `input` of each signal in `outputs` (positions; a velocity is the
/// position's FRF times `jω`) at `freq_hz`, as `[re, im]`; `None` where singular.
pub fn model_frf(
    ir: &ModelIr,
    lm: &LinearModel,
    input: usize,
    outputs: &[SignalId],
    freq_hz: &[f64],
) -> Vec<Vec<Option<[f64; 2]>>> {
    let per_freq: Vec<Option<Vec<NComplex<f64>>>> = freq_hz
        .iter()
        .map(|f| lm.position_frf(input, 2.0 * PI * f))
        .collect();
    let nb = ir.bodies.len();
    outputs
        .iter()
        .map(|s| {
            let s = s.index();
            per_freq
                .iter()
                .zip(freq_hz)
                .map(|(x, f)| {
                    let x = x.as_ref()?;
                    if s >= 2 * nb {
                        return None;
                    }
                    let h = x[s / 2];
                    let h = if s % 2 == 1 {
                        h * NComplex::new(0.0, 2.0 * PI * f)
                    } else {
                        h
                    };
                    (h.re.is_finite() && h.im.is_finite()).then_some([h.re, h.im])
                })
                .collect()
        })
        .collect()
}
