//! `ModelIr`: the plain-data contract between the front end and every back end.
//!
//! Invariants (checked by [`ModelIr::check_invariants`] in debug builds and tests):
//! - `exprs` is topologically ordered: a node only refers to nodes with smaller ids, and the
//!   DAG is hash-consed, so structurally equal sub-expressions share one id.
//! - `bodies[i]` is degree of freedom `i`; its position and velocity signals are
//!   `signals[2 i]` and `signals[2 i + 1]`; input `j` is `signals[2 n_bodies + j]`;
//!   reference `k` is `signals[2 n_bodies + n_inputs + k]`; after the references come the
//!   acceleration signals `name.a` of the bodies measured by accelerometers (body order,
//!   one each, present only for those bodies: a model without them has the same signal
//!   table, and the same JSON, as before accelerations existed).
//! - `equations[i]` is the equation of motion of body `i`, written as `Σ coef · basis = 0`
//!   (input forces appear as terms with a known coefficient −1).
//! - Every parameter is used by at least one term (validation rejects unused parameters).
//!
//! No pest, syn or I/O types appear here; spans are byte ranges into the source the model
//! was compiled from, kept in side tables so that late errors can point at the `.dyn` line.

use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// A byte range `[start, end)` in the model source.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Span {
    pub start: usize,
    pub end: usize,
}

impl Span {
    pub fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }
}

macro_rules! typed_id {
    ($($name:ident),*) => {$(
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        #[serde(transparent)]
        pub struct $name(pub u32);
        impl $name {
            pub fn index(self) -> usize { self.0 as usize }
        }
    )*};
}
typed_id!(
    BodyId,
    InputId,
    ReferenceId,
    ParamId,
    ElementId,
    SignalId,
    ExprId
);

/// What a signal is. Signal names: body `m1` gives `m1.x` and `m1.v` (and `m1.a` where its
/// acceleration is measured); input `u` is `u`; reference `r` is `r`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SignalKind {
    Position(BodyId),
    Velocity(BodyId),
    Input(InputId),
    /// A measured set point: read only by control laws, never by a force.
    Reference(ReferenceId),
    /// The measured acceleration `ẍ` of a body (an accelerometer). It is a column of the
    /// data only: forces never read it (the inertia term `m ẍ` is a derivative basis).
    Acceleration(BodyId),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SignalIr {
    pub name: String,
    pub kind: SignalKind,
    /// Present as a column in measured data.
    pub measured: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyIr {
    pub name: String,
    /// The mass: a known constant or a parameter.
    pub mass: Coef,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InputIr {
    pub name: String,
    /// The body the input force acts on (positive along the body's coordinate).
    pub body: BodyId,
}

/// `reference r`: an exogenous, measured signal (a set point) that control laws read.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceIr {
    pub name: String,
}

/// `control u = law`: in a simulation the input `u` is not driven by its data or form
/// filter but computed from the law, an expression of body signals, references and
/// constants (known parameters are folded in). Identification ignores the law and uses
/// the measured `u`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControlIr {
    pub input: InputId,
    pub law: ExprId,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ParamKind {
    /// A value the user knows; its terms move to the right-hand side.
    Known(f64),
    /// To be identified. The nominal value is the simulation model's value.
    Unknown { nominal: Option<f64> },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamIr {
    pub name: String,
    pub kind: ParamKind,
}

impl ParamIr {
    pub fn is_unknown(&self) -> bool {
        matches!(self.kind, ParamKind::Unknown { .. })
    }
    /// The value used for simulation: the known value or the nominal one.
    pub fn nominal(&self) -> Option<f64> {
        match self.kind {
            ParamKind::Known(v) => Some(v),
            ParamKind::Unknown { nominal } => nominal,
        }
    }
}

/// A coefficient `scale · param` (or just `scale` when `param` is `None`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Coef {
    pub scale: f64,
    pub param: Option<ParamId>,
}

impl Coef {
    pub fn constant(scale: f64) -> Self {
        Coef { scale, param: None }
    }
    pub fn param(p: ParamId) -> Self {
        Coef {
            scale: 1.0,
            param: Some(p),
        }
    }
    pub fn scaled(self, by: f64) -> Self {
        Coef {
            scale: self.scale * by,
            param: self.param,
        }
    }
}

/// Elements between the same two nodes (see [`ModelIr::element_groups`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ElementGroup {
    /// The nodes as the group's first element writes them.
    pub nodes: (Node, Node),
    pub members: Vec<ElementId>,
}

