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
//!
//! Where each job lives: this file holds the entry `lower`, the `Lowerer` state and the
//! declaration pass; `names` the namespace (reserved words, name resolution, "did you mean"
//! suggestions); `element` elements and the split of a force into terms; `force_expr` the
//! expression inside a term; `expr` the expression algebra those build; `statements` the
//! `measure`, `excite` and `filter` statements; `validate` the checks that need the whole IR.

mod element;
mod expr;
mod force_expr;
mod names;
mod statements;
mod validate;

use crate::ast::*;
use crate::error::{ErrorKind, ErrorSink};
use crate::ir::*;
use element::{split_sum, walk_params, LoweredElement, Place};
use names::is_reserved;
use std::collections::HashMap;

#[derive(Clone, Copy, Debug)]
enum Decl {
    Body(BodyId),
    Input(InputId),
    Reference(ReferenceId),
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

/// The state of lowering one model: the namespace, and the bodies, inputs and parameters
/// declared so far.
struct Lowerer<'a> {
    sink: &'a mut ErrorSink,
    names: HashMap<String, (Decl, Span)>,
    bodies: Vec<BodyIr>,
    body_spans: Vec<Span>,
    inputs: Vec<(String, AstIdent, Span)>,
    references: Vec<(String, Span)>,
    pending: Vec<Pending>,
    params: Vec<ParamIr>,
    param_spans: Vec<Span>,
    arena: ExprArena,
    /// Shape parameters: name, nominal value, and the nodes whose gap or limit it is.
    shapes: Vec<(String, f64, Vec<ExprId>)>,
    /// Pending parameter → its shape parameter.
    shape_of: HashMap<usize, usize>,
}

pub(crate) fn lower(ast: &AstModel, sink: &mut ErrorSink) -> ModelIr {
    let mut l = Lowerer {
        sink,
        names: HashMap::new(),
        bodies: Vec::new(),
        body_spans: Vec::new(),
        inputs: Vec::new(),
        references: Vec::new(),
        pending: Vec::new(),
        params: Vec::new(),
        param_spans: Vec::new(),
        arena: ExprArena::default(),
        shapes: Vec::new(),
        shape_of: HashMap::new(),
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
    // Laws before the check of unused parameters: a gain used only by a law is used.
    let (controls, control_spans) = l.controls(ast);
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
    for (k, (name, _)) in l.references.iter().enumerate() {
        signals.push(SignalIr {
            name: name.clone(),
            kind: SignalKind::Reference(ReferenceId(k as u32)),
            // A set point is always a column of the data.
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
        references: l
            .references
            .iter()
            .map(|(name, _)| ReferenceIr { name: name.clone() })
            .collect(),
        controls,
        reference_excitation: Vec::new(),
        shapes: std::mem::take(&mut l.shapes)
            .into_iter()
            .map(|(name, nominal, sites)| ShapeIr {
                name,
                nominal,
                sites,
            })
            .collect(),
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
            references: l.references.iter().map(|r| r.1).collect(),
            controls: control_spans,
            model: ast.span,
        },
    };
    ir.equations = crate::edit::assemble_equations(&ir);
    l.statements(ast, &mut ir);
    l.validate(ast, &ir, &term_spans);
    ir
}

fn fmt_value(v: f64) -> String {
    crate::num::exact(v)
}

impl Lowerer<'_> {
    fn err(&mut self, kind: ErrorKind, message: String, span: Span, label: &str, help: String) {
        self.sink.error(kind, message, span, label, help);
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
                AstItem::Reference { name, span } => {
                    let id = ReferenceId(self.references.len() as u32);
                    self.register(name, Decl::Reference(id), "reference");
                    self.references.push((name.name.clone(), *span));
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

    /// The check a force's terms get (element.rs): the constant factor of each term of a
    /// law must be finite, so `kp * (r - m.x) / 0` is refused here rather than making the
    /// simulation fail. Call only on a law that lowered without error.
    fn law_terms_finite(&mut self, law: &AstExpr, ctx: &force_expr::Ctx) -> bool {
        let mut ok = true;
        for (_, term) in element::split_sum(law) {
            let Some(t) = self.lower_expr(term, ctx, None) else {
                continue;
            };
            let (scale, _) = t.extract_scale();
            if !scale.is_finite() {
                self.err(
                    ErrorKind::InvalidValue,
                    "the constant factor of this term of the control law is not finite".into(),
                    term.span,
                    "division by zero?",
                    "check the numeric factors of the term".into(),
                );
                ok = false;
            }
        }
        ok
    }

    /// The `control` statements: each law lowered over body signals, references and known
    /// values, at most one per input.
    fn controls(&mut self, ast: &AstModel) -> (Vec<ControlIr>, Vec<Span>) {
        let mut out: Vec<ControlIr> = Vec::new();
        let mut spans: Vec<Span> = Vec::new();
        let zero = expr::LExpr::Const(0.0);
        for item in &ast.items {
            let AstItem::Control { input, law, span } = item else {
                continue;
            };
            let span = &Span::new(span.start, law.span.end.max(span.start));
            let id = match self.names.get(&input.name).copied() {
                Some((Decl::Input(i), _)) => Some(i),
                _ => {
                    self.err(
                        ErrorKind::InvalidControl,
                        format!("`{}` is not an input", input.name),
                        input.span,
                        "not an input",
                        "a control law computes an input: declare `input u on BODY` and write `control u = …`".into(),
                    );
                    None
                }
            };
            let ctx = force_expr::Ctx {
                s: &zero,
                v: &zero,
                law: true,
            };
            let mut lowered = self.lower_expr(law, &ctx, None);
            if lowered.is_some() && !self.law_terms_finite(law, &ctx) {
                lowered = None;
            }
            let Some(i) = id else { continue };
            if let Some(k) = out.iter().position(|c| c.input == i) {
                self.sink.draft(
                    ErrorKind::InvalidControl,
                    crate::error::Draft {
                        message: format!("input `{}` has two control laws", input.name),
                        span: Some(*span),
                        label: "second law".into(),
                        other: Some(spans[k]),
                        other_label: "first law".into(),
                        help: "give each input one `control` line".into(),
                    },
                );
                continue;
            }
            if let Some(x) = lowered {
                out.push(ControlIr {
                    input: i,
                    law: x.intern(&mut self.arena),
                });
                spans.push(*span);
            }
        }
        (out, spans)
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

    fn check_not_negative(&mut self, n: &AstNumber, what: &str) -> bool {
        if n.value >= 0.0 {
            return true;
        }
        self.err(
            ErrorKind::InvalidValue,
            format!("{what} must not be negative, found {}", fmt_value(n.value)),
            n.span,
            "negative",
            format!("give {what} as zero or more"),
        );
        false
    }
}
