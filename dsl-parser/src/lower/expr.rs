//! The expression algebra of lowering: `LExpr` trees with constant folding as they are
//! built, the split of a term into a constant scale and a basis, and interning into the
//! IR's expression arena.

use crate::ir::*;

/// An expression tree during lowering. Constants are folded while the tree is built, and
/// only the final tree is interned, so the arena holds no dead intermediate nodes.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum LExpr {
    Const(f64),
    Sig(SignalId),
    Unary(UnaryOp, Box<LExpr>),
    Binary(BinaryOp, Box<LExpr>, Box<LExpr>),
    Powi(Box<LExpr>, i32),
    /// `deadzone(a, gap)`; the index of the shape parameter the gap stands for, if any.
    Deadzone(Box<LExpr>, f64, Option<usize>),
    Saturate(Box<LExpr>, f64, Option<usize>),
}

impl LExpr {
    pub(super) fn as_const(&self) -> Option<f64> {
        match self {
            LExpr::Const(c) => Some(*c),
            _ => None,
        }
    }
    fn is_const(&self, v: f64) -> bool {
        self.as_const() == Some(v)
    }
    pub(super) fn neg(a: LExpr) -> LExpr {
        match a {
            LExpr::Const(c) => LExpr::Const(-c),
            LExpr::Unary(UnaryOp::Neg, x) => *x,
            a => LExpr::Unary(UnaryOp::Neg, Box::new(a)),
        }
    }
    pub(super) fn unary(op: UnaryOp, a: LExpr) -> LExpr {
        if op == UnaryOp::Neg {
            return LExpr::neg(a);
        }
        match a.as_const() {
            Some(c) => LExpr::Const(eval_node(ExprNode::Unary(op, ExprId(0)), &[c], &[])),
            None => LExpr::Unary(op, Box::new(a)),
        }
    }
    pub(super) fn binary(op: BinaryOp, a: LExpr, b: LExpr) -> LExpr {
        use BinaryOp::*;
        if let (Some(x), Some(y)) = (a.as_const(), b.as_const()) {
            return LExpr::Const(match op {
                Add => x + y,
                Sub => x - y,
                Mul => x * y,
                Div => x / y,
            });
        }
        match op {
            Add if a.is_const(0.0) => b,
            Add | Sub if b.is_const(0.0) => a,
            Sub if a.is_const(0.0) => LExpr::neg(b),
            Mul if a.is_const(0.0) || b.is_const(0.0) => LExpr::Const(0.0),
            Mul if a.is_const(1.0) => b,
            Mul | Div if b.is_const(1.0) => a,
            _ => LExpr::Binary(op, Box::new(a), Box::new(b)),
        }
    }
    pub(super) fn powi(a: LExpr, n: i32) -> LExpr {
        match (a.as_const(), n) {
            (_, 1) => a,
            (_, 0) => LExpr::Const(1.0),
            (Some(c), n) => LExpr::Const(c.powi(n)),
            (None, n) => LExpr::Powi(Box::new(a), n),
        }
    }
    pub(super) fn has_signal(&self) -> bool {
        match self {
            LExpr::Const(_) => false,
            LExpr::Sig(_) => true,
            LExpr::Unary(_, a)
            | LExpr::Powi(a, _)
            | LExpr::Deadzone(a, ..)
            | LExpr::Saturate(a, ..) => a.has_signal(),
            LExpr::Binary(_, a, b) => a.has_signal() || b.has_signal(),
        }
    }
    /// Split off a constant factor: `-2 * x` → (−2, x). Used to put every term in the form
    /// `scale · param · basis` with a basis that carries no sign or constant factor.
    pub(super) fn extract_scale(self) -> (f64, LExpr) {
        let mut scale = 1.0;
        let mut e = self;
        loop {
            e = match e {
                LExpr::Unary(UnaryOp::Neg, x) => {
                    scale = -scale;
                    *x
                }
                LExpr::Binary(BinaryOp::Mul, a, b) if a.as_const().is_some() => {
                    scale *= a.as_const().unwrap_or(1.0);
                    *b
                }
                LExpr::Binary(BinaryOp::Mul, a, b) if b.as_const().is_some() => {
                    scale *= b.as_const().unwrap_or(1.0);
                    *a
                }
                LExpr::Binary(BinaryOp::Div, a, b) if b.as_const().is_some() => {
                    scale /= b.as_const().unwrap_or(1.0);
                    *a
                }
                e => return (scale, e),
            }
        }
    }
    pub(super) fn intern(&self, arena: &mut ExprArena) -> ExprId {
        match self {
            LExpr::Const(c) => arena.constant(*c),
            LExpr::Sig(s) => arena.signal(*s),
            LExpr::Unary(op, a) => {
                let a = a.intern(arena);
                arena.unary(*op, a)
            }
            LExpr::Binary(op, a, b) => {
                let a = a.intern(arena);
                let b = b.intern(arena);
                arena.binary(*op, a, b)
            }
            LExpr::Powi(a, n) => {
                let a = a.intern(arena);
                arena.intern(ExprNode::Powi(a, *n))
            }
            LExpr::Deadzone(a, g, _) => {
                let a = a.intern(arena);
                arena.intern(ExprNode::Deadzone(a, g.to_bits()))
            }
            LExpr::Saturate(a, l, _) => {
                let a = a.intern(arena);
                arena.intern(ExprNode::Saturate(a, l.to_bits()))
            }
        }
    }
    /// `(shape index, node)` of every gap or limit that stands for a shape parameter, once
    /// the tree is interned (interning again only looks the nodes up).
    pub(super) fn shape_sites(&self, arena: &mut ExprArena, out: &mut Vec<(usize, ExprId)>) {
        match self {
            LExpr::Const(_) | LExpr::Sig(_) => {}
            LExpr::Unary(_, a) | LExpr::Powi(a, _) => a.shape_sites(arena, out),
            LExpr::Binary(_, a, b) => {
                a.shape_sites(arena, out);
                b.shape_sites(arena, out);
            }
            LExpr::Deadzone(a, _, k) | LExpr::Saturate(a, _, k) => {
                a.shape_sites(arena, out);
                if let Some(k) = k {
                    out.push((*k, self.intern(arena)));
                }
            }
        }
    }
}
