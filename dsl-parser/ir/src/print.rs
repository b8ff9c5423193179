//! Human-readable views of a [`ModelIr`]: equations, parameter and column tables, and the
//! model printed back as `.dyn` source.
//!
//! [`to_source`] is an inverse of compilation: `compile_str(to_source(ir))` gives `ir` again
//! (up to spans). Expressions are printed with exactly the parentheses that make the parser
//! rebuild the same tree.

use crate::ir::*;
use serde::Serialize;
use std::fmt::Write;

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

/// A row of the parameter table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParamRow {
    pub name: String,
    /// `"unknown"` or `"known"`.
    pub kind: &'static str,
    /// The known value or the nominal one (absent for an unknown without nominal).
    pub value: Option<f64>,
    /// Elements (or `body (mass)`) whose terms use the parameter.
    pub used_by: Vec<String>,
}

/// A column of the least-squares problem restricted to one equation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ColumnRow {
    /// The unknown parameter (the column's name).
    pub column: String,
    /// The body whose equation this is.
    pub equation: String,
    /// The sum of the scaled bases the parameter multiplies in this equation.
    pub basis: String,
    /// `static`, `static (m1.v measured)` or `derivative (moved onto the filter)`.
    pub kind: String,
}

/// Per parameter, the terms it multiplies as (equation, term) indices in model order: one
/// pass over the equations, so the tables cost time linear in the model's size.
fn terms_by_param(ir: &ModelIr) -> Vec<Vec<(usize, usize)>> {
    let mut by = vec![Vec::new(); ir.params.len()];
    for (q, eq) in ir.equations.iter().enumerate() {
        for (k, t) in eq.terms.iter().enumerate() {
            if let Some(p) = t.coef.param.and_then(|p| by.get_mut(p.index())) {
                p.push((q, k));
            }
        }
    }
    by
}

pub fn param_rows(ir: &ModelIr) -> Vec<ParamRow> {
    let by = terms_by_param(ir);
    ir.params
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut used_by: Vec<String> = Vec::new();
            {
                for t in by[i].iter().map(|&(q, k)| &ir.equations[q].terms[k]) {
                    let who = match t.origin {
                        TermOrigin::Inertia(b) => format!("{} (mass)", ir.bodies[b.index()].name),
                        TermOrigin::Element(e) => ir.elements[e.index()].name.clone(),
                        TermOrigin::Input(j) => ir.inputs[j.index()].name.clone(),
                    };
                    if !used_by.contains(&who) {
                        used_by.push(who);
                    }
                }
            }
            ParamRow {
                name: p.name.clone(),
                kind: if p.is_unknown() { "unknown" } else { "known" },
                value: p.nominal(),
                used_by,
            }
        })
        .collect()
}

