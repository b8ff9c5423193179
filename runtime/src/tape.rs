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
                        UnaryOp::Sin => f64::sin,
                        UnaryOp::Cos => f64::cos,
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

/// A [`Tape`] laid out for evaluation one point at a time (the simulator's right-hand side,
/// millions of times a second): every operand is an index into one array
/// `mem = [signals…, constants…, registers…]`, so an instruction is two loads, one
/// operation and one store, with no dispatch on where an operand lives.
///
/// Results are bit-identical to [`Tape::eval_point`].
#[derive(Clone, Debug)]
pub struct PointTape {
    ops: Vec<PointOp>,
    /// `mem` index of each root.
    roots: Vec<usize>,
    /// `mem[n_signals .. n_signals + consts.len()]`, written by [`PointTape::memory`].
    consts: Vec<f64>,
    n_signals: usize,
}

/// One instruction: 12 bytes, operands as indices into `mem` (for `Deadzone` and
/// `Saturate`, `b` is the slot of the gap or limit among the constants; for `Powi`, the
/// exponent's bits).
#[derive(Clone, Copy, Debug)]
struct PointOp {
    kind: PointKind,
    a: u32,
    b: u32,
}

/// The operation of a [`PointOp`], flat: one dispatch per instruction.
#[derive(Clone, Copy, Debug)]
#[repr(u8)]
enum PointKind {
    Neg,
    Abs,
    Sign,
    Tanh,
    Sqrt,
    Exp,
    Sin,
    Cos,
    Add,
    Sub,
    Mul,
    Div,
    Square,
    Cube,
    Powi,
    Deadzone,
    Saturate,
}

impl PointTape {
    pub fn new(tape: &Tape) -> PointTape {
        let n_signals = tape.n_signals;
        // Distinct constants (by bits), in order of first use, the dead zones' gaps and the
        // limits among them; the registers follow them.
        let mut consts: Vec<f64> = Vec::new();
        let mut keep = |c: f64| {
            if !consts.iter().any(|x| x.to_bits() == c.to_bits()) {
                consts.push(c);
            }
        };
        for op in &tape.ops {
            for o in op_operands(op) {
                if let Operand::Const(c) = o {
                    keep(c);
                }
            }
            if let Op::Deadzone(_, c) | Op::Saturate(_, c) = *op {
                keep(c);
            }
        }
        for o in &tape.roots {
            if let Operand::Const(c) = *o {
                keep(c);
            }
        }
        let base = n_signals + consts.len();
        let constant = |c: f64| {
            n_signals
                + consts
                    .iter()
                    .position(|x| x.to_bits() == c.to_bits())
                    .expect("invariant: every constant was collected above")
        };
        let slot = |o: Operand| match o {
            Operand::Reg(r) => base + r as usize,
            Operand::Sig(s) => s as usize,
            Operand::Const(c) => constant(c),
        };
        let index = |i: usize| {
            u32::try_from(i).expect("invariant: fewer than 2³² values (each a parsed node)")
        };
        let ops: Vec<PointOp> = tape
            .ops
            .iter()
            .map(|op| {
                let (kind, a, b) = match *op {
                    Op::Unary(u, a) => {
                        let kind = match u {
                            UnaryOp::Neg => PointKind::Neg,
                            UnaryOp::Abs => PointKind::Abs,
                            UnaryOp::Sign => PointKind::Sign,
                            UnaryOp::Tanh => PointKind::Tanh,
                            UnaryOp::Sqrt => PointKind::Sqrt,
                            UnaryOp::Exp => PointKind::Exp,
                            UnaryOp::Sin => PointKind::Sin,
                            UnaryOp::Cos => PointKind::Cos,
                        };
                        (kind, slot(a), 0)
                    }
                    Op::Binary(b, x, y) => {
                        let kind = match b {
                            BinaryOp::Add => PointKind::Add,
                            BinaryOp::Sub => PointKind::Sub,
                            BinaryOp::Mul => PointKind::Mul,
                            BinaryOp::Div => PointKind::Div,
                        };
                        (kind, slot(x), slot(y))
                    }
                    Op::Powi(a, 2) => (PointKind::Square, slot(a), 0),
                    Op::Powi(a, 3) => (PointKind::Cube, slot(a), 0),
                    Op::Powi(a, k) => (PointKind::Powi, slot(a), k as u32 as usize),
                    Op::Deadzone(a, g) => (PointKind::Deadzone, slot(a), constant(g)),
                    Op::Saturate(a, l) => (PointKind::Saturate, slot(a), constant(l)),
                };
                PointOp {
                    kind,
                    a: index(a),
                    b: index(b),
                }
            })
            .collect();
        let roots = tape.roots.iter().map(|&o| slot(o)).collect();
        // What `eval`'s unchecked reads rely on: operands are signals, constants or
        // earlier registers (the tape is in topological order); `Powi`'s `b` is no slot.
        for (i, op) in ops.iter().enumerate() {
            let reads_b = !matches!(op.kind, PointKind::Powi);
            assert!(
                (op.a as usize) < base + i && (!reads_b || (op.b as usize) < base + i),
                "invariant: operands precede their instruction"
            );
        }
        PointTape {
            ops,
            roots,
            consts,
            n_signals,
        }
    }