/// One end of an element.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Node {
    Ground,
    Body(BodyId),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ElementKind {
    Spring,
    Damper,
    Force,
}

/// A force element between two nodes. With `s = x(b) − x(a)` and `v = v(b) − v(a)` the
/// element force `f = Σ coef · basis(s, v, inputs)` pushes `a` by `+f` and `b` by `−f`
/// (a positive `f` resists extension, as a spring does).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ElementIr {
    pub name: String,
    pub kind: ElementKind,
    pub nodes: (Node, Node),
    /// The relative displacement `s` and velocity `v` as expressions over signals.
    pub s: ExprId,
    pub v: ExprId,
    /// The force terms, with `s` and `v` already substituted.
    pub terms: Vec<ForceTerm>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ForceTerm {
    pub coef: Coef,
    pub basis: ExprId,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum UnaryOp {
    Neg,
    Abs,
    Sign,
    Tanh,
    Sqrt,
    Exp,
    /// Sine of an angle in radians (a position-periodic force: `sin(2π s / p)`).
    Sin,
    Cos,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum BinaryOp {
    Add,
    Sub,
    Mul,
    Div,
}

impl UnaryOp {
    /// The operation's value at `a` (the one definition every evaluator uses).
    #[inline]
    pub fn apply(self, a: f64) -> f64 {
        match self {
            UnaryOp::Neg => -a,
            UnaryOp::Abs => a.abs(),
            UnaryOp::Sign => sign(a),
            UnaryOp::Tanh => a.tanh(),
            UnaryOp::Sqrt => a.sqrt(),
            UnaryOp::Exp => a.exp(),
            UnaryOp::Sin => a.sin(),
            UnaryOp::Cos => a.cos(),
        }
    }
}

impl BinaryOp {
    /// The operation's value at `(a, b)`.
    #[inline]
    pub fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            BinaryOp::Add => a + b,
            BinaryOp::Sub => a - b,
            BinaryOp::Mul => a * b,
            BinaryOp::Div => a / b,
        }
    }
}

/// A node of the expression DAG. Constants are stored as bit patterns so nodes can be
/// hash-consed; use [`ExprNode::constant`] and [`f64::from_bits`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ExprNode {
    Const(u64),
    Signal(SignalId),
    Unary(UnaryOp, ExprId),
    Binary(BinaryOp, ExprId, ExprId),
    /// Integer power.
    Powi(ExprId, i32),
    /// `deadzone(a, gap)`: 0 for |a| ≤ gap, else `a − gap·sign(a)`. The gap is a constant.
    Deadzone(ExprId, u64),
    /// `saturate(a, limit)`: `a` clamped to [−limit, limit]. The limit is a constant.
    Saturate(ExprId, u64),
}

impl ExprNode {
    pub fn constant(v: f64) -> Self {
        // Normalise −0.0 so that equal constants hash equally.
        ExprNode::Const(if v == 0.0 {
            0.0f64.to_bits()
        } else {
            v.to_bits()
        })
    }
    /// The children of this node, in order.
    pub fn children(&self) -> impl Iterator<Item = ExprId> {
        let (a, b) = match *self {
            ExprNode::Const(_) | ExprNode::Signal(_) => (None, None),
            ExprNode::Unary(_, a)
            | ExprNode::Powi(a, _)
            | ExprNode::Deadzone(a, _)
            | ExprNode::Saturate(a, _) => (Some(a), None),
            ExprNode::Binary(_, a, b) => (Some(a), Some(b)),
        };
        a.into_iter().chain(b)
    }
}

/// The thing a coefficient multiplies in an equation of motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Basis {
    /// A static function of signals (which may include velocities), or the constant 1 of a
    /// constant force.
    Expr(ExprId),
    /// The `order`-th time derivative (1 or 2) of a body's position. Terms linear in a
    /// velocity are lowered to `Deriv { order: 1 }` so that a back end can move the
    /// derivative onto its filter when the velocity is not measured.
    Deriv { body: BodyId, order: u8 },
}

