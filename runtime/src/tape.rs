//! A flat instruction tape compiled from the expression DAG of a [`ModelIr`].
//!
//! The tape evaluates a fixed list of root expressions over blocks of samples, one
//! instruction at a time across the whole block (so the inner loops are simple and
//! vectorise), without walking trees per sample and without allocating per sample.

use dynid_ir::ir::{
    deadzone, saturate, sign, BinaryOp, ExprId, ExprNode, ModelIr, SignalId, UnaryOp,
};

/// Where an instruction reads a value from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Operand {
    /// A scratch register (the result of an earlier instruction).
    Reg(u32),
    /// A signal column of the input block.
    Sig(u32),
    /// A constant.
    Const(f64),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Op {
    Unary(UnaryOp, Operand),
    Binary(BinaryOp, Operand, Operand),
    Powi(Operand, i32),
    Deadzone(Operand, f64),
    Saturate(Operand, f64),
}

/// A compiled evaluator for a list of root expressions.
#[derive(Clone, Debug)]
pub struct Tape {
    /// Instruction `i` writes register `i`.
    pub ops: Vec<Op>,
    /// Where each root's value lives after evaluation.
    pub roots: Vec<Operand>,
    /// Number of signals the input block must provide (indexed by `SignalId`).
    pub n_signals: usize,
}

/// Per-thread scratch space for [`Tape::eval_block`], reused across blocks.
#[derive(Default, Debug)]
pub struct TapeScratch {
    regs: Vec<f64>,
    len: usize,
}

impl Tape {
    /// Compile the expressions `roots` of `ir`. Shared subexpressions are computed once.
    pub fn compile(ir: &ModelIr, roots: &[ExprId]) -> Tape {
        let needed = ir.needed_nodes(roots);
        let n = needed.len();
        let mut place: Vec<Option<Operand>> = vec![None; n];
        let mut ops = Vec::new();
        for i in 0..n {
            if !needed[i] {
                continue;
            }
            let arg = |e: ExprId| place[e.index()].expect("invariant: topological order");
            let op = match ir.exprs[i] {
                ExprNode::Const(b) => {
                    place[i] = Some(Operand::Const(f64::from_bits(b)));
                    continue;
                }
                ExprNode::Signal(s) => {
                    place[i] = Some(Operand::Sig(s.0));
                    continue;
                }
                ExprNode::Unary(op, a) => Op::Unary(op, arg(a)),
                ExprNode::Binary(op, a, b) => Op::Binary(op, arg(a), arg(b)),
                ExprNode::Powi(a, k) => Op::Powi(arg(a), k),
                ExprNode::Deadzone(a, g) => Op::Deadzone(arg(a), f64::from_bits(g)),
                ExprNode::Saturate(a, l) => Op::Saturate(arg(a), f64::from_bits(l)),
            };
            place[i] = Some(Operand::Reg(ops.len() as u32));
            ops.push(op);
        }
        Tape {
            ops,
            roots: roots
                .iter()
                .map(|r| place[r.index()].expect("invariant: every root is placed above"))
                .collect(),
            n_signals: ir.signals.len(),
        }
    }

    pub fn n_roots(&self) -> usize {
        self.roots.len()
    }

    /// Signals read by the tape.
    pub fn signals_read(&self) -> Vec<SignalId> {
        let mut out: Vec<SignalId> = self
            .ops
            .iter()
            .flat_map(op_operands)
            .chain(self.roots.iter().copied())
            .filter_map(|o| match o {
                Operand::Sig(s) => Some(SignalId(s)),
                _ => None,
            })
            .collect();
        out.sort();
        out.dedup();
        out
    }

