//! Human-readable views of a [`ModelIr`]: equations, parameter and column tables, and the
//! model printed back as `.dyn` source.
//!
//! One file per view: this one prints expressions and equations (the `Printer` the others
//! share); `tables` gives the parameter and column tables, `report` the report of
//! `dynid compile` (text and JSON), `source` the model as `.dyn` source. Their items are
//! re-exported here, so `print::to_source` and the like are the public paths.
//!
//! [`to_source`] is an inverse of compilation: `compile_str(to_source(ir))` gives `ir` again
//! (up to spans). Expressions are printed with exactly the parentheses that make the parser
//! rebuild the same tree.

mod report;
mod source;
mod tables;

pub use report::{render_report, report_json};
pub use source::to_source;
pub use tables::{
    aligned, column_rows, param_rows, render_columns, render_params, ColumnRow, ParamRow,
};

use crate::ir::*;

use crate::num::exact as fmt_num;

const P_ADD: u8 = 1;
const P_MUL: u8 = 2;
const P_NEG: u8 = 3;
const P_ATOM: u8 = 5;

struct Printer<'a> {
    ir: &'a ModelIr,
    /// Nodes printed by a name instead (an element's `s` and `v`).
    names: &'a [(ExprId, &'a str)],
    /// Printing source: which shape parameters were declared already (the first use is
    /// written `g ~ value`, later ones `g`). `None`: shapes print by name.
    declared: Option<&'a std::cell::RefCell<Vec<bool>>>,
}

impl Printer<'_> {
    fn prec(&self, e: ExprId) -> u8 {
        if self.names.iter().any(|(id, _)| *id == e) {
            return P_ATOM;
        }
        match self.ir.expr(e) {
            ExprNode::Const(b) if f64::from_bits(b) < 0.0 => P_NEG,
            ExprNode::Const(_) | ExprNode::Signal(_) => P_ATOM,
            ExprNode::Unary(UnaryOp::Neg, _) => P_NEG,
            ExprNode::Unary(..) | ExprNode::Deadzone(..) | ExprNode::Saturate(..) => P_ATOM,
            ExprNode::Binary(BinaryOp::Add | BinaryOp::Sub, ..) => P_ADD,
            ExprNode::Binary(..) => P_MUL,
            ExprNode::Powi(..) => 4,
        }
    }

    /// The gap or limit of node `e`: its number, or its shape parameter's name.
    fn shape_or(&self, e: ExprId, bits: u64) -> String {
        let Some(k) = self.ir.shapes.iter().position(|s| s.sites.contains(&e)) else {
            return fmt_num(f64::from_bits(bits));
        };
        let name = &self.ir.shapes[k].name;
        match self.declared {
            Some(d) if !std::mem::replace(&mut d.borrow_mut()[k], true) => {
                format!("{name} ~ {}", fmt_num(self.ir.shapes[k].nominal))
            }
            _ => name.clone(),
        }
    }

    /// Print `e`, parenthesised if its precedence is below `min`.
    fn at(&self, e: ExprId, min: u8) -> String {
        let s = self.expr(e);
        if self.prec(e) < min {
            format!("({s})")
        } else {
            s
        }
    }

    fn expr(&self, e: ExprId) -> String {
        if let Some((_, n)) = self.names.iter().find(|(id, _)| *id == e) {
            return n.to_string();
        }
        match self.ir.expr(e) {
            ExprNode::Const(b) => fmt_num(f64::from_bits(b)),
            ExprNode::Signal(s) => self.ir.signal(s).name.clone(),
            ExprNode::Unary(UnaryOp::Neg, a) => format!("-{}", self.at(a, P_NEG)),
            ExprNode::Unary(op, a) => {
                let f = match op {
                    UnaryOp::Abs => "abs",
                    UnaryOp::Sign => "sign",
                    UnaryOp::Tanh => "tanh",
                    UnaryOp::Sqrt => "sqrt",
                    UnaryOp::Exp => "exp",
                    UnaryOp::Sin => "sin",
                    UnaryOp::Cos => "cos",
                    UnaryOp::Neg => "-",
                };
                format!("{f}({})", self.expr(a))
            }
            ExprNode::Binary(op, a, b) => {
                let (sym, p) = match op {
                    BinaryOp::Add => ("+", P_ADD),
                    BinaryOp::Sub => ("-", P_ADD),
                    BinaryOp::Mul => ("*", P_MUL),
                    BinaryOp::Div => ("/", P_MUL),
                };
                // Operators are left-associative: the right operand needs parentheses at
                // equal precedence so the tree is rebuilt as it was.
                format!("{} {sym} {}", self.at(a, p), self.at(b, p + 1))
            }
            ExprNode::Powi(a, n) => format!("{}^{n}", self.at(a, P_ATOM)),
            ExprNode::Deadzone(a, g) => {
                format!("deadzone({}, {})", self.expr(a), self.shape_or(e, g))
            }
            ExprNode::Saturate(a, l) => {
                format!("saturate({}, {})", self.expr(a), self.shape_or(e, l))
            }
        }
    }
}

