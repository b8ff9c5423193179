//! Lowering: spanned AST → [`ModelIr`], with validation.
//!
//! The passes, in order: declare names (`declare`), resolve element nodes and force terms
//! (`lower_element`), assemble the equations of motion (`edit::assemble_equations`), then check the model
//! against the data it will meet (`validate`). Every pass records its errors and carries on,
//! so one run reports all the problems of a file.
//!
//! Parameter order (= column order of the least-squares problem) is canonical: unknown
//! masses in body order, then element parameters in element order and, within an element,
//! in order of first use. Where a `param` statement stands in the file does not matter, so
//! printing a model and parsing it again gives the same IR.

use crate::ast::*;
use crate::error::{Draft, ErrorKind, ErrorSink};
use crate::ir::*;
use std::collections::HashMap;

const FUNCTIONS: &[(&str, usize)] = &[
    ("abs", 1),
    ("sign", 1),
    ("tanh", 1),
    ("sqrt", 1),
    ("exp", 1),
    ("deadzone", 2),
    ("saturate", 2),
];

const KEYWORDS: &[&str] = &[
    "model", "body", "input", "on", "measure", "param", "spring", "damper", "force", "excite",
    "levels", "filter", "corners", "order", "driven", "by",
];

fn is_reserved(name: &str) -> bool {
    matches!(name, "ground" | "s" | "v" | "t")
        || FUNCTIONS.iter().any(|(f, _)| *f == name)
        || KEYWORDS.contains(&name)
}

/// An expression tree during lowering. Constants are folded while the tree is built, and
/// only the final tree is interned, so the arena holds no dead intermediate nodes.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum LExpr {
    Const(f64),
    Sig(SignalId),
    Unary(UnaryOp, Box<LExpr>),
    Binary(BinaryOp, Box<LExpr>, Box<LExpr>),
    Powi(Box<LExpr>, i32),
    Deadzone(Box<LExpr>, f64),
    Saturate(Box<LExpr>, f64),
}

