//! Evaluating the expression DAG (one node from earlier nodes and the signals, the static
//! nonlinearities it uses) and the hash-consing arena that builds it.

use super::{BinaryOp, ExprId, ExprNode, SignalId, UnaryOp};
use std::collections::HashMap;

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
