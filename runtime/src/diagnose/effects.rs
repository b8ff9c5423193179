//! The library of unmodelled effects, the sites where they may act, and how a candidate is
//! added to a model: a new force element on the IR (`ModelIr::add_force`), its coefficient
//! an unknown with nominal 0.

use dynid_ir::edit::NewTerm;
use dynid_ir::ir::{BinaryOp, ExprArena, ExprId, ExprNode, ModelIr, UnaryOp};
use dynid_ir::num;
use serde::Serialize;

/// An unmodelled effect of the library.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Effect {
    Cubic,
    /// An asymmetric spring: stiffer in one direction than the other.
    QuadraticStiffness,
    Coulomb,
    QuadraticDamping,
    Backlash {
        gap: f64,
    },
    Prestress,
    /// A constant force on a body (gravity on an inclined axis, a cable, an amplifier's
    /// bias): the element `force off (ground, m) = f0`, its basis the number 1. Its sites
    /// are the bodies against ground; its value is a force in N.
    ConstantForce,
}

impl Effect {
    pub fn name(&self) -> String {
        match self {
            Effect::Cubic => "cubic stiffness s^3".into(),
            Effect::QuadraticStiffness => "quadratic (asymmetric) stiffness s^2".into(),
            Effect::Coulomb => "Coulomb friction sign(v)".into(),
            Effect::QuadraticDamping => "quadratic damping v*abs(v)".into(),
            Effect::Backlash { gap } => format!("backlash deadzone(s, {})", num::exact(*gap)),
            Effect::Prestress => "prestress sign(s)".into(),
            Effect::ConstantForce => "constant force".into(),
        }
    }
    /// The unit of the effect's value where it is a force (the constant force, in N); the
    /// other coefficients have the units of force per unit of their basis.
    pub fn unit(&self) -> Option<&'static str> {
        matches!(self, Effect::ConstantForce).then_some("N")
    }
    /// Short kind name, stable for machines.
    pub fn kind(&self) -> &'static str {
        match self {
            Effect::Cubic => "cubic",
            Effect::QuadraticStiffness => "quadratic_stiffness",
            Effect::Coulomb => "coulomb",
            Effect::QuadraticDamping => "quadratic_damping",
            Effect::Backlash { .. } => "backlash",
            Effect::Prestress => "prestress",
            Effect::ConstantForce => "constant_force",
        }
    }
    /// The effect's basis function of an element's relative displacement `s` and velocity
    /// `v`, built into the model's expression DAG.
    fn basis(&self, arena: &mut ExprArena, s: ExprId, v: ExprId) -> ExprId {
        match *self {
            Effect::Cubic => arena.intern(ExprNode::Powi(s, 3)),
            Effect::QuadraticStiffness => arena.intern(ExprNode::Powi(s, 2)),
            Effect::Coulomb => arena.unary(UnaryOp::Sign, v),
            Effect::QuadraticDamping => {
                let a = arena.unary(UnaryOp::Abs, v);
                arena.binary(BinaryOp::Mul, v, a)
            }
            Effect::Backlash { gap } => arena.intern(ExprNode::Deadzone(s, gap.to_bits())),
            Effect::Prestress => arena.unary(UnaryOp::Sign, s),
            // The basis the language gives a term that is a parameter alone.
            Effect::ConstantForce => arena.constant(1.0),
        }
    }
    pub(super) fn param_stem(&self) -> &'static str {
        match self {
            Effect::Cubic => "k3",
            Effect::QuadraticStiffness => "k2",
            Effect::Coulomb => "r",
            Effect::QuadraticDamping => "q",
            Effect::Backlash { .. } => "kb",
            Effect::Prestress => "f0",
            Effect::ConstantForce => "offset",
        }
    }
    pub(super) fn needs_velocity(&self) -> bool {
        matches!(self, Effect::Coulomb | Effect::QuadraticDamping)
    }
    /// Friction, damping, backlash and preload dissipate or resist: a negative coefficient
    /// is unphysical. A cubic term may harden or soften; the sign of a quadratic term only
    /// says in which direction the spring is stiffer; a constant force pushes either way.
    pub(super) fn sign_ok(&self, p: f64) -> bool {
        matches!(
            self,
            Effect::Cubic | Effect::QuadraticStiffness | Effect::ConstantForce
        ) || p >= 0.0
    }
}

/// Where a candidate acts: between two nodes (an existing element's or body to ground).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Location {
    pub a: String,
    pub b: String,
    /// Names of the existing elements between these nodes (empty: a new body-to-ground site).
    pub elements: Vec<String>,
}

impl Location {
    pub fn label(&self) -> String {
        format!("({}, {})", self.a, self.b)
    }
}