/// Where a term of an equation comes from (for printing and diagnostics).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum TermOrigin {
    Inertia(BodyId),
    Element(ElementId),
    Input(InputId),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TermIr {
    pub coef: Coef,
    pub basis: Basis,
    pub origin: TermOrigin,
}

/// The equation of motion of one body: `Σ terms = 0`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EquationIr {
    pub body: BodyId,
    pub terms: Vec<TermIr>,
}

/// How simulation drives an input or a reference: a form filter (Schiehlen & Krause eq. 2;
/// docs/method.md, References) that turns white noise of intensity `level` into the signal,
/// or a planned trajectory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum FormFilter {
    /// `u' = −corner·u + level·w`.
    Lowpass { corner: f64 },
    /// `u'' + 2 damping freq u' + freq² u = level·w`.
    SecondOrder { freq: f64, damping: f64 },
    /// `u = level·w` band-limited to the sample rate (white, held per sample).
    White,
    /// Planned point-to-point moves, no noise: a cycle of six moves of `distance`, out
    /// and back at `speed`, `speed/2` and `speed/4` (peak acceleration `accel`, smooth
    /// velocity profile), each after `dwell` seconds at rest, repeated. Level `L` runs
    /// every move `L` times as fast (speeds × L, accelerations × L²); dwells stay.
    Moves {
        distance: f64,
        speed: f64,
        accel: f64,
        dwell: f64,
    },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExcitationIr {
    pub input: InputId,
    pub filter: FormFilter,
    /// Intensities of the white noise, one per excitation level.
    pub levels: Vec<f64>,
}

/// `excite r: …` on a reference: the set point of a closed-loop experiment is the output of
/// the form filter, level by level as for an input.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceExcitationIr {
    pub reference: ReferenceId,
    pub filter: FormFilter,
    pub levels: Vec<f64>,
}

/// A user-specified identification filter bank.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FilterSpecIr {
    /// Corner frequencies in rad/s.
    pub corners: Vec<f64>,
    /// Order of each low-pass chain (≥ 2 so displacement-only data works).
    pub order: u32,
    /// Signals driving the bank; empty means the default (measured positions and inputs).
    pub driven_by: Vec<SignalId>,
}

/// Spans of declarations, for errors raised after lowering.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SpanTable {
    pub bodies: Vec<Span>,
    pub inputs: Vec<Span>,
    pub params: Vec<Span>,
    pub elements: Vec<Span>,
    #[serde(default)]
    pub references: Vec<Span>,
    #[serde(default)]
    pub controls: Vec<Span>,
    /// Span of the whole `model` item.
    pub model: Span,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelIr {
    pub name: String,
    pub bodies: Vec<BodyIr>,
    pub inputs: Vec<InputIr>,
    pub params: Vec<ParamIr>,
    pub signals: Vec<SignalIr>,
    pub elements: Vec<ElementIr>,
    pub exprs: Vec<ExprNode>,
    pub equations: Vec<EquationIr>,
    pub excitation: Vec<ExcitationIr>,
    pub filter: Option<FilterSpecIr>,
    pub spans: SpanTable,
    /// Set points of closed loops (their signals follow the inputs').
    #[serde(default)]
    pub references: Vec<ReferenceIr>,
    /// Control laws, at most one per input.
    #[serde(default)]
    pub controls: Vec<ControlIr>,
    #[serde(default)]
    pub reference_excitation: Vec<ReferenceExcitationIr>,
    /// Shape parameters: unknown gaps and limits (`deadzone(s, g ~ 0.05)`).
    #[serde(default)]
    pub shapes: Vec<ShapeIr>,
}

/// An unknown that enters nonlinearly, as the gap of a `deadzone` or the limit of a
/// `saturate`: not a least-squares column, but profiled (each trial value is a linear
/// least-squares problem). The nodes in `sites` hold the current value as their constant;
/// [`ModelIr::with_shapes`] rewrites them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeIr {
    pub name: String,
    /// The starting (simulation) value.
    pub nominal: f64,
    /// `Deadzone` or `Saturate` nodes whose constant is this parameter.
    pub sites: Vec<ExprId>,
}