pub fn column_rows(ir: &ModelIr) -> Vec<ColumnRow> {
    let by = terms_by_param(ir);
    let mut rows = Vec::new();
    for p in ir.unknowns() {
        let uses = &by[p.index()];
        // The equations this parameter appears in, in model order.
        let mut eqs: Vec<usize> = uses.iter().map(|&(q, _)| q).collect();
        eqs.dedup();
        for q in eqs {
            let eq = &ir.equations[q];
            let terms: Vec<&TermIr> = uses
                .iter()
                .filter(|&&(qq, _)| qq == q)
                .map(|&(_, k)| &eq.terms[k])
                .collect();
            let mut pieces = Vec::new();
            let (mut is_static, mut velocities, mut derivative) = (false, Vec::new(), false);
            let mut constant = false;
            // Terms of bodies measured only by accelerations: formed from `b.a` by the
            // band-pass instruments (`ẍ` is the acceleration itself).
            let mut integrated: Vec<String> = Vec::new();
            for t in &terms {
                let b = match (terms.len(), t.basis, t.coef.scale) {
                    // A lone positive term needs no parentheses.
                    (1, Basis::Expr(e), s) if s > 0.0 => render_expr(ir, e),
                    _ => render_basis(ir, t.basis),
                };
                let a = t.coef.scale.abs();
                let text = if a == 1.0 {
                    b
                } else if matches!(t.basis, Basis::Expr(e) if ir.is_constant(e)) {
                    fmt_num(a)
                } else {
                    format!("{} {b}", fmt_num(a))
                };
                pieces.push((t.coef.scale < 0.0, text));
                let accel_only = |body: BodyId| {
                    ir.acceleration_only(body)
                        .then(|| ir.acceleration(body))
                        .flatten()
                        .map(|a| ir.signal(a).name.clone())
                };
                let from_acc: Vec<String> = match t.basis {
                    Basis::Expr(e) => ir
                        .expr_signals(e)
                        .into_iter()
                        .filter_map(|s| match ir.signal(s).kind {
                            SignalKind::Position(b) | SignalKind::Velocity(b) => accel_only(b),
                            _ => None,
                        })
                        .collect(),
                    Basis::Deriv { body, .. } => accel_only(body).into_iter().collect(),
                };
                if !from_acc.is_empty() {
                    integrated.extend(from_acc);
                    continue;
                }
                match t.basis {
                    Basis::Expr(e) if ir.is_constant(e) => constant = true,
                    Basis::Expr(_) => is_static = true,
                    Basis::Deriv { body, order: 1 } if ir.signal(ir.velocity(body)).measured => {
                        velocities.push(ir.signal(ir.velocity(body)).name.clone());
                    }
                    Basis::Deriv { .. } => derivative = true,
                }
            }
            let mut kinds = Vec::new();
            if constant {
                kinds.push("constant (needs data with a mean)".to_string());
            }
            if is_static || !velocities.is_empty() {
                kinds.push(if velocities.is_empty() {
                    "static".to_string()
                } else {
                    velocities.sort();
                    velocities.dedup();
                    format!("static ({} measured)", velocities.join(", "))
                });
            }
            if derivative {
                kinds.push("derivative (moved onto the filter)".to_string());
            }
            if !integrated.is_empty() {
                integrated.sort();
                integrated.dedup();
                kinds.push(format!(
                    "from {} (integrals moved onto band-pass filters)",
                    integrated.join(", ")
                ));
            }
            rows.push(ColumnRow {
                column: ir.params[p.index()].name.clone(),
                equation: ir.bodies[eq.body.index()].name.clone(),
                basis: join_signed(&pieces),
                kind: kinds.join(" + "),
            });
        }
    }
    rows
}

fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let all: Vec<Vec<String>> = std::iter::once(header.iter().map(|h| h.to_string()).collect())
        .chain(rows.iter().cloned())
        .collect();
    aligned(&all, &[], "  ")
}

