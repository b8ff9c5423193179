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

mod eval;
mod model;

pub use eval::{deadzone, eval_node, saturate, sign, ExprArena};