/// An expression in the model's notation, e.g. `(m2.x - m1.x)^3`.
pub fn render_expr(ir: &ModelIr, e: ExprId) -> String {
    Printer {
        ir,
        names: &[],
        declared: None,
    }
    .expr(e)
}

/// A basis as it stands after a coefficient (`k1 (m2.x - m1.x)`, `k3 m1.x^3`).
pub fn render_basis(ir: &ModelIr, b: Basis) -> String {
    match b {
        Basis::Deriv { body, order } => {
            format!(
                "{}.x{}",
                ir.bodies[body.index()].name,
                "'".repeat(order as usize)
            )
        }
        Basis::Expr(e) => Printer {
            ir,
            names: &[],
            declared: None,
        }
        .at(e, P_MUL),
    }
}

fn coef_text(ir: &ModelIr, c: &Coef) -> String {
    let a = c.scale.abs();
    match c.param {
        None => fmt_num(a),
        Some(p) if a == 1.0 => ir.params[p.index()].name.clone(),
        Some(p) => format!("{} {}", fmt_num(a), ir.params[p.index()].name),
    }
}

/// Join signed pieces as `a - b + c`.
fn join_signed(pieces: &[(bool, String)]) -> String {
    let mut out = String::new();
    for (i, (neg, s)) in pieces.iter().enumerate() {
        match (i, neg) {
            (0, true) => out.push('-'),
            (0, false) => {}
            (_, true) => out.push_str(" - "),
            (_, false) => out.push_str(" + "),
        }
        out.push_str(s);
    }
    if out.is_empty() {
        out.push('0');
    }
    out
}

/// One equation, e.g. `m1: 1 m1.x'' + d1 m1.x' + k1 m1.x = u`. Input forces are shown on
/// the right-hand side.
pub fn render_equation(ir: &ModelIr, eq: &EquationIr) -> String {
    let mut lhs = Vec::new();
    let mut rhs = Vec::new();
    for t in &eq.terms {
        let text = match t.basis {
            // A constant force reads as its coefficient alone: `+ f0`, not `+ f0 1`.
            Basis::Expr(e) if ir.is_constant(e) => coef_text(ir, &t.coef),
            b => format!("{} {}", coef_text(ir, &t.coef), render_basis(ir, b)),
        };
        match t.origin {
            TermOrigin::Input(_) if t.coef.param.is_none() => {
                let basis = match t.basis {
                    Basis::Expr(e) => Printer {
                        ir,
                        names: &[],
                        declared: None,
                    }
                    .at(e, P_MUL),
                    b => render_basis(ir, b),
                };
                let piece = if t.coef.scale.abs() == 1.0 {
                    basis
                } else {
                    format!("{} {basis}", fmt_num(t.coef.scale.abs()))
                };
                rhs.push((t.coef.scale > 0.0, piece));
            }
            _ => lhs.push((t.coef.scale < 0.0, text)),
        }
    }
    format!(
        "{}: {} = {}",
        ir.bodies[eq.body.index()].name,
        join_signed(&lhs),
        join_signed(&rhs)
    )
}

/// All equations of motion, one line per body.
pub fn render_equations(ir: &ModelIr) -> String {
    let mut out = String::new();
    for eq in &ir.equations {
        out.push_str(&render_equation(ir, eq));
        out.push('\n');
    }
    out
}

/// `(input, law)` of every control law, the law as source text.
fn control_rows(ir: &ModelIr) -> Vec<(String, String)> {
    let pr = Printer {
        ir,
        names: &[],
        declared: None,
    };
    ir.controls
        .iter()
        .map(|c| (ir.inputs[c.input.index()].name.clone(), pr.expr(c.law)))
        .collect()
}