impl ModelIr {
    pub fn position(&self, b: BodyId) -> SignalId {
        SignalId(2 * b.0)
    }
    pub fn velocity(&self, b: BodyId) -> SignalId {
        SignalId(2 * b.0 + 1)
    }
    pub fn input_signal(&self, i: InputId) -> SignalId {
        SignalId(2 * self.bodies.len() as u32 + i.0)
    }
    pub fn reference_signal(&self, r: ReferenceId) -> SignalId {
        SignalId((2 * self.bodies.len() + self.inputs.len()) as u32 + r.0)
    }
    /// The measured acceleration signal of body `b`, if the body has an accelerometer.
    pub fn acceleration(&self, b: BodyId) -> Option<SignalId> {
        let first = 2 * self.bodies.len() + self.inputs.len() + self.references.len();
        (first..self.signals.len())
            .find(|&k| self.signals[k].kind == SignalKind::Acceleration(b))
            .map(|k| SignalId(k as u32))
    }
    /// Whether body `b` is measured by its acceleration alone (neither its position nor its
    /// velocity is a column of the data): its linear terms are formed from the acceleration
    /// by filters with zeros at the origin, and nonlinear terms in its motion are refused.
    pub fn acceleration_only(&self, b: BodyId) -> bool {
        self.acceleration(b)
            .is_some_and(|a| self.signal(a).measured)
            && !self.signal(self.position(b)).measured
            && !self.signal(self.velocity(b)).measured
    }
    /// The control law of input `i`, if it is computed in closed loop.
    pub fn control_of(&self, i: InputId) -> Option<&ControlIr> {
        self.controls.iter().find(|c| c.input == i)
    }
    pub fn signal(&self, s: SignalId) -> &SignalIr {
        &self.signals[s.index()]
    }
    pub fn expr(&self, e: ExprId) -> ExprNode {
        self.exprs[e.index()]
    }
    pub fn param_id(&self, name: &str) -> Option<ParamId> {
        self.params
            .iter()
            .position(|p| p.name == name)
            .map(|i| ParamId(i as u32))
    }
    pub fn signal_id(&self, name: &str) -> Option<SignalId> {
        self.signals
            .iter()
            .position(|s| s.name == name)
            .map(|i| SignalId(i as u32))
    }
    /// Unknown parameters in declaration order: the columns of the least-squares problem.
    pub fn unknowns(&self) -> Vec<ParamId> {
        (0..self.params.len() as u32)
            .map(ParamId)
            .filter(|p| self.params[p.index()].is_unknown())
            .collect()
    }
    /// A copy whose unknown parameters have `values` (in [`Self::unknowns`] order) as their
    /// nominal values: the model a simulation with those values runs.
    ///
    /// # Panics
    /// If `values` does not hold one value per unknown parameter.
    pub fn with_nominals(&self, values: &[f64]) -> ModelIr {
        let unknowns = self.unknowns();
        assert_eq!(
            values.len(),
            unknowns.len(),
            "model `{}` has {} unknown parameters",
            self.name,
            unknowns.len()
        );
        let mut ir = self.clone();
        for (p, &v) in unknowns.iter().zip(values) {
            ir.params[p.index()].kind = ParamKind::Unknown { nominal: Some(v) };
        }
        ir
    }
    /// A copy whose shape parameters take `values` (one per shape, in order) at every site,
    /// and as their nominal values.
    ///
    /// # Panics
    /// If `values` does not hold one value per shape parameter.
    pub fn with_shapes(&self, values: &[f64]) -> ModelIr {
        assert_eq!(
            values.len(),
            self.shapes.len(),
            "one value per shape parameter"
        );
        let mut ir = self.clone();
        for (shape, &v) in ir.shapes.iter_mut().zip(values) {
            shape.nominal = v;
            for site in &shape.sites {
                let node = &mut ir.exprs[site.index()];
                *node = match *node {
                    ExprNode::Deadzone(a, _) => ExprNode::Deadzone(a, v.to_bits()),
                    ExprNode::Saturate(a, _) => ExprNode::Saturate(a, v.to_bits()),
                    other => other,
                };
            }
        }
        ir
    }
    /// The shape parameter whose value node `e` holds, if any.
    pub fn shape_at(&self, e: ExprId) -> Option<&ShapeIr> {
        self.shapes.iter().find(|s| s.sites.contains(&e))
    }
    /// The elements grouped by the pair of nodes they connect (in either order): one
    /// group per pair, in order of first appearance, with the nodes of its first element.
    /// Springs, dampers and forces between the same two nodes act as one connection.
    pub fn element_groups(&self) -> Vec<ElementGroup> {
        let key = |n: Node| match n {
            Node::Ground => 0usize,
            Node::Body(b) => b.index() + 1,
        };
        let mut out: Vec<((usize, usize), ElementGroup)> = Vec::new();
        for (i, e) in self.elements.iter().enumerate() {
            let (a, b) = (key(e.nodes.0), key(e.nodes.1));
            let k = (a.min(b), a.max(b));
            let id = ElementId(i as u32);
            match out.iter_mut().find(|(x, _)| *x == k) {
                Some((_, g)) => g.members.push(id),
                None => out.push((
                    k,
                    ElementGroup {
                        nodes: e.nodes,
                        members: vec![id],
                    },
                )),
            }
        }
        out.into_iter().map(|(_, g)| g).collect()
    }
    pub fn measured_signals(&self) -> Vec<SignalId> {
        (0..self.signals.len() as u32)
            .map(SignalId)
            .filter(|s| self.signals[s.index()].measured)
            .collect()
    }
    /// The static basis expressions of all equations, deduplicated, in first-use order.
    /// This is the list of columns a compiled evaluator computes per sample; the macro's
    /// generated code and the interpreter both compute exactly this list, in this order.
    pub fn eval_roots(&self) -> Vec<ExprId> {
        let mut seen = std::collections::HashSet::new();
        let mut out = Vec::new();
        for eq in &self.equations {
            for t in &eq.terms {
                if let Basis::Expr(e) = t.basis {
                    if seen.insert(e) {
                        out.push(e);
                    }
                }
            }
        }
        out
    }
    /// Whether `e` is a constant: the basis of a constant force is the number 1 (lowering
    /// makes no other constant basis).
    pub fn is_constant(&self, e: ExprId) -> bool {
        matches!(self.expr(e), ExprNode::Const(_))
    }
    /// Which nodes the `roots` depend on (the roots included): `needed[i]` for node `i`,
    /// up to the largest root. Evaluators compute exactly these nodes.
    pub fn needed_nodes(&self, roots: &[ExprId]) -> Vec<bool> {
        let n = roots.iter().map(|r| r.index() + 1).max().unwrap_or(0);
        let mut needed = vec![false; n];
        for r in roots {
            needed[r.index()] = true;
        }
        // Topological order: a node's children have smaller ids.
        for i in (0..n).rev() {
            if needed[i] {
                for c in self.exprs[i].children() {
                    needed[c.index()] = true;
                }
            }
        }
        needed
    }