/// The candidate sites: every node pair that carries an element, then every body to ground.
pub(super) fn locations(ir: &ModelIr) -> Vec<Location> {
    let mut out: Vec<Location> = ir
        .element_groups()
        .into_iter()
        .map(|g| Location {
            a: ir.node_name(g.nodes.0).to_string(),
            b: ir.node_name(g.nodes.1).to_string(),
            elements: g
                .members
                .iter()
                .map(|e| ir.elements[e.index()].name.clone())
                .collect(),
        })
        .collect();
    for body in &ir.bodies {
        let b = body.name.clone();
        if !out
            .iter()
            .any(|l| (l.a == "ground" && l.b == b) || (l.b == "ground" && l.a == b))
        {
            out.push(Location {
                a: "ground".into(),
                b,
                elements: vec![],
            });
        }
    }
    out
}

/// The sites of a constant force: every body against ground, written `(ground, body)` (the
/// element pushes the body by `−f0`, as `force off (ground, m) = f0` does), with the
/// elements that already join the body to ground. A constant force between two bodies is
/// an internal force, which no rig supplies unaided.
pub(super) fn constant_force_sites(ir: &ModelIr, locs: &[Location]) -> Vec<Location> {
    ir.bodies
        .iter()
        .map(|body| {
            let b = body.name.clone();
            let elements = locs
                .iter()
                .find(|l| (l.a == "ground" && l.b == b) || (l.b == "ground" && l.a == b))
                .map(|l| l.elements.clone())
                .unwrap_or_default();
            Location {
                a: "ground".into(),
                b,
                elements,
            }
        })
        .collect()
}

/// A model variant: the model with the added force elements.
#[derive(Clone)]
pub(super) struct Variant {
    pub(super) ir: ModelIr,
    /// Parameter names of the added terms.
    pub(super) added: Vec<String>,
}

impl Variant {
    /// This variant with a candidate added: the candidate's model `ir` and its new
    /// parameter `p`.
    pub(super) fn with(&self, ir: ModelIr, p: String) -> Variant {
        let mut added = self.added.clone();
        added.push(p);
        Variant { ir, added }
    }
}

/// `base` with `effect` added as a new force element at `loc`, its coefficient an unknown
/// with nominal 0; returns the model and the new parameter's name.
pub(super) fn add_effect(
    base: &ModelIr,
    effect: Effect,
    loc: &Location,
) -> Option<(ModelIr, String)> {
    let mut ir = base.clone();
    let el = ir.fresh_name("gap_fix");
    let p = ir.fresh_name(&format!("{}_fix", effect.param_stem()));
    let basis = |arena: &mut ExprArena, s: ExprId, v: ExprId| effect.basis(arena, s, v);
    let term = NewTerm {
        param: &p,
        nominal: Some(0.0),
        basis: &basis,
    };
    ir.add_force(&el, (&loc.a, &loc.b), &[term]).ok()?;
    Some((ir, p))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every effect added on the IR gives the model that compiling the same element,
    /// written in the language, gives: the same equations and the same printed source.
    #[test]
    fn an_effect_added_on_the_ir_is_the_written_element() {
        let src = "model a {\n    body m = 1\n    body n = 2\n    input u on m\n    spring k (ground, m) ~ 4\n    spring k2 (m, n) ~ 1\n}\n";
        let ir = dsl_parser::compile_str("a", src).unwrap();
        let cases = [
            (Effect::Cubic, "r ~ 0 * s^3"),
            (Effect::QuadraticStiffness, "r ~ 0 * s^2"),
            (Effect::Coulomb, "r ~ 0 * sign(v)"),
            (Effect::QuadraticDamping, "r ~ 0 * v * abs(v)"),
            (Effect::Backlash { gap: 0.25 }, "r ~ 0 * deadzone(s, 0.25)"),
            (Effect::Prestress, "r ~ 0 * sign(s)"),
            (Effect::ConstantForce, "r ~ 0"),
        ];
        for loc in &locations(&ir) {
            for (effect, text) in cases {
                let (edited, p) = add_effect(&ir, effect, loc).unwrap();
                let stem = effect.param_stem();
                assert_eq!(p, format!("{stem}_fix"));
                let line = format!(
                    "    force gap_fix ({}, {}) = {}\n}}\n",
                    loc.a,
                    loc.b,
                    text.replacen('r', &p, 1)
                );
                let written = src.replacen("}\n", &line, 1);
                let compiled = dsl_parser::compile_str("a", &written).unwrap();
                let printed = dynid_ir::print::to_source(&edited);
                assert_eq!(printed, dynid_ir::print::to_source(&compiled), "{written}");
                assert_eq!(
                    dynid_ir::print::render_equations(&edited),
                    dynid_ir::print::render_equations(&compiled)
                );
                // The printed model compiles back to the edited one.
                let again = dsl_parser::compile_str("a", &printed).unwrap();
                assert_eq!(dynid_ir::print::to_source(&again), printed);
            }
        }
    }
}