/// Text columns padded to their widest cell, counted in characters (so that σ, χ² and Δ
/// do not throw the alignment off), two spaces apart, each line starting with `indent`.
/// `right[j]` right-aligns column j (left where absent); a left-aligned last cell is not
/// padded and lines carry no trailing spaces.
pub fn aligned(rows: &[Vec<String>], right: &[bool], indent: &str) -> String {
    let ncol = rows.iter().map(Vec::len).max().unwrap_or(0);
    let width: Vec<usize> = (0..ncol)
        .map(|j| {
            rows.iter()
                .filter_map(|r| r.get(j))
                .map(|c| c.chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut out = String::new();
    for r in rows {
        let mut line = indent.to_string();
        for (j, c) in r.iter().enumerate() {
            let pad = " ".repeat(width[j] - c.chars().count());
            let last = j + 1 == r.len();
            if j > 0 {
                line.push_str("  ");
            }
            if right.get(j).copied().unwrap_or(false) {
                line.push_str(&pad);
                line.push_str(c);
            } else {
                line.push_str(c);
                if !last {
                    line.push_str(&pad);
                }
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

/// The parameter table as text.
pub fn render_params(ir: &ModelIr) -> String {
    let rows: Vec<Vec<String>> = param_rows(ir)
        .into_iter()
        .map(|r| {
            let value = match (r.kind, r.value) {
                ("known", Some(v)) => format!("= {}", fmt_num(v)),
                (_, Some(v)) => format!("~ {}", fmt_num(v)),
                (_, None) => "(no nominal)".into(),
            };
            vec![r.name, r.kind.to_string(), value, r.used_by.join(", ")]
        })
        .collect();
    table(&["parameter", "kind", "value", "used by"], &rows)
}

/// The column table as text.
pub fn render_columns(ir: &ModelIr) -> String {
    let rows: Vec<Vec<String>> = column_rows(ir)
        .into_iter()
        .map(|r| vec![r.column, r.equation, r.basis, r.kind])
        .collect();
    table(&["column", "equation", "basis", "kind"], &rows)
}

/// The full text report of `dynid compile`.
pub fn render_report(ir: &ModelIr) -> String {
    let mut out = String::new();
    let n_unknown = ir.unknowns().len();
    let _ = writeln!(
        out,
        "model {}: {} bod{}, {} input{}, {} parameter{} ({n_unknown} unknown)",
        ir.name,
        ir.bodies.len(),
        if ir.bodies.len() == 1 { "y" } else { "ies" },
        ir.inputs.len(),
        if ir.inputs.len() == 1 { "" } else { "s" },
        ir.params.len(),
        if ir.params.len() == 1 { "" } else { "s" },
    );
    let measured: Vec<&str> = ir
        .signals
        .iter()
        .filter(|s| s.measured)
        .map(|s| s.name.as_str())
        .collect();
    let _ = writeln!(out, "measured: {}", measured.join(", "));
    for (input, law) in control_rows(ir) {
        let _ = writeln!(out, "closed loop: {input} = {law}");
    }
    out.push_str("\nequations of motion:\n");
    for eq in &ir.equations {
        let _ = writeln!(out, "  {}", render_equation(ir, eq));
    }
    out.push_str("\nparameters:\n");
    out.push_str(&render_params(ir));
    for sh in &ir.shapes {
        let _ = writeln!(
            out,
            "  shape parameter {} ~ {} (a gap or limit: profiled by identification, not a column)",
            sh.name,
            fmt_num(sh.nominal)
        );
    }
    out.push_str("\nleast-squares columns:\n");
    out.push_str(&render_columns(ir));
    out
}

#[derive(Serialize)]
struct JsonEquation {
    body: String,
    text: String,
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

#[derive(Serialize)]
struct JsonControl {
    input: String,
    law: String,
}

#[derive(Serialize)]
struct JsonReport {
    model: String,
    measured: Vec<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    controls: Vec<JsonControl>,
    equations: Vec<JsonEquation>,
    params: Vec<ParamRow>,
    columns: Vec<ColumnRow>,
}

/// The report of `dynid compile --format json`.
pub fn report_json(ir: &ModelIr) -> serde_json::Value {
    let r = JsonReport {
        model: ir.name.clone(),
        measured: ir
            .signals
            .iter()
            .filter(|s| s.measured)
            .map(|s| s.name.clone())
            .collect(),
        controls: control_rows(ir)
            .into_iter()
            .map(|(input, law)| JsonControl { input, law })
            .collect(),
        equations: ir
            .equations
            .iter()
            .map(|eq| JsonEquation {
                body: ir.bodies[eq.body.index()].name.clone(),
                text: render_equation(ir, eq)
                    .split_once(": ")
                    .map(|(_, t)| t.to_string())
                    .unwrap_or_default(),
            })
            .collect(),
        params: param_rows(ir),
        columns: column_rows(ir),
    };
    serde_json::to_value(r).unwrap_or(serde_json::Value::Null)
}

fn node_name(ir: &ModelIr, n: Node) -> &str {
    match n {
        Node::Ground => "ground",
        Node::Body(b) => &ir.bodies[b.index()].name,
    }
}

fn value_suffix(kind: &ParamKind) -> String {
    match kind {
        ParamKind::Known(v) => format!(" = {}", fmt_num(*v)),
        ParamKind::Unknown { nominal: Some(v) } => format!(" ~ {}", fmt_num(*v)),
        ParamKind::Unknown { nominal: None } => String::new(),
    }
}

/// The model as `.dyn` source. Parameters are declared where they are first used, so
/// compiling the text gives back the same IR (spans aside).
pub fn to_source(ir: &ModelIr) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "model {} {{", ir.name);
    let mut declared = vec![false; ir.params.len()];
    for b in &ir.bodies {
        match b.mass.param {
            Some(p) => {
                declared[p.index()] = true;
                let _ = writeln!(
                    out,
                    "    body {}{}",
                    b.name,
                    value_suffix(&ir.params[p.index()].kind)
                );
            }
            None => {
                let _ = writeln!(out, "    body {} = {}", b.name, fmt_num(b.mass.scale));
            }
        }
    }
    for i in &ir.inputs {
        let _ = writeln!(
            out,
            "    input {} on {}",
            i.name,
            ir.bodies[i.body.index()].name
        );
    }
    for r in &ir.references {
        let _ = writeln!(out, "    reference {}", r.name);
    }
    for (input, law) in control_rows(ir) {
        let _ = writeln!(out, "    control {input} = {law}");
    }
    if ir.signals.iter().any(|s| !s.measured) {
        let m: Vec<&str> = ir
            .signals
            .iter()
            .filter(|s| s.measured)
            .map(|s| s.name.as_str())
            .collect();
        let _ = writeln!(out, "    measure {}", m.join(", "));
    }
    // Parameters owned by springs and dampers are declared by their statement, wherever
    // it stands, so force terms refer to them by name.
    let owned = |e: &ElementIr| -> Option<ParamId> {
        let basis = match e.kind {
            ElementKind::Spring => e.s,
            ElementKind::Damper => e.v,
            ElementKind::Force => return None,
        };
        match e.terms.as_slice() {
            [t] if t.basis == basis && t.coef.scale == 1.0 => {
                t.coef.param.filter(|p| ir.params[p.index()].name == e.name)
            }
            _ => None,
        }
    };
    for e in &ir.elements {
        if let Some(p) = owned(e) {
            declared[p.index()] = true;
        }
    }
    let shapes_declared = std::cell::RefCell::new(vec![false; ir.shapes.len()]);
    for e in &ir.elements {
        let (a, b) = (node_name(ir, e.nodes.0), node_name(ir, e.nodes.1));
        if let Some(p) = owned(e) {
            let kw = if e.kind == ElementKind::Spring {
                "spring"
            } else {
                "damper"
            };
            let _ = writeln!(
                out,
                "    {kw} {} ({a}, {b}){}",
                e.name,
                value_suffix(&ir.params[p.index()].kind)
            );
            continue;
        }
        let names = [(e.s, "s"), (e.v, "v")];
        let pr = Printer {
            ir,
            names: &names,
            declared: Some(&shapes_declared),
        };
        let mut pieces = Vec::new();
        for t in &e.terms {
            let mut factors = Vec::new();
            let a = t.coef.scale.abs();
            if a != 1.0 || t.coef.param.is_none() {
                factors.push(fmt_num(a));
            }
            if let Some(p) = t.coef.param {
                let param = &ir.params[p.index()];
                if declared[p.index()] {
                    factors.push(param.name.clone());
                } else {
                    declared[p.index()] = true;
                    factors.push(format!("{}{}", param.name, value_suffix(&param.kind)));
                }
            }
            // A constant force is written as its coefficient alone (`f0 ~ -0.5`).
            if !(ir.is_constant(t.basis) && t.coef.param.is_some()) {
                factors.push(pr.at(t.basis, P_MUL + 1));
            }
            pieces.push((t.coef.scale < 0.0, factors.join(" * ")));
        }
        let _ = writeln!(
            out,
            "    force {} ({a}, {b}) = {}",
            e.name,
            join_signed(&pieces)
        );
    }
    let excite = |out: &mut String, name: &str, filter: &FormFilter, levels: &[f64]| {
        let form = match *filter {
            FormFilter::Lowpass { corner } => format!("lowpass(corner = {})", fmt_num(corner)),
            FormFilter::SecondOrder { freq, damping } => format!(
                "second_order(freq = {}, damping = {})",
                fmt_num(freq),
                fmt_num(damping)
            ),
            FormFilter::White => "white".into(),
            FormFilter::Moves {
                distance,
                speed,
                accel,
                dwell,
            } => format!(
                "moves(distance = {}, speed = {}, accel = {}, dwell = {})",
                fmt_num(distance),
                fmt_num(speed),
                fmt_num(accel),
                fmt_num(dwell)
            ),
        };
        let levels: Vec<String> = levels.iter().map(|l| fmt_num(*l)).collect();
        let _ = writeln!(
            out,
            "    excite {name}: {form} levels [{}]",
            levels.join(", ")
        );
    };
    for x in &ir.excitation {
        excite(
            &mut out,
            &ir.inputs[x.input.index()].name,
            &x.filter,
            &x.levels,
        );
    }
    for x in &ir.reference_excitation {
        let name = &ir.references[x.reference.index()].name;
        excite(&mut out, name, &x.filter, &x.levels);
    }
    if let Some(f) = &ir.filter {
        let corners: Vec<String> = f.corners.iter().map(|c| fmt_num(*c)).collect();
        let _ = write!(
            out,
            "    filter corners [{}] order {}",
            corners.join(", "),
            f.order
        );
        if !f.driven_by.is_empty() {
            let d: Vec<&str> = f
                .driven_by
                .iter()
                .map(|s| ir.signal(*s).name.as_str())
                .collect();
            let _ = write!(out, " driven by {}", d.join(", "));
        }
        out.push('\n');
    }
    out.push_str("}\n");
    out
}