    /// `e` as a linear form `Σ aₖ sₖ` in signals (no constant offset), if it is one.
    pub fn linear_form(&self, e: ExprId) -> Option<Vec<(SignalId, f64)>> {
        let scale =
            |v: Vec<(SignalId, f64)>, f: f64| v.into_iter().map(|(s, a)| (s, a * f)).collect();
        match self.exprs[e.index()] {
            ExprNode::Signal(s) => Some(vec![(s, 1.0)]),
            ExprNode::Unary(UnaryOp::Neg, a) => Some(scale(self.linear_form(a)?, -1.0)),
            ExprNode::Binary(op, a, b) => {
                let (na, nb) = (self.exprs[a.index()], self.exprs[b.index()]);
                match op {
                    BinaryOp::Add | BinaryOp::Sub => {
                        let mut out = self.linear_form(a)?;
                        let sign = if op == BinaryOp::Add { 1.0 } else { -1.0 };
                        for (s, c) in self.linear_form(b)? {
                            match out.iter_mut().find(|(t, _)| *t == s) {
                                Some(e) => e.1 += sign * c,
                                None => out.push((s, sign * c)),
                            }
                        }
                        out.retain(|(_, c)| *c != 0.0);
                        Some(out)
                    }
                    BinaryOp::Mul => match (na, nb) {
                        (ExprNode::Const(c), _) => {
                            Some(scale(self.linear_form(b)?, f64::from_bits(c)))
                        }
                        (_, ExprNode::Const(c)) => {
                            Some(scale(self.linear_form(a)?, f64::from_bits(c)))
                        }
                        _ => None,
                    },
                    BinaryOp::Div => match nb {
                        ExprNode::Const(c) if f64::from_bits(c) != 0.0 => {
                            Some(scale(self.linear_form(a)?, 1.0 / f64::from_bits(c)))
                        }
                        _ => None,
                    },
                }
            }
            _ => None,
        }
    }