    /// Evaluate all roots over a block of `len` samples.
    ///
    /// `signals[s]` is the column of signal `s` (at least `len` long; signals the tape does
    /// not read may be empty). `out` receives the roots root-major: root `r` at
    /// `out[r * len .. (r + 1) * len]`.
    pub fn eval_block(
        &self,
        signals: &[&[f64]],
        len: usize,
        out: &mut [f64],
        scratch: &mut TapeScratch,
    ) {
        assert!(
            out.len() >= self.roots.len() * len,
            "output block too small"
        );
        if scratch.len != len || scratch.regs.len() < self.ops.len() * len {
            scratch.regs.resize(self.ops.len() * len, 0.0);
            scratch.len = len;
        }
        let regs = &mut scratch.regs;
        for (i, op) in self.ops.iter().enumerate() {
            let (done, rest) = regs.split_at_mut(i * len);
            let dst = &mut rest[..len];
            let read = |o: Operand| -> Src {
                match o {
                    Operand::Reg(r) => Src::Col(&done[r as usize * len..(r as usize + 1) * len]),
                    Operand::Sig(s) => Src::Col(&signals[s as usize][..len]),
                    Operand::Const(c) => Src::Const(c),
                }
            };
            match *op {
                Op::Unary(u, a) => {
                    let f: fn(f64) -> f64 = match u {
                        UnaryOp::Neg => |a| -a,
                        UnaryOp::Abs => f64::abs,
                        UnaryOp::Sign => sign,
                        UnaryOp::Tanh => f64::tanh,
                        UnaryOp::Sqrt => f64::sqrt,
                        UnaryOp::Exp => f64::exp,
                    };
                    map1(dst, read(a), f)
                }
                Op::Binary(b, x, y) => match b {
                    BinaryOp::Add => map2(dst, read(x), read(y), |a, b| a + b),
                    BinaryOp::Sub => map2(dst, read(x), read(y), |a, b| a - b),
                    BinaryOp::Mul => map2(dst, read(x), read(y), |a, b| a * b),
                    BinaryOp::Div => map2(dst, read(x), read(y), |a, b| a / b),
                },
                Op::Powi(a, k) => match k {
                    2 => map1(dst, read(a), |a| a * a),
                    3 => map1(dst, read(a), |a| a * a * a),
                    _ => map1(dst, read(a), |a| a.powi(k)),
                },
                Op::Deadzone(a, g) => map1(dst, read(a), |a| deadzone(a, g)),
                Op::Saturate(a, l) => map1(dst, read(a), |a| saturate(a, l)),
            }
        }
        for (r, root) in self.roots.iter().enumerate() {
            let dst = &mut out[r * len..(r + 1) * len];
            match *root {
                Operand::Reg(i) => {
                    dst.copy_from_slice(&regs[i as usize * len..(i as usize + 1) * len])
                }
                Operand::Sig(s) => dst.copy_from_slice(&signals[s as usize][..len]),
                Operand::Const(c) => dst.fill(c),
            }
        }
    }

    /// Evaluate all roots at one point (`signals[s]` = value of signal `s`).
    /// `regs` must hold at least `self.ops.len()` values; no allocation happens here.
    pub fn eval_point(&self, signals: &[f64], regs: &mut [f64], out: &mut [f64]) {
        let get = |regs: &[f64], o: Operand| match o {
            Operand::Reg(r) => regs[r as usize],
            Operand::Sig(s) => signals[s as usize],
            Operand::Const(c) => c,
        };
        for (i, op) in self.ops.iter().enumerate() {
            regs[i] = match *op {
                Op::Unary(u, a) => u.apply(get(regs, a)),
                Op::Binary(b, x, y) => b.apply(get(regs, x), get(regs, y)),
                Op::Powi(a, k) => get(regs, a).powi(k),
                Op::Deadzone(a, g) => deadzone(get(regs, a), g),
                Op::Saturate(a, l) => saturate(get(regs, a), l),
            };
        }
        for (o, root) in out.iter_mut().zip(&self.roots) {
            *o = get(regs, *root);
        }
    }
}

fn op_operands(op: &Op) -> Vec<Operand> {
    match *op {
        Op::Unary(_, a) | Op::Powi(a, _) | Op::Deadzone(a, _) | Op::Saturate(a, _) => vec![a],
        Op::Binary(_, a, b) => vec![a, b],
    }
}

enum Src<'a> {
    Col(&'a [f64]),
    Const(f64),
}

#[inline]
fn map1(dst: &mut [f64], a: Src, f: impl Fn(f64) -> f64) {
    match a {
        Src::Col(a) => dst.iter_mut().zip(a).for_each(|(d, &a)| *d = f(a)),
        Src::Const(c) => dst.fill(f(c)),
    }
}

#[inline]
fn map2(dst: &mut [f64], a: Src, b: Src, f: impl Fn(f64, f64) -> f64) {
    match (a, b) {
        (Src::Col(a), Src::Col(b)) => dst
            .iter_mut()
            .zip(a.iter().zip(b))
            .for_each(|(d, (&a, &b))| *d = f(a, b)),
        (Src::Col(a), Src::Const(c)) => dst.iter_mut().zip(a).for_each(|(d, &a)| *d = f(a, c)),
        (Src::Const(c), Src::Col(b)) => dst.iter_mut().zip(b).for_each(|(d, &b)| *d = f(c, b)),
        (Src::Const(a), Src::Const(b)) => dst.fill(f(a, b)),
    }
}

impl crate::basis::BasisEval for Tape {
    fn n_roots(&self) -> usize {
        self.roots.len()
    }
    fn eval_block(&self, signals: &[&[f64]], len: usize, out: &mut [f64], scratch: &mut Vec<f64>) {
        // Lend the caller's buffer to the tape's scratch type so no allocation happens once
        // the buffer has grown to size.
        let mut s = TapeScratch {
            regs: std::mem::take(scratch),
            len: 0,
        };
        Tape::eval_block(self, signals, len, out, &mut s);
        *scratch = s.regs;
    }
}