    /// A memory array for [`PointTape::eval`] with the constants in place; the caller
    /// writes the signals into `mem[..n_signals]`.
    pub fn memory(&self) -> Vec<f64> {
        let mut mem = vec![0.0; self.memory_len()];
        mem[self.n_signals..self.n_signals + self.consts.len()].copy_from_slice(&self.consts);
        mem
    }

    /// Length of [`PointTape::memory`].
    pub fn memory_len(&self) -> usize {
        self.n_signals + self.consts.len() + self.ops.len()
    }

    /// Where root `r` lives in the memory after [`PointTape::eval`].
    pub fn root_slot(&self, r: usize) -> usize {
        self.roots[r]
    }

    pub fn n_signals(&self) -> usize {
        self.n_signals
    }

    /// Evaluate every instruction on `mem` (from [`PointTape::memory`], signals written).
    #[inline(always)]
    pub fn eval(&self, mem: &mut [f64]) {
        let base = self.n_signals + self.consts.len();
        assert!(
            mem.len() >= base + self.ops.len(),
            "memory smaller than PointTape::memory"
        );
        for (i, op) in self.ops.iter().enumerate() {
            // SAFETY: `new` makes every operand index smaller than `base + i` (signals,
            // constants, or an earlier register; `b` of every kind but `Powi`), and `mem`
            // holds `base + ops.len()` values (asserted above).
            let a = unsafe { *mem.get_unchecked(op.a as usize) };
            let b = || unsafe { *mem.get_unchecked(op.b as usize) };
            let v = match op.kind {
                PointKind::Neg => UnaryOp::Neg.apply(a),
                PointKind::Abs => UnaryOp::Abs.apply(a),
                PointKind::Sign => UnaryOp::Sign.apply(a),
                PointKind::Tanh => UnaryOp::Tanh.apply(a),
                PointKind::Sqrt => UnaryOp::Sqrt.apply(a),
                PointKind::Exp => UnaryOp::Exp.apply(a),
                PointKind::Sin => UnaryOp::Sin.apply(a),
                PointKind::Cos => UnaryOp::Cos.apply(a),
                PointKind::Add => BinaryOp::Add.apply(a, b()),
                PointKind::Sub => BinaryOp::Sub.apply(a, b()),
                PointKind::Mul => BinaryOp::Mul.apply(a, b()),
                PointKind::Div => BinaryOp::Div.apply(a, b()),
                // `powi` by repeated squaring gives these same products.
                PointKind::Square => a * a,
                PointKind::Cube => a * a * a,
                PointKind::Powi => a.powi(op.b as i32),
                PointKind::Deadzone => deadzone(a, b()),
                PointKind::Saturate => saturate(a, b()),
            };
            // SAFETY: `base + i < base + ops.len() <= mem.len()`.
            unsafe { *mem.get_unchecked_mut(base + i) = v };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind of instruction, constants shared and not, roots that are signals.
    fn model() -> ModelIr {
        let src = "model every_op {
            body m = 1.0
            body n ~ 2.0
            input u on m
            spring k (ground, m) ~ 4.0
            damper d (m, n) ~ 0.4
            force a (ground, m) = c1 ~ 1.0 * s^3 + c2 ~ 1.0 * s^2 * v + c3 ~ 1.0 * s^5
            force b (m, n) = c4 ~ 1.0 * sign(v) + c5 ~ 1.0 * tanh(v / 0.3) + c6 ~ 1.0 * abs(v) * v
            force c (ground, n) = c7 ~ 1.0 * deadzone(s, 0.05) + c8 ~ 1.0 * saturate(s, 0.2)
            force e (ground, n) = c9 ~ 1.0 * sqrt(abs(s)) * exp(-v * v) - 3 * s / 7
            excite u: lowpass(corner = 10) levels [1]
        }";
        dsl_parser::compile_str("every_op", src).expect("a valid model")
    }

    #[test]
    fn the_point_tape_gives_the_tapes_values_bit_for_bit() {
        let ir = model();
        let roots = ir.eval_roots();
        let tape = Tape::compile(&ir, &roots);
        let point = PointTape::new(&tape);
        let mut mem = point.memory();
        let mut regs = vec![0.0; tape.ops.len()];
        let mut expected = vec![0.0; tape.n_roots()];
        for k in 0..200 {
            // Values around every kink: zero, the dead zone's and the limit's edges.
            let signals: Vec<f64> = (0..tape.n_signals)
                .map(|s| ((k * 7 + s * 13) % 41) as f64 * 0.0125 - 0.25)
                .collect();
            tape.eval_point(&signals, &mut regs, &mut expected);
            mem[..point.n_signals()].copy_from_slice(&signals);
            point.eval(&mut mem);
            for (r, e) in expected.iter().enumerate() {
                assert_eq!(
                    mem[point.root_slot(r)].to_bits(),
                    e.to_bits(),
                    "root {r} at point {k}"
                );
            }
        }
    }
}