    /// The signals an expression depends on.
    pub fn expr_signals(&self, e: ExprId) -> Vec<SignalId> {
        let needed = self.needed_nodes(&[e]);
        let mut out: Vec<SignalId> = (0..needed.len())
            .filter(|&i| needed[i])
            .filter_map(|i| match self.exprs[i] {
                ExprNode::Signal(s) => Some(s),
                _ => None,
            })
            .collect();
        out.sort();
        out.dedup();
        out
    }
    /// Evaluate an expression at one point, given every signal's value (index = SignalId).
    /// For printing, tests and the statistical-linearisation templates; hot loops use a
    /// compiled evaluator instead.
    pub fn eval_scalar(&self, e: ExprId, signals: &[f64]) -> f64 {
        let mut vals = vec![0.0; e.index() + 1];
        for i in 0..=e.index() {
            vals[i] = eval_node(self.exprs[i], &vals, signals);
        }
        vals[e.index()]
    }

    /// Check the structural invariants listed in the module documentation.
    pub fn check_invariants(&self) -> Result<(), String> {
        for (i, n) in self.exprs.iter().enumerate() {
            for c in n.children() {
                if c.index() >= i {
                    return Err(format!("expr {i} refers forward to {}", c.index()));
                }
            }
        }
        let nb = self.bodies.len();
        let first_acc = 2 * nb + self.inputs.len() + self.references.len();
        if self.signals.len() < first_acc || self.signals.len() > first_acc + nb {
            return Err("signal table does not match bodies, inputs and references".into());
        }
        for (i, b) in self.bodies.iter().enumerate() {
            let id = BodyId(i as u32);
            if self.signals[2 * i].kind != SignalKind::Position(id)
                || self.signals[2 * i + 1].kind != SignalKind::Velocity(id)
            {
                return Err(format!("signals of body {} are out of place", b.name));
            }
        }
        if self.equations.len() != nb {
            return Err("one equation per body expected".into());
        }
        self.check_references()
    }