impl LExpr {
    fn as_const(&self) -> Option<f64> {
        match self {
            LExpr::Const(c) => Some(*c),
            _ => None,
        }
    }
    fn is_const(&self, v: f64) -> bool {
        self.as_const() == Some(v)
    }
    fn neg(a: LExpr) -> LExpr {
        match a {
            LExpr::Const(c) => LExpr::Const(-c),
            LExpr::Unary(UnaryOp::Neg, x) => *x,
            a => LExpr::Unary(UnaryOp::Neg, Box::new(a)),
        }
    }
    fn unary(op: UnaryOp, a: LExpr) -> LExpr {
        if op == UnaryOp::Neg {
            return LExpr::neg(a);
        }
        match a.as_const() {
            Some(c) => LExpr::Const(eval_node(ExprNode::Unary(op, ExprId(0)), &[c], &[])),
            None => LExpr::Unary(op, Box::new(a)),
        }
    }
    fn binary(op: BinaryOp, a: LExpr, b: LExpr) -> LExpr {
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
    fn powi(a: LExpr, n: i32) -> LExpr {
        match (a.as_const(), n) {
            (_, 1) => a,
            (_, 0) => LExpr::Const(1.0),
            (Some(c), n) => LExpr::Const(c.powi(n)),
            (None, n) => LExpr::Powi(Box::new(a), n),
        }
    }
    fn has_signal(&self) -> bool {
        match self {
            LExpr::Const(_) => false,
            LExpr::Sig(_) => true,
            LExpr::Unary(_, a)
            | LExpr::Powi(a, _)
            | LExpr::Deadzone(a, _)
            | LExpr::Saturate(a, _) => a.has_signal(),
            LExpr::Binary(_, a, b) => a.has_signal() || b.has_signal(),
        }
    }
    /// Split off a constant factor: `-2 * x` → (−2, x). Used to put every term in the form
    /// `scale · param · basis` with a basis that carries no sign or constant factor.
    fn extract_scale(self) -> (f64, LExpr) {
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
    pub(crate) fn intern(&self, arena: &mut ExprArena) -> ExprId {
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
            LExpr::Deadzone(a, g) => {
                let a = a.intern(arena);
                arena.intern(ExprNode::Deadzone(a, g.to_bits()))
            }
            LExpr::Saturate(a, l) => {
                let a = a.intern(arena);
                arena.intern(ExprNode::Saturate(a, l.to_bits()))
            }
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Decl {
    Body(BodyId),
    Input(InputId),
    /// An element; springs and dampers own the parameter of the same name.
    Element(Option<usize>),
    /// A parameter (index into `Lowerer::pending`).
    Param(usize),
}

/// A declared parameter; it receives its `ParamId` at its first use.
struct Pending {
    name: String,
    value: Option<AstValue>,
    span: Span,
    /// Declared by a `param` statement (so it may be unused).
    statement: bool,
    /// Named in some force term, even one rejected with an error (no "unused" cascade).
    mentioned: bool,
    id: Option<ParamId>,
}

struct Lowerer<'a> {
    sink: &'a mut ErrorSink,
    names: HashMap<String, (Decl, Span)>,
    bodies: Vec<BodyIr>,
    body_spans: Vec<Span>,
    inputs: Vec<(String, AstIdent, Span)>,
    pending: Vec<Pending>,
    params: Vec<ParamIr>,
    param_spans: Vec<Span>,
    arena: ExprArena,
}

/// A lowered element with the spans of its terms (for late errors).
struct LoweredElement {
    ir: ElementIr,
    term_spans: Vec<Span>,
}

/// Where a parameter occurrence sits in its term.
#[derive(Clone, Debug)]
enum Place {
    /// A plain factor: only `*`, `/` (numerator) and unary minus above it.
    Factor,
    /// Anywhere else; the string says where, for the error message.
    Nested(String),
}

pub(crate) fn lower(ast: &AstModel, sink: &mut ErrorSink) -> ModelIr {
    let mut l = Lowerer {
        sink,
        names: HashMap::new(),
        bodies: Vec::new(),
        body_spans: Vec::new(),
        inputs: Vec::new(),
        pending: Vec::new(),
        params: Vec::new(),
        param_spans: Vec::new(),
        arena: ExprArena::default(),
    };
    l.declare(ast);
    let input_bodies = l.resolve_inputs();
    let elements: Vec<LoweredElement> = ast
        .items
        .iter()
        .filter_map(|it| match it {
            AstItem::Element {
                kind,
                name,
                nodes,
                expr,
                span,
                ..
            } => Some(l.lower_element(*kind, name, nodes, expr.as_ref(), *span)),
            _ => None,
        })
        .collect();
    for p in &l.pending {
        if p.statement && p.id.is_none() && !p.mentioned {
            let name = &p.name;
            l.sink.error(
                ErrorKind::UnusedParameter,
                format!("parameter `{name}` is declared but never used"),
                p.span,
                "declared here",
                format!(
                    "use it as a factor of a force term (`{name} * s^3`) or remove the declaration"
                ),
            );
        }
    }
    let inputs: Vec<InputIr> = l
        .inputs
        .iter()
        .zip(&input_bodies)
        .map(|((name, _, _), &body)| InputIr {
            name: name.clone(),
            body,
        })
        .collect();
    let input_spans = l.inputs.iter().map(|i| i.2).collect();

    let nb = l.bodies.len();
    let mut signals = Vec::with_capacity(2 * nb + inputs.len());
    for (i, b) in l.bodies.iter().enumerate() {
        let id = BodyId(i as u32);
        for (suffix, kind) in [
            ("x", SignalKind::Position(id)),
            ("v", SignalKind::Velocity(id)),
        ] {
            signals.push(SignalIr {
                name: format!("{}.{suffix}", b.name),
                kind,
                measured: true,
            });
        }
    }
    for (j, i) in inputs.iter().enumerate() {
        signals.push(SignalIr {
            name: i.name.clone(),
            kind: SignalKind::Input(InputId(j as u32)),
            measured: true,
        });
    }
    // Input signals are interned: the input forces of the equations refer to them.
    for j in 0..inputs.len() {
        l.arena.signal(SignalId((2 * nb + j) as u32));
    }
    let term_spans: Vec<Vec<Span>> = elements.iter().map(|e| e.term_spans.clone()).collect();
    let elements: Vec<ElementIr> = elements.into_iter().map(|e| e.ir).collect();

    let mut ir = ModelIr {
        name: ast.name.name.clone(),
        bodies: std::mem::take(&mut l.bodies),
        inputs,
        params: std::mem::take(&mut l.params),
        signals,
        elements,
        exprs: std::mem::take(&mut l.arena).into_nodes(),
        equations: Vec::new(),
        excitation: Vec::new(),
        filter: None,
        spans: SpanTable {
            bodies: std::mem::take(&mut l.body_spans),
            inputs: input_spans,
            params: std::mem::take(&mut l.param_spans),
            elements: ast
                .items
                .iter()
                .filter_map(|it| match it {
                    AstItem::Element { span, .. } => Some(*span),
                    _ => None,
                })
                .collect(),
            model: ast.span,
        },
    };
    ir.equations = crate::edit::assemble_equations(&ir);
    l.statements(ast, &mut ir);
    l.validate(ast, &ir, &term_spans);
    ir
}

/// Levenshtein distance, for "did you mean" suggestions.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

fn closest<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .map(|c| (distance(name, c), c))
        .filter(|&(d, c)| d <= 2 && d < c.len().max(name.len()))
        .min()
        .map(|(_, c)| c)
}

fn fmt_value(v: f64) -> String {
    crate::num::exact(v)
}

impl Lowerer<'_> {
    fn err(&mut self, kind: ErrorKind, message: String, span: Span, label: &str, help: String) {
        self.sink.error(kind, message, span, label, help);
    }

    fn register(&mut self, ident: &AstIdent, decl: Decl, what: &str) -> bool {
        if is_reserved(&ident.name) {
            self.err(
                ErrorKind::ReservedName,
                format!("`{}` is a reserved word and cannot name a {what}", ident.name),
                ident.span,
                "reserved",
                "choose another name; `ground`, `s`, `v`, `t`, the functions and the keywords are reserved".into(),
            );
            // Still declared, so that its uses are not reported again as unknown names.
            self.names
                .entry(ident.name.clone())
                .or_insert((decl, ident.span));
            return false;
        }
        if let Some(&(_, first)) = self.names.get(&ident.name) {
            self.sink.draft(
                ErrorKind::DuplicateName,
                Draft {
                    message: format!("`{}` is declared twice", ident.name),
                    span: Some(ident.span),
                    label: "declared again here".into(),
                    other: Some(first),
                    other_label: "first declared here".into(),
                    help: "bodies, inputs, elements and parameters share one namespace; rename one of them (to share a parameter, declare it once and refer to it by name)".into(),
                },
            );
            return false;
        }
        self.names.insert(ident.name.clone(), (decl, ident.span));
        true
    }

    fn add_pending(
        &mut self,
        name: &AstIdent,
        value: Option<AstValue>,
        span: Span,
        statement: bool,
    ) -> usize {
        self.pending.push(Pending {
            name: name.name.clone(),
            value,
            span,
            statement,
            mentioned: false,
            id: None,
        });
        self.pending.len() - 1
    }

    fn new_param(&mut self, name: &str, kind: ParamKind, span: Span) -> ParamId {
        self.params.push(ParamIr {
            name: name.to_string(),
            kind,
        });
        self.param_spans.push(span);
        ParamId(self.params.len() as u32 - 1)
    }

    /// The parameter of a pending declaration, created at its first use.
    fn use_param(&mut self, p: usize) -> ParamId {
        if let Some(id) = self.pending[p].id {
            return id;
        }
        let kind = match self.pending[p].value {
            None => ParamKind::Unknown { nominal: None },
            Some(AstValue::Nominal(n)) => ParamKind::Unknown {
                nominal: Some(n.value),
            },
            Some(AstValue::Known(n)) => ParamKind::Known(n.value),
        };
        let (name, span) = (self.pending[p].name.clone(), self.pending[p].span);
        let id = self.new_param(&name, kind, span);
        self.pending[p].id = Some(id);
        id
    }

    /// Declaration pass: every name of the file, in textual order.
    fn declare(&mut self, ast: &AstModel) {
        for item in &ast.items {
            match item {
                AstItem::Body { name, mass, span } => {
                    let id = BodyId(self.bodies.len() as u32);
                    self.register(name, Decl::Body(id), "body");
                    let mass = match mass {
                        None => {
                            self.err(
                                ErrorKind::MissingMass,
                                format!("body `{}` has no mass", name.name),
                                name.span,
                                "no `= mass` or `~ nominal`",
                                format!("write `body {0} = 1.0` for a known mass or `body {0} ~ 1.0` for an unknown mass with nominal 1.0", name.name),
                            );
                            Coef::constant(1.0)
                        }
                        Some(AstValue::Known(n)) => {
                            self.check_positive(n, "a mass");
                            Coef::constant(n.value)
                        }
                        Some(AstValue::Nominal(n)) => {
                            self.check_positive(n, "a mass");
                            let p = self.new_param(
                                &name.name,
                                ParamKind::Unknown {
                                    nominal: Some(n.value),
                                },
                                *span,
                            );
                            Coef::param(p)
                        }
                    };
                    self.bodies.push(BodyIr {
                        name: name.name.clone(),
                        mass,
                    });
                    self.body_spans.push(*span);
                }
                AstItem::Input { name, body, span } => {
                    let id = InputId(self.inputs.len() as u32);
                    self.register(name, Decl::Input(id), "input");
                    self.inputs.push((name.name.clone(), body.clone(), *span));
                }
                AstItem::Param { name, value, span } => {
                    let p = self.add_pending(name, *value, *span, true);
                    self.register(name, Decl::Param(p), "parameter");
                }
                AstItem::Element {
                    kind,
                    name,
                    value,
                    expr,
                    span,
                    ..
                } => {
                    let owned = match kind {
                        AstElementKind::Force => None,
                        _ => Some(self.add_pending(name, *value, *span, false)),
                    };
                    self.register(name, Decl::Element(owned), "element");
                    if let Some(e) = expr {
                        self.declare_inline(e);
                    }
                }
                _ => {}
            }
        }
        // A bare, undeclared name in factor position declares an unknown parameter without
        // nominal value. Done after all explicit declarations so a later `param` wins.
        for item in &ast.items {
            if let AstItem::Element { expr: Some(e), .. } = item {
                let mut found = Vec::new();
                for (_, term) in split_sum(e) {
                    walk_params(term, Place::Factor, &mut |leaf, place| {
                        if let (AstExprKind::Ref(r), Place::Factor) = (&leaf.kind, place) {
                            if r.field.is_none() && !is_reserved(&r.base.name) {
                                found.push(r.base.clone());
                            }
                        }
                    });
                }
                for ident in found {
                    if !self.names.contains_key(&ident.name) {
                        let p = self.add_pending(&ident, None, ident.span, false);
                        self.names
                            .insert(ident.name.clone(), (Decl::Param(p), ident.span));
                    }
                }
            }
        }
    }

    fn declare_inline(&mut self, e: &AstExpr) {
        let mut decls = Vec::new();
        walk_params(e, Place::Factor, &mut |leaf, _| {
            if let AstExprKind::ParamDecl(name, value) = &leaf.kind {
                decls.push((name.clone(), *value, leaf.span));
            }
        });
        for (name, value, span) in decls {
            let p = self.add_pending(&name, Some(value), span, false);
            self.register(&name, Decl::Param(p), "parameter");
        }
    }

    fn check_positive(&mut self, n: &AstNumber, what: &str) -> bool {
        if n.value > 0.0 {
            return true;
        }
        self.err(
            ErrorKind::InvalidValue,
            format!("{what} must be positive, found {}", fmt_value(n.value)),
            n.span,
            "not positive",
            format!("give {what} greater than zero"),
        );
        false
    }

    fn body_names(&self) -> Vec<&str> {
        self.bodies.iter().map(|b| b.name.as_str()).collect()
    }

    /// A node of an element or the body of an input.
    fn resolve_body(&mut self, ident: &AstIdent, allow_ground: bool) -> Option<Node> {
        if ident.name == "ground" && allow_ground {
            return Some(Node::Ground);
        }
        match self.names.get(&ident.name) {
            Some(&(Decl::Body(b), _)) => Some(Node::Body(b)),
            Some(_) => {
                self.err(
                    ErrorKind::InvalidConnection,
                    format!("`{}` is not a body", ident.name),
                    ident.span,
                    "not a body",
                    "elements connect bodies (or `ground`); inputs act on a body".into(),
                );
                None
            }
            None => {
                let bodies = self.body_names();
                let help = match closest(&ident.name, bodies.into_iter().chain(["ground"])) {
                    Some(c) => {
                        format!("did you mean `{c}`? Declare bodies with `body NAME = mass`")
                    }
                    None => {
                        "declare the body with `body NAME = mass`, or connect to `ground`".into()
                    }
                };
                self.err(
                    ErrorKind::UndefinedName,
                    format!("unknown body `{}`", ident.name),
                    ident.span,
                    "not declared",
                    help,
                );
                None
            }
        }
    }

    fn resolve_inputs(&mut self) -> Vec<BodyId> {
        let inputs = self.inputs.clone();
        inputs
            .iter()
            .map(|(name, body, span)| {
                if body.name == "ground" {
                    self.err(
                        ErrorKind::InvalidConnection,
                        format!("input `{name}` acts on ground"),
                        *span,
                        "on ground",
                        "an input force must act on a body".into(),
                    );
                    return BodyId(0);
                }
                match self.resolve_body(body, false) {
                    Some(Node::Body(b)) => b,
                    _ => BodyId(0),
                }
            })
            .collect()
    }

    fn lower_element(
        &mut self,
        kind: AstElementKind,
        name: &AstIdent,
        nodes: &(AstIdent, AstIdent),
        expr: Option<&AstExpr>,
        span: Span,
    ) -> LoweredElement {
        let a = self.resolve_body(&nodes.0, true);
        let b = self.resolve_body(&nodes.1, true);
        let (a, b) = (a.unwrap_or(Node::Ground), b.unwrap_or(Node::Ground));
        let resolved = !(nodes.0.name != "ground" && a == Node::Ground
            || nodes.1.name != "ground" && b == Node::Ground);
        if resolved && a == b {
            let what = if a == Node::Ground {
                "connects ground to ground".to_string()
            } else {
                format!("connects `{}` to itself", nodes.0.name)
            };
            self.err(
                ErrorKind::InvalidConnection,
                format!("element `{}` {what}", name.name),
                Span::new(nodes.0.span.start, nodes.1.span.end),
                "same node twice",
                "an element acts between two different nodes, e.g. `(ground, m1)` or `(m1, m2)`"
                    .into(),
            );
        }
        let rel = |suffix: u32| -> LExpr {
            let sig = |n: Node| match n {
                Node::Ground => None,
                Node::Body(b) => Some(LExpr::Sig(SignalId(2 * b.0 + suffix))),
            };
            match (sig(a), sig(b)) {
                (None, None) => LExpr::Const(0.0),
                (None, Some(xb)) => xb,
                (Some(xa), None) => LExpr::neg(xa),
                (Some(xa), Some(xb)) => LExpr::binary(BinaryOp::Sub, xb, xa),
            }
        };
        let (s_tree, v_tree) = (rel(0), rel(1));
        let s = s_tree.intern(&mut self.arena);
        let v = v_tree.intern(&mut self.arena);
        let owned = match self.names.get(&name.name) {
            Some(&(Decl::Element(p), _)) => p,
            _ => None,
        };
        let mut terms = Vec::new();
        let mut term_spans = Vec::new();
        let ir_kind = match kind {
            AstElementKind::Spring => ElementKind::Spring,
            AstElementKind::Damper => ElementKind::Damper,
            AstElementKind::Force => ElementKind::Force,
        };
        match (kind, expr) {
            (AstElementKind::Force, Some(expr)) => {
                let ctx = Ctx {
                    s: &s_tree,
                    v: &v_tree,
                };
                let (ss, s_core) = s_tree.clone().extract_scale();
                let (vs, v_core) = v_tree.clone().extract_scale();
                for (scale, param, basis, tspan) in self.lower_force(expr, &ctx) {
                    // Keep the element's own `s` and `v` nodes as bases, so that a term
                    // `c * v` is recognised as linear in the relative velocity.
                    let (scale, basis) = if basis == v_core {
                        (scale * vs, v)
                    } else if basis == s_core {
                        (scale * ss, s)
                    } else {
                        (scale, basis.intern(&mut self.arena))
                    };
                    terms.push(ForceTerm {
                        coef: Coef { scale, param },
                        basis,
                    });
                    term_spans.push(tspan);
                }
            }
            (_, _) => {
                let p = owned.map(|p| self.use_param(p));
                let coef = Coef {
                    scale: 1.0,
                    param: p,
                };
                terms.push(ForceTerm {
                    coef,
                    basis: if kind == AstElementKind::Damper { v } else { s },
                });
                term_spans.push(span);
            }
        }
        LoweredElement {
            ir: ElementIr {
                name: name.name.clone(),
                kind: ir_kind,
                nodes: (a, b),
                s,
                v,
                terms,
            },
            term_spans,
        }
    }

    /// Lower a force expression into terms `scale · param · basis` (`force` rule).
    fn lower_force(
        &mut self,
        expr: &AstExpr,
        ctx: &Ctx,
    ) -> Vec<(f64, Option<ParamId>, LExpr, Span)> {
        let mut out = Vec::new();
        for (sign, term) in split_sum(expr) {
            let mut occurrences = Vec::new();
            walk_params(term, Place::Factor, &mut |leaf, place| {
                occurrences.push((leaf, place));
            });
            let mut coef: Option<(usize, Span, String)> = None;
            let mut ok = true;
            for (leaf, place) in occurrences {
                let (pname, pspan) = match &leaf.kind {
                    AstExprKind::ParamDecl(n, _) => (n.name.clone(), n.span),
                    AstExprKind::Ref(r) if r.field.is_none() => (r.base.name.clone(), r.base.span),
                    _ => continue,
                };
                let Some(p) = self.param_of(&pname) else {
                    continue;
                };
                self.pending[p].mentioned = true;
                match place {
                    Place::Nested(where_) => {
                        ok = false;
                        self.err(
                            ErrorKind::NonlinearParameter,
                            format!("parameter `{pname}` enters its term nonlinearly ({where_})"),
                            pspan,
                            "not a plain factor of the term",
                            "every term must be (parameter) × (expression of signals and numbers), e.g. `k3 ~ 1.5 * s^3`; a parameter cannot appear inside a function, a power, a denominator or a nested sum — write gaps, limits and exponents as numbers, and multiply sums out into separate terms".into(),
                        );
                    }
                    Place::Factor => match &coef {
                        None => coef = Some((p, leaf.span, pname)),
                        Some((_, _, first)) => {
                            ok = false;
                            let first = first.clone();
                            self.err(
                                ErrorKind::NonlinearParameter,
                                format!("term multiplies two parameters, `{first}` and `{pname}`"),
                                pspan,
                                "second parameter of the term",
                                format!("the product `{first} * {pname}` is not linear in the parameters; use one parameter for the product"),
                            );
                        }
                    },
                }
            }
            let coef_span = coef.as_ref().map(|c| c.1);
            let Some(tree) = self.lower_expr(term, ctx, coef_span) else {
                continue;
            };
            if !ok {
                continue;
            }
            let (scale, mut basis) = tree.extract_scale();
            let mut scale = sign * scale;
            if !basis.has_signal() {
                // A constant force `scale · param · 1`: the basis is the constant 1, so that
                // every constant force of the model shares one column of moments.
                let value = basis.as_const().unwrap_or(f64::NAN);
                if coef.is_none() {
                    self.err(
                        ErrorKind::ConstantTerm,
                        "term is a bare number: it has no parameter and depends on no signal"
                            .into(),
                        term.span,
                        "a constant without a parameter",
                        "a constant force needs a parameter: write `f0 ~ 0.5` to identify it, or declare `param f0 = 0.5` and write `f0` for a known one; otherwise make the term depend on `s`, `v` or an input".into(),
                    );
                    continue;
                }
                if value == 0.0 {
                    self.err(
                        ErrorKind::ConstantTerm,
                        "term is identically zero".into(),
                        term.span,
                        "a zero constant",
                        "remove the term, or make it depend on `s`, `v` or an input".into(),
                    );
                    continue;
                }
                scale *= value;
                basis = LExpr::Const(1.0);
            }
            if !scale.is_finite() {
                self.err(
                    ErrorKind::InvalidValue,
                    "the constant factor of this term is not finite".into(),
                    term.span,
                    "division by zero?",
                    "check the numeric factors of the term".into(),
                );
                continue;
            }
            let param = coef.map(|(p, _, _)| self.use_param(p));
            out.push((scale, param, basis, term.span));
        }
        out
    }

    fn param_of(&self, name: &str) -> Option<usize> {
        match self.names.get(name) {
            Some(&(Decl::Param(p), _)) | Some(&(Decl::Element(Some(p)), _)) => Some(p),
            _ => None,
        }
    }

    /// Lower a parameter-free expression (the `expr` rule and below). The occurrence at
    /// `coef` (the term's parameter) stands for 1. Returns `None` after an error.
    fn lower_expr(&mut self, e: &AstExpr, ctx: &Ctx, coef: Option<Span>) -> Option<LExpr> {
        let folded = |l: &mut Self, x: LExpr| -> Option<LExpr> {
            match x.as_const() {
                Some(c) if !c.is_finite() => {
                    l.err(
                        ErrorKind::InvalidValue,
                        "this constant expression is not a finite number".into(),
                        e.span,
                        "evaluates to inf or NaN",
                        "check for a division by zero or the square root of a negative number"
                            .into(),
                    );
                    None
                }
                _ => Some(x),
            }
        };
        match &e.kind {
            AstExprKind::Num(v) => Some(LExpr::Const(*v)),
            AstExprKind::ParamDecl(..) => Some(LExpr::Const(1.0)),
            AstExprKind::Ref(r) => self.lower_ref(r, ctx, coef),
            AstExprKind::Neg(a) => {
                let a = self.lower_expr(a, ctx, coef)?;
                Some(LExpr::neg(a))
            }
            AstExprKind::Binary(op, a, b) => {
                let a = self.lower_expr(a, ctx, coef);
                let b = self.lower_expr(b, ctx, coef);
                let op = match op {
                    AstBinOp::Add => BinaryOp::Add,
                    AstBinOp::Sub => BinaryOp::Sub,
                    AstBinOp::Mul => BinaryOp::Mul,
                    AstBinOp::Div => BinaryOp::Div,
                };
                let x = LExpr::binary(op, a?, b?);
                folded(self, x)
            }
            AstExprKind::Pow(a, b) => {
                let base = self.lower_expr(a, ctx, coef);
                let n = self.const_arg(b, ctx, "an exponent")?;
                if n.fract() != 0.0 || n.abs() > 64.0 {
                    self.err(
                        ErrorKind::NonConstantArgument,
                        format!("exponent {} is not a small integer", fmt_value(n)),
                        b.span,
                        "not an integer",
                        "use an integer exponent between -64 and 64 (e.g. `s^3`); for other powers use `sqrt`, `abs` and products".into(),
                    );
                    return None;
                }
                let x = LExpr::powi(base?, n as i32);
                folded(self, x)
            }
            AstExprKind::Call(f, args) => {
                let Some(&(_, arity)) = FUNCTIONS.iter().find(|(n, _)| *n == f.name) else {
                    let help = match closest(&f.name, FUNCTIONS.iter().map(|f| f.0)) {
                        Some(c) => format!("did you mean `{c}`? The functions are abs, sign, tanh, sqrt, exp, deadzone(x, gap) and saturate(x, limit)"),
                        None => "the functions are abs, sign, tanh, sqrt, exp, deadzone(x, gap) and saturate(x, limit)".into(),
                    };
                    self.err(
                        ErrorKind::InvalidCall,
                        format!("unknown function `{}`", f.name),
                        f.span,
                        "not a function",
                        help,
                    );
                    return None;
                };
                if args.len() != arity {
                    self.err(
                        ErrorKind::InvalidCall,
                        format!(
                            "`{}` takes {arity} argument{}, found {}",
                            f.name,
                            if arity == 1 { "" } else { "s" },
                            args.len()
                        ),
                        e.span,
                        "wrong number of arguments",
                        match arity {
                            1 => format!("write `{}(x)`", f.name),
                            _ => format!("write `{}(x, c)` with a positive number c", f.name),
                        },
                    );
                    return None;
                }
                let x = self.lower_expr(&args[0], ctx, coef);
                let x = match f.name.as_str() {
                    "deadzone" | "saturate" => {
                        let what = if f.name == "deadzone" {
                            "the gap"
                        } else {
                            "the limit"
                        };
                        let c = self.const_arg(&args[1], ctx, what)?;
                        let ok = if f.name == "deadzone" {
                            c >= 0.0
                        } else {
                            c > 0.0
                        };
                        if !ok {
                            self.err(
                                ErrorKind::InvalidValue,
                                format!(
                                    "{what} of `{}` must be {}",
                                    f.name,
                                    if f.name == "deadzone" {
                                        "non-negative"
                                    } else {
                                        "positive"
                                    }
                                ),
                                args[1].span,
                                "out of range",
                                format!("write `{}(s, 0.1)`", f.name),
                            );
                            return None;
                        }
                        let x = x?;
                        match (f.name.as_str(), x.as_const()) {
                            ("deadzone", Some(a)) => LExpr::Const(deadzone(a, c)),
                            ("deadzone", None) => LExpr::Deadzone(Box::new(x), c),
                            (_, Some(a)) => LExpr::Const(saturate(a, c)),
                            (_, None) => LExpr::Saturate(Box::new(x), c),
                        }
                    }
                    name => {
                        let op = match name {
                            "abs" => UnaryOp::Abs,
                            "sign" => UnaryOp::Sign,
                            "tanh" => UnaryOp::Tanh,
                            "sqrt" => UnaryOp::Sqrt,
                            _ => UnaryOp::Exp,
                        };
                        LExpr::unary(op, x?)
                    }
                };
                folded(self, x)
            }
        }
    }

    /// A numeric-constant argument (exponent, gap, limit).
    fn const_arg(&mut self, e: &AstExpr, ctx: &Ctx, what: &str) -> Option<f64> {
        let x = self.lower_expr(e, ctx, None)?;
        match x.as_const() {
            Some(c) => Some(c),
            None => {
                self.err(
                    ErrorKind::NonConstantArgument,
                    format!("{what} must be a numeric constant"),
                    e.span,
                    "depends on a signal",
                    format!("write {what} as a number"),
                );
                None
            }
        }
    }

    fn lower_ref(&mut self, r: &AstSigRef, ctx: &Ctx, coef: Option<Span>) -> Option<LExpr> {
        let name = r.base.name.as_str();
        if let Some(field) = &r.field {
            return match self.names.get(name) {
                Some(&(Decl::Body(b), _)) => match field.name.as_str() {
                    "x" => Some(LExpr::Sig(SignalId(2 * b.0))),
                    "v" => Some(LExpr::Sig(SignalId(2 * b.0 + 1))),
                    other => {
                        self.err(
                            ErrorKind::InvalidSignal,
                            format!("`{name}.{other}` is not a signal"),
                            r.span,
                            "unknown suffix",
                            format!("a body has a position `{name}.x` and a velocity `{name}.v`"),
                        );
                        None
                    }
                },
                _ => {
                    self.undefined(&r.base, r.span, "signals are written `body.x` or `body.v`");
                    None
                }
            };
        }
        match name {
            "s" => return Some(ctx.s.clone()),
            "v" => return Some(ctx.v.clone()),
            "t" => {
                self.err(
                    ErrorKind::TimeDependent,
                    "a force element cannot depend on time `t`".into(),
                    r.span,
                    "time",
                    "the covariance method needs time-invariant forces; model a time-varying force as an `input`".into(),
                );
                return None;
            }
            _ => {}
        }
        match self.names.get(name).copied() {
            Some((Decl::Input(i), _)) => {
                Some(LExpr::Sig(SignalId((2 * self.bodies.len()) as u32 + i.0)))
            }
            Some((Decl::Param(_), _)) | Some((Decl::Element(Some(_)), _)) => {
                // The term's coefficient stands for 1; any other occurrence was reported.
                let _ = coef;
                Some(LExpr::Const(1.0))
            }
            Some((Decl::Body(_), _)) => {
                self.err(
                    ErrorKind::InvalidSignal,
                    format!("body `{name}` is not a value"),
                    r.span,
                    "a body",
                    format!("write its position `{name}.x` or velocity `{name}.v`"),
                );
                None
            }
            Some((Decl::Element(None), _)) => {
                self.err(
                    ErrorKind::InvalidSignal,
                    format!("element `{name}` is not a value"),
                    r.span,
                    "an element",
                    "inside a force use `s`, `v`, signals `m1.x`/`m1.v`, inputs and parameters"
                        .into(),
                );
                None
            }
            None => {
                self.undefined(&r.base, r.span, "");
                None
            }
        }
    }

    fn undefined(&mut self, ident: &AstIdent, span: Span, extra: &str) {
        let mut cands: Vec<String> = self.names.keys().cloned().collect();
        cands.extend(["s", "v"].map(String::from));
        for b in &self.bodies {
            cands.push(format!("{}.x", b.name));
            cands.push(format!("{}.v", b.name));
        }
        cands.sort();
        let help = match closest(&ident.name, cands.iter().map(String::as_str)) {
            Some(c) => format!("did you mean `{c}`? {extra}"),
            None => format!("a force may use `s`, `v`, signals `m1.x`/`m1.v`, inputs and parameters; a new parameter must be a plain factor of a term (`k ~ 1.0 * s`). {extra}"),
        };
        self.err(
            ErrorKind::UndefinedName,
            format!("`{}` is not defined", ident.name),
            span,
            "not declared",
            help.trim_end().to_string(),
        );
    }

    /// `measure`, `excite` and `filter` statements.
    fn statements(&mut self, ast: &AstModel, ir: &mut ModelIr) {
        // measure
        let lists: Vec<&Vec<AstSigRef>> = ast
            .items
            .iter()
            .filter_map(|it| match it {
                AstItem::Measure { signals, .. } => Some(signals),
                _ => None,
            })
            .collect();
        if !lists.is_empty() {
            for s in ir.signals.iter_mut() {
                s.measured = false;
            }
            for list in lists {
                for r in list {
                    if let Some(id) = self.signal_ref(r, ir) {
                        ir.signals[id.index()].measured = true;
                    }
                }
            }
        }
        // excite
        let mut first: Option<(usize, Span)> = None;
        let mut seen: HashMap<InputId, Span> = HashMap::new();
        for item in &ast.items {
            let AstItem::Excite {
                input,
                form,
                levels,
                levels_span,
                span: _,
            } = item
            else {
                continue;
            };
            let id = match self.names.get(&input.name) {
                Some(&(Decl::Input(i), _)) => Some(i),
                _ => {
                    let inputs: Vec<&str> = ir.inputs.iter().map(|i| i.name.as_str()).collect();
                    let help = match (
                        closest(&input.name, inputs.iter().copied()),
                        inputs.is_empty(),
                    ) {
                        (Some(c), _) => format!("did you mean `{c}`?"),
                        (None, true) => "declare an input first: `input u on m1`".into(),
                        (None, false) => format!(
                            "the inputs are {}",
                            inputs
                                .iter()
                                .map(|i| format!("`{i}`"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    };
                    self.err(
                        ErrorKind::UnknownInput,
                        format!("`{}` is not an input", input.name),
                        input.span,
                        "not an input",
                        help,
                    );
                    None
                }
            };
            if let Some(i) = id {
                if let Some(&prev) = seen.get(&i) {
                    self.sink.draft(
                        ErrorKind::DuplicateExcitation,
                        Draft {
                            message: format!("input `{}` is excited twice", input.name),
                            span: Some(input.span),
                            label: "second excitation".into(),
                            other: Some(prev),
                            other_label: "first excitation".into(),
                            help: "give each input one `excite` line".into(),
                        },
                    );
                } else {
                    seen.insert(i, input.span);
                }
            }
            let filter = self.form_filter(form);
            let mut good = true;
            for l in levels {
                good &= self.check_positive(l, "an excitation level");
            }
            if levels.is_empty() {
                self.err(
                    ErrorKind::InvalidValue,
                    "no excitation levels".into(),
                    *levels_span,
                    "empty",
                    "give at least one level, e.g. `levels [6, 15, 40]`; several levels make nonlinear terms identifiable".into(),
                );
                good = false;
            }
            match first {
                None => first = Some((levels.len(), *levels_span)),
                Some((n, span)) if n != levels.len() => {
                    self.sink.draft(
                        ErrorKind::LevelCountMismatch,
                        Draft {
                            message: format!("{} here but {} in the first `excite` line", levels_text(levels.len()), levels_text(n)),
                            span: Some(*levels_span),
                            label: levels_text(levels.len()),
                            other: Some(span),
                            other_label: levels_text(n),
                            help: "every `excite` line must list the same number of levels: level k of all inputs forms experiment k".into(),
                        },
                    );
                }
                _ => {}
            }
            if let (Some(i), Some(filter), true) = (id, filter, good) {
                ir.excitation.push(ExcitationIr {
                    input: i,
                    filter,
                    levels: levels.iter().map(|l| l.value).collect(),
                });
            }
        }
        // filter
        let filters: Vec<&AstItem> = ast
            .items
            .iter()
            .filter(|it| matches!(it, AstItem::Filter { .. }))
            .collect();
        for (k, item) in filters.iter().enumerate() {
            let AstItem::Filter {
                corners,
                corners_span,
                order,
                driven_by,
                span,
            } = item
            else {
                continue;
            };
            if k > 0 {
                self.err(
                    ErrorKind::DuplicateName,
                    "a second `filter` statement".into(),
                    *span,
                    "second filter",
                    "a model has at most one identification filter bank; merge the corner lists"
                        .into(),
                );
                continue;
            }
            for c in corners {
                self.check_positive(c, "a corner frequency");
            }
            if corners.is_empty() {
                self.err(
                    ErrorKind::InvalidValue,
                    "no corner frequencies".into(),
                    *corners_span,
                    "empty",
                    "list the corner frequencies in rad/s, e.g. `corners [0.5, 1, 2, 4, 8, 16]`"
                        .into(),
                );
            }
            let order_v = order.map_or(2, |o| o.0);
            if let Some((o, ospan)) = order {
                if !(1..=8).contains(o) {
                    self.err(
                        ErrorKind::InvalidValue,
                        format!("filter order {o} is out of range"),
                        *ospan,
                        "order",
                        "use an order between 1 and 8 (2 is the default and works with displacement-only data)".into(),
                    );
                } else if *o < 2 {
                    if let Some(b) = ir
                        .bodies
                        .iter()
                        .enumerate()
                        .find(|(i, _)| !ir.signals[2 * i + 1].measured)
                    {
                        self.err(
                            ErrorKind::InvalidValue,
                            format!("filter order 1 cannot be used: `{}.v` is not measured", b.1.name),
                            *ospan,
                            "order 1",
                            "without velocity data the acceleration term must move twice onto the filter; use `order 2` or more".into(),
                        );
                    }
                }
            }
            let mut ids = Vec::new();
            for r in driven_by {
                if let Some(id) = self.signal_ref(r, ir) {
                    if !ir.signals[id.index()].measured {
                        let n = &ir.signals[id.index()].name;
                        self.err(
                            ErrorKind::UnmeasuredSignal,
                            format!("the filter is driven by `{n}`, which is not measured"),
                            r.span,
                            "not measured",
                            format!(
                                "add `{n}` to `measure` or drive the filter by measured signals"
                            ),
                        );
                    }
                    ids.push(id);
                }
            }
            ir.filter = Some(FilterSpecIr {
                corners: corners.iter().map(|c| c.value).collect(),
                order: order_v,
                driven_by: ids,
            });
        }
    }

    fn form_filter(&mut self, form: &AstForm) -> Option<FormFilter> {
        let expected: &[&str] = match form.name.name.as_str() {
            "lowpass" => &["corner"],
            "second_order" => &["freq", "damping"],
            "white" => &[],
            other => {
                self.err(
                    ErrorKind::InvalidValue,
                    format!("unknown form filter `{other}`"),
                    form.name.span,
                    "not a form filter",
                    "use `lowpass(corner = ..)`, `second_order(freq = .., damping = ..)` or `white`".into(),
                );
                return None;
            }
        };
        let mut vals = vec![None; expected.len()];
        let mut ok = true;
        for a in &form.args {
            match expected.iter().position(|e| *e == a.name.name) {
                Some(k) => {
                    ok &= self.check_positive(&a.value, &format!("`{}`", a.name.name));
                    vals[k] = Some(a.value.value);
                }
                None => {
                    ok = false;
                    self.err(
                        ErrorKind::InvalidValue,
                        format!("`{}` has no argument `{}`", form.name.name, a.name.name),
                        a.name.span,
                        "unknown argument",
                        format!(
                            "`{}` takes {}",
                            form.name.name,
                            if expected.is_empty() {
                                "no arguments".to_string()
                            } else {
                                expected
                                    .iter()
                                    .map(|e| format!("`{e} = ..`"))
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            }
                        ),
                    );
                }
            }
        }
        for (k, v) in vals.iter().enumerate() {
            if v.is_none() {
                ok = false;
                self.err(
                    ErrorKind::InvalidValue,
                    format!("`{}` needs `{} = ..`", form.name.name, expected[k]),
                    form.span,
                    "missing argument",
                    "corner and frequencies are in rad/s, damping is a ratio, e.g. `lowpass(corner = 10)`, `second_order(freq = 20, damping = 0.3)`".into(),
                );
            }
        }
        if !ok {
            return None;
        }
        let v = |k: usize| vals[k].unwrap_or(1.0);
        Some(match expected.len() {
            0 => FormFilter::White,
            1 => FormFilter::Lowpass { corner: v(0) },
            _ => FormFilter::SecondOrder {
                freq: v(0),
                damping: v(1),
            },
        })
    }

    /// A signal in `measure` or `driven by`: `m1.x`, `m1.v` or an input name.
    fn signal_ref(&mut self, r: &AstSigRef, ir: &ModelIr) -> Option<SignalId> {
        let full = match &r.field {
            Some(f) => format!("{}.{}", r.base.name, f.name),
            None => r.base.name.clone(),
        };
        if let Some(id) = ir.signal_id(&full) {
            return Some(id);
        }
        let is_body = matches!(self.names.get(&r.base.name), Some((Decl::Body(_), _)));
        if is_body {
            let b = &r.base.name;
            self.err(
                ErrorKind::InvalidSignal,
                format!("`{full}` is not a signal"),
                r.span,
                "not a signal",
                format!("a body has a position `{b}.x` and a velocity `{b}.v`"),
            );
        } else {
            let help = match closest(&full, ir.signals.iter().map(|s| s.name.as_str())) {
                Some(c) => format!("did you mean `{c}`?"),
                None => format!(
                    "the signals are {}",
                    ir.signals
                        .iter()
                        .map(|s| format!("`{}`", s.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            };
            self.err(
                ErrorKind::UndefinedName,
                format!("unknown signal `{full}`"),
                r.span,
                "not a signal",
                help,
            );
        }
        None
    }

    /// Checks that need the whole IR: measured signals, identifiability of the scale.
    fn validate(&mut self, ast: &AstModel, ir: &ModelIr, term_spans: &[Vec<Span>]) {
        let measured = |s: SignalId| ir.signals[s.index()].measured;
        for (ei, e) in ir.elements.iter().enumerate() {
            for (ti, t) in e.terms.iter().enumerate() {
                if t.basis == e.v {
                    continue;
                }
                // An unmeasured velocity of a body whose position is measured is estimated
                // from the position at identification.
                let missing: Vec<SignalId> = ir
                    .expr_signals(t.basis)
                    .into_iter()
                    .filter(|&s| !measured(s))
                    .filter(|&s| match ir.signal(s).kind {
                        SignalKind::Velocity(b) => !measured(ir.position(b)),
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
                let span = term_spans
                    .get(ei)
                    .and_then(|s| s.get(ti))
                    .copied()
                    .unwrap_or(ir.spans.elements[ei]);
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
            if !measured(ir.position(id)) && !measured(ir.velocity(id)) {
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

struct Ctx<'a> {
    s: &'a LExpr,
    v: &'a LExpr,
}

/// Split a force expression into signed terms at its top-level `+` and `-`.
pub(crate) fn split_sum(e: &AstExpr) -> Vec<(f64, &AstExpr)> {
    let mut out = Vec::new();
    let mut stack = vec![(1.0, e)];
    while let Some((sign, e)) = stack.pop() {
        match &e.kind {
            AstExprKind::Binary(AstBinOp::Add, a, b) => {
                stack.push((sign, b));
                stack.push((sign, a));
            }
            AstExprKind::Binary(AstBinOp::Sub, a, b) => {
                stack.push((-sign, b));
                stack.push((sign, a));
            }
            AstExprKind::Neg(a)
                if matches!(
                    a.kind,
                    AstExprKind::Binary(AstBinOp::Add | AstBinOp::Sub, ..) | AstExprKind::Neg(_)
                ) =>
            {
                stack.push((-sign, a));
            }
            _ => out.push((sign, e)),
        }
    }
    out
}

/// Visit every name leaf (`Ref` without a field) and inline declaration of a term, with its
/// place: a plain factor, or nested somewhere a parameter may not stand.
fn walk_params<'e>(e: &'e AstExpr, place: Place, f: &mut impl FnMut(&'e AstExpr, Place)) {
    match &e.kind {
        AstExprKind::Num(_) => {}
        AstExprKind::Ref(r) => {
            if r.field.is_none() {
                f(e, place)
            }
        }
        AstExprKind::ParamDecl(..) => f(e, place),
        AstExprKind::Neg(a) => walk_params(a, place, f),
        AstExprKind::Binary(op, a, b) => match (op, &place) {
            (AstBinOp::Mul, _) => {
                walk_params(a, place.clone(), f);
                walk_params(b, place, f);
            }
            (AstBinOp::Div, Place::Factor) => {
                walk_params(a, Place::Factor, f);
                walk_params(b, Place::Nested("in a denominator".into()), f);
            }
            (AstBinOp::Div, Place::Nested(_)) => {
                walk_params(a, place.clone(), f);
                walk_params(b, place, f);
            }
            (_, Place::Factor) => {
                let p = Place::Nested(
                    "inside a parenthesised sum; multiply it out into separate terms".into(),
                );
                walk_params(a, p.clone(), f);
                walk_params(b, p, f);
            }
            (_, Place::Nested(_)) => {
                walk_params(a, place.clone(), f);
                walk_params(b, place, f);
            }
        },
        AstExprKind::Pow(a, b) => {
            let (pa, pb) = match &place {
                Place::Factor => (
                    Place::Nested("as the base of a power".into()),
                    Place::Nested("in an exponent".into()),
                ),
                Place::Nested(_) => (place.clone(), place.clone()),
            };
            walk_params(a, pa, f);
            walk_params(b, pb, f);
        }
        AstExprKind::Call(name, args) => {
            let p = match &place {
                Place::Factor => Place::Nested(format!("inside `{}(…)`", name.name)),
                Place::Nested(_) => place.clone(),
            };
            for a in args {
                walk_params(a, p.clone(), f);
            }
        }
    }
}

fn levels_text(n: usize) -> String {
    if n == 1 {
        "1 level".into()
    } else {
        format!("{n} levels")
    }
}
