//! Elements (`spring`, `damper`, `force` rules): their nodes, their relative displacement
//! `s` and velocity `v`, and the split of a force into terms `scale · param · basis`, with
//! the rules on where a parameter may stand in a term.

use super::expr::LExpr;
use super::force_expr::Ctx;
use super::{Decl, Lowerer};
use crate::ast::*;
use crate::error::ErrorKind;
use crate::ir::*;

/// A lowered element with the spans of its terms (for late errors).
pub(super) struct LoweredElement {
    pub(super) ir: ElementIr,
    pub(super) term_spans: Vec<Span>,
}

/// Where a parameter occurrence sits in its term.
#[derive(Clone, Debug)]
pub(super) enum Place {
    /// A plain factor: only `*`, `/` (numerator) and unary minus above it.
    Factor,
    /// Anywhere else; the string says where, for the error message.
    Nested(String),
    /// The gap of `deadzone` or the limit of `saturate` directly: an unknown parameter
    /// there is a shape parameter, profiled by identification.
    Shape,
}

impl Lowerer<'_> {
    pub(super) fn lower_element(
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
                    law: false,
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
                        let id = basis.intern(&mut self.arena);
                        let mut sites = Vec::new();
                        basis.shape_sites(&mut self.arena, &mut sites);
                        for (k, site) in sites {
                            if !self.shapes[k].2.contains(&site) {
                                self.shapes[k].2.push(site);
                            }
                        }
                        (scale, id)
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
                    // A known value is a number; an unknown one a shape parameter (checked
                    // where the gap is lowered).
                    Place::Shape => {}
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
}

/// Split a force expression into signed terms at its top-level `+` and `-`.
pub(super) fn split_sum(e: &AstExpr) -> Vec<(f64, &AstExpr)> {
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
pub(super) fn walk_params<'e>(
    e: &'e AstExpr,
    place: Place,
    f: &mut impl FnMut(&'e AstExpr, Place),
) {
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
            (AstBinOp::Div, _) => {
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
            (_, _) => {
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
                _ => (place.clone(), place.clone()),
            };
            walk_params(a, pa, f);
            walk_params(b, pb, f);
        }
        AstExprKind::Call(name, args) => {
            let p = match &place {
                Place::Factor => Place::Nested(format!("inside `{}(…)`", name.name)),
                _ => place.clone(),
            };
            let shaped = matches!(name.name.as_str(), "deadzone" | "saturate") && args.len() == 2;
            for (k, a) in args.iter().enumerate() {
                let named = match &a.kind {
                    AstExprKind::ParamDecl(..) => true,
                    AstExprKind::Ref(r) => r.field.is_none(),
                    _ => false,
                };
                if shaped && k == 1 && named {
                    f(a, Place::Shape);
                } else {
                    walk_params(a, p.clone(), f);
                }
            }
        }
    }
}