    /// Every index in the model names something that exists, every number is finite and
    /// every known mass is positive: what a model read from JSON must satisfy before any
    /// back end indexes with it (the compiler guarantees it for models it lowered).
    pub fn check_references(&self) -> Result<(), String> {
        let (np, ns, ne, nb) = (
            self.params.len(),
            self.signals.len(),
            self.exprs.len(),
            self.bodies.len(),
        );
        let coef = |c: &Coef, at: &str| -> Result<(), String> {
            if !c.scale.is_finite() {
                return Err(format!("{at}: coefficient {} is not finite", c.scale));
            }
            match c.param {
                Some(p) if p.index() >= np => {
                    Err(format!("{at}: parameter #{} does not exist", p.index()))
                }
                _ => Ok(()),
            }
        };
        let expr = |e: ExprId, at: &str| -> Result<(), String> {
            if e.index() >= ne {
                return Err(format!("{at}: expression #{} does not exist", e.index()));
            }
            Ok(())
        };
        let body = |b: BodyId, at: &str| -> Result<(), String> {
            if b.index() >= nb {
                return Err(format!("{at}: body #{} does not exist", b.index()));
            }
            Ok(())
        };
        let node = |n: Node, at: &str| match n {
            Node::Ground => Ok(()),
            Node::Body(b) => body(b, at),
        };
        for p in &self.params {
            let v = match p.kind {
                ParamKind::Known(v) => Some(v),
                ParamKind::Unknown { nominal } => nominal,
            };
            if v.is_some_and(|v| !v.is_finite()) {
                return Err(format!(
                    "parameter `{}` has a value that is not finite",
                    p.name
                ));
            }
        }
        for b in &self.bodies {
            let at = format!("body `{}`", b.name);
            coef(&b.mass, &at)?;
            let known = match b.mass.param {
                None => Some(b.mass.scale),
                Some(p) => match self.params[p.index()].kind {
                    ParamKind::Known(v) => Some(b.mass.scale * v),
                    ParamKind::Unknown { .. } => None,
                },
            };
            if known.is_some_and(|m| m <= 0.0) {
                return Err(format!("{at}: the known mass must be positive"));
            }
        }
        for (j, i) in self.inputs.iter().enumerate() {
            body(i.body, &format!("input #{j} `{}`", i.name))?;
        }
        for (k, n) in self.exprs.iter().enumerate() {
            let at = format!("expression #{k}");
            match *n {
                ExprNode::Signal(sig) if sig.index() >= ns => {
                    return Err(format!("{at}: signal #{} does not exist", sig.index()))
                }
                ExprNode::Const(b) | ExprNode::Deadzone(_, b) | ExprNode::Saturate(_, b)
                    if !f64::from_bits(b).is_finite() =>
                {
                    return Err(format!("{at}: a constant is not finite"))
                }
                _ => {}
            }
        }
        for e in &self.elements {
            let at = format!("element `{}`", e.name);
            node(e.nodes.0, &at)?;
            node(e.nodes.1, &at)?;
            expr(e.s, &at)?;
            expr(e.v, &at)?;
            for t in &e.terms {
                coef(&t.coef, &at)?;
                expr(t.basis, &at)?;
            }
        }
        for (k, eq) in self.equations.iter().enumerate() {
            let at = format!("equation #{k}");
            body(eq.body, &at)?;
            for t in &eq.terms {
                coef(&t.coef, &at)?;
                match t.basis {
                    Basis::Expr(e) => expr(e, &at)?,
                    Basis::Deriv { body: b, order } => {
                        body(b, &at)?;
                        if !(1..=2).contains(&order) {
                            return Err(format!("{at}: derivative of order {order}"));
                        }
                    }
                }
                let origin_ok = match t.origin {
                    TermOrigin::Inertia(b) => b.index() < nb,
                    TermOrigin::Element(el) => el.index() < self.elements.len(),
                    TermOrigin::Input(i) => i.index() < self.inputs.len(),
                };
                if !origin_ok {
                    return Err(format!("{at}: a term's origin does not exist"));
                }
            }
        }
        let nr = self.references.len();
        for c in &self.controls {
            if c.input.index() >= self.inputs.len() {
                return Err(format!(
                    "control law of input #{} that does not exist",
                    c.input.index()
                ));
            }
            expr(c.law, "a control law")?;
        }
        for sh in &self.shapes {
            if !sh.nominal.is_finite() {
                return Err(format!("shape parameter `{}` is not finite", sh.name));
            }
            for &site in &sh.sites {
                expr(site, "a shape parameter")?;
                if !matches!(
                    self.exprs[site.index()],
                    ExprNode::Deadzone(..) | ExprNode::Saturate(..)
                ) {
                    return Err(format!(
                        "shape parameter `{}` sits on a node that is no gap or limit",
                        sh.name
                    ));
                }
            }
        }
        let first_acc = 2 * nb + self.inputs.len() + nr;
        let mut last: Option<usize> = None;
        for (k, s) in self.signals.iter().enumerate() {
            let acc = match s.kind {
                SignalKind::Acceleration(b) => Some(b),
                _ => None,
            };
            if k < first_acc {
                if acc.is_some() {
                    return Err(format!("acceleration signal `{}` is out of place", s.name));
                }
                continue;
            }
            let Some(b) = acc else {
                return Err(format!(
                    "signal `{}` after the references is no acceleration",
                    s.name
                ));
            };
            body(b, &format!("acceleration signal `{}`", s.name))?;
            if last.is_some_and(|l| l >= b.index()) {
                return Err(format!(
                    "acceleration signals are not in body order at `{}`",
                    s.name
                ));
            }
            last = Some(b.index());
        }
        for x in &self.reference_excitation {
            if x.reference.index() >= nr {
                return Err(format!(
                    "excitation of reference #{} that does not exist",
                    x.reference.index()
                ));
            }
        }
        for (k, r) in self.references.iter().enumerate() {
            let s = self.reference_signal(ReferenceId(k as u32));
            if self.signals.get(s.index()).map(|s| s.kind)
                != Some(SignalKind::Reference(ReferenceId(k as u32)))
            {
                return Err(format!(
                    "the signal of reference `{}` is out of place",
                    r.name
                ));
            }
        }
        for x in &self.excitation {
            if x.input.index() >= self.inputs.len() {
                return Err(format!(
                    "excitation of input #{} that does not exist",
                    x.input.index()
                ));
            }
        }
        if let Some(f) = &self.filter {
            if let Some(s) = f.driven_by.iter().find(|s| s.index() >= ns) {
                return Err(format!(
                    "the filter is driven by signal #{} that does not exist",
                    s.index()
                ));
            }
        }
        Ok(())
    }
}

