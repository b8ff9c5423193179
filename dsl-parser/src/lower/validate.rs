//! Validation: the checks that need the whole IR, that is the model against the data it
//! will meet (measured signals) and the identifiability of the parameters' common scale.

use super::Lowerer;
use crate::ast::*;
use crate::error::ErrorKind;
use crate::ir::*;

impl Lowerer<'_> {
    /// Checks that need the whole IR: measured signals, identifiability of the scale.
    pub(super) fn validate(&mut self, ast: &AstModel, ir: &ModelIr, term_spans: &[Vec<Span>]) {
        let measured = |s: SignalId| ir.signals[s.index()].measured;
        for (ei, e) in ir.elements.iter().enumerate() {
            for (ti, t) in e.terms.iter().enumerate() {
                if t.basis == e.v {
                    continue;
                }
                // Where a message points: the term, else its element.
                let span = term_spans
                    .get(ei)
                    .and_then(|s| s.get(ti))
                    .copied()
                    .unwrap_or(ir.spans.elements[ei]);
                // Motion of a body measured only by its acceleration: linear terms are
                // formed from the acceleration, nonlinear ones read integrals of it (both at
                // identification), so the motion counts as available below.
                // An unmeasured velocity of a body whose position is measured is estimated
                // from the position at identification.
                let missing: Vec<SignalId> = ir
                    .expr_signals(t.basis)
                    .into_iter()
                    .filter(|&s| !measured(s))
                    .filter(|&s| match ir.signal(s).kind {
                        SignalKind::Velocity(b) => {
                            !measured(ir.position(b)) && !ir.acceleration_only(b)
                        }
                        SignalKind::Position(b) => !ir.acceleration_only(b),
                        _ => true,
                    })
                    .collect();
                if missing.is_empty() {
                    continue;
                }
                let names: Vec<String> = missing
                    .iter()
                    .map(|&s| format!("`{}`", ir.signal(s).name))
                    .collect();
                let term = crate::print::render_expr(ir, t.basis);
                let any_velocity = missing
                    .iter()
                    .any(|&s| matches!(ir.signal(s).kind, SignalKind::Velocity(_)));
                let help = if any_velocity {
                    format!("a nonlinear function of a velocity needs the velocity or the body's position (from which it is estimated); add {} or the position to `measure`", names.join(" and "))
                } else {
                    format!("add {} to `measure`: a static term is computed from the data sample by sample", names.join(" and "))
                };
                self.err(
                    ErrorKind::UnmeasuredSignal,
                    format!(
                        "term `{term}` of `{}` needs {}, which {} not measured",
                        e.name,
                        names.join(" and "),
                        if names.len() == 1 { "is" } else { "are" }
                    ),
                    span,
                    "needs an unmeasured signal",
                    help,
                );
            }
        }
        for (i, b) in ir.bodies.iter().enumerate() {
            let id = BodyId(i as u32);
            if !measured(ir.position(id))
                && !measured(ir.velocity(id))
                && !ir.acceleration(id).is_some_and(measured)
            {
                self.err(
                    ErrorKind::UnmeasuredSignal,
                    format!("the motion of body `{}` is not measured", b.name),
                    ir.spans.bodies[i],
                    "neither position nor velocity measured",
                    format!("add `{}.x` to `measure`: the inertia term needs the position (or the velocity)", b.name),
                );
            }
        }
        for (j, inp) in ir.inputs.iter().enumerate() {
            if !measured(ir.input_signal(InputId(j as u32))) {
                self.err(
                    ErrorKind::UnmeasuredSignal,
                    format!("input `{}` is not measured", inp.name),
                    ir.spans.inputs[j],
                    "not measured",
                    format!("add `{}` to `measure`: the input force is the right-hand side of the equation", inp.name),
                );
            }
        }
        if ir.unknowns().is_empty() {
            self.err(
                ErrorKind::NothingToIdentify,
                format!("model `{}` has no unknown parameter", ir.name),
                ast.name.span,
                "nothing to identify",
                "mark a parameter as unknown with `~ nominal`, e.g. `spring k1 (ground, m1) ~ 4.0`"
                    .into(),
            );
        } else {
            let known = ir
                .equations
                .iter()
                .flat_map(|e| &e.terms)
                .any(|t| match t.coef.param {
                    None => true,
                    Some(p) => !ir.params[p.index()].is_unknown(),
                });
            if !known {
                self.err(
                    ErrorKind::NoKnownScale,
                    format!("every coefficient of model `{}` is unknown", ir.name),
                    ast.name.span,
                    "no known coefficient",
                    "the equations are homogeneous, so the parameters are only determined up to a common factor; add a measured `input` or make a mass known (`body m1 = 1.0`)".into(),
                );
            }
        }
    }
}