/// Evaluate one node given the values of earlier nodes and of all signals.
#[inline]
pub fn eval_node(node: ExprNode, vals: &[f64], signals: &[f64]) -> f64 {
    match node {
        ExprNode::Const(b) => f64::from_bits(b),
        ExprNode::Signal(s) => signals[s.index()],
        ExprNode::Unary(op, a) => op.apply(vals[a.index()]),
        ExprNode::Binary(op, a, b) => op.apply(vals[a.index()], vals[b.index()]),
        ExprNode::Powi(a, n) => vals[a.index()].powi(n),
        ExprNode::Deadzone(a, g) => deadzone(vals[a.index()], f64::from_bits(g)),
        ExprNode::Saturate(a, l) => saturate(vals[a.index()], f64::from_bits(l)),
    }
}

/// `sign(0) = 0`, as in the physics of Coulomb friction at rest.
#[inline]
pub fn sign(a: f64) -> f64 {
    if a > 0.0 {
        1.0
    } else if a < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[inline]
pub fn deadzone(a: f64, gap: f64) -> f64 {
    if a > gap {
        a - gap
    } else if a < -gap {
        a + gap
    } else {
        0.0
    }
}

#[inline]
pub fn saturate(a: f64, limit: f64) -> f64 {
    a.clamp(-limit, limit)
}

/// Hash-consing builder for the expression DAG. Lowering uses it so that common
/// subexpressions (e.g. `m2.x - m1.x` used by several terms) are shared.
#[derive(Default, Debug, Clone)]
pub struct ExprArena {
    pub nodes: Vec<ExprNode>,
    index: HashMap<ExprNode, ExprId>,
}

impl ExprArena {
    /// An arena holding `nodes` (a model's `exprs`), to extend it with hash-consing intact.
    pub fn from_nodes(nodes: Vec<ExprNode>) -> Self {
        let index = nodes
            .iter()
            .enumerate()
            .map(|(i, &n)| (n, ExprId(i as u32)))
            .collect();
        ExprArena { nodes, index }
    }
    pub fn intern(&mut self, node: ExprNode) -> ExprId {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        let id = ExprId(self.nodes.len() as u32);
        self.nodes.push(node);
        self.index.insert(node, id);
        id
    }
    pub fn constant(&mut self, v: f64) -> ExprId {
        self.intern(ExprNode::constant(v))
    }
    pub fn signal(&mut self, s: SignalId) -> ExprId {
        self.intern(ExprNode::Signal(s))
    }
    pub fn binary(&mut self, op: BinaryOp, a: ExprId, b: ExprId) -> ExprId {
        self.intern(ExprNode::Binary(op, a, b))
    }
    pub fn unary(&mut self, op: UnaryOp, a: ExprId) -> ExprId {
        self.intern(ExprNode::Unary(op, a))
    }
    pub fn into_nodes(self) -> Vec<ExprNode> {
        self.nodes
    }
}
