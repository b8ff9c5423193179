//! The spanned syntax tree of a `.dyn` file, built from the pest parse tree.
//!
//! Every node carries the byte span of its source text so that lowering and validation can
//! point at the line of the model file.

use crate::error::{CompileError, ErrorSink};
use crate::grammar::{DynParser, Rule};
use crate::ir::Span;
use pest::iterators::Pair;
use pest::Parser;

/// Deeper nesting than this is rejected before parsing so that neither the parser nor the
/// recursive lowering can exhaust the stack on hostile input.
const MAX_NESTING: usize = 64;
/// Operators per force expression; bounds the recursion depth of lowering and printing.
pub(crate) const MAX_EXPR_NODES: usize = 1000;

#[derive(Clone, Debug, PartialEq)]
pub struct AstIdent {
    pub name: String,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AstNumber {
    pub value: f64,
    pub span: Span,
}

/// `~ nominal` (unknown) or `= value` (known).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AstValue {
    Nominal(AstNumber),
    Known(AstNumber),
}

/// `m1.x`, `m1.v` or a plain name.
#[derive(Clone, Debug, PartialEq)]
pub struct AstSigRef {
    pub base: AstIdent,
    pub field: Option<AstIdent>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub struct AstNamedArg {
    pub name: AstIdent,
    pub value: AstNumber,
}

#[derive(Clone, Debug, PartialEq)]
pub struct AstForm {
    pub name: AstIdent,
    pub args: Vec<AstNamedArg>,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AstElementKind {
    Spring,
    Damper,
    Force,
}

#[derive(Clone, Debug, PartialEq)]
pub enum AstItem {
    Body {
        name: AstIdent,
        mass: Option<AstValue>,
        span: Span,
    },
    Input {
        name: AstIdent,
        body: AstIdent,
        span: Span,
    },
    /// `reference r`: a measured set point that control laws read.
    Reference {
        name: AstIdent,
        span: Span,
    },
    /// `control u = law`: input `u` computed from the state and references.
    Control {
        input: AstIdent,
        law: AstExpr,
        span: Span,
    },
    Measure {
        signals: Vec<AstSigRef>,
        span: Span,
    },
    Param {
        name: AstIdent,
        value: Option<AstValue>,
        span: Span,
    },
    Element {
        kind: AstElementKind,
        name: AstIdent,
        nodes: (AstIdent, AstIdent),
        /// The value of a spring's or damper's parameter.
        value: Option<AstValue>,
        /// The force expression of a `force` element.
        expr: Option<AstExpr>,
        span: Span,
    },
    Excite {
        input: AstIdent,
        form: AstForm,
        levels: Vec<AstNumber>,
        levels_span: Span,
        span: Span,
    },
    Filter {
        corners: Vec<AstNumber>,
        corners_span: Span,
        order: Option<(u32, Span)>,
        driven_by: Vec<AstSigRef>,
        span: Span,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct AstModel {
    pub name: AstIdent,
    pub items: Vec<AstItem>,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AstBinOp {
    Add,
    Sub,
    Mul,
    Div,
}

#[derive(Clone, Debug, PartialEq)]
pub enum AstExprKind {
    Num(f64),
    /// A name or a signal reference (`s`, `u`, `k3`, `m1.x`).
    Ref(AstSigRef),
    /// `k ~ 1.5` or `k = 1.5` inside an expression.
    ParamDecl(AstIdent, AstValue),
    Neg(Box<AstExpr>),
    Binary(AstBinOp, Box<AstExpr>, Box<AstExpr>),
    Pow(Box<AstExpr>, Box<AstExpr>),
    Call(AstIdent, Vec<AstExpr>),
}

#[derive(Clone, Debug, PartialEq)]
pub struct AstExpr {
    pub kind: AstExprKind,
    pub span: Span,
}

fn span_of(p: &Pair<Rule>) -> Span {
    let s = p.as_span();
    // Implicit whitespace before an optional part that is absent stays in the pair's span;
    // a label should end at the last token, so trailing blanks and comments are cut.
    let inner_end = p.clone().into_inner().map(|c| c.as_span().end()).max();
    let from = inner_end.unwrap_or(s.start());
    let tail = &s.get_input()[from..s.end()];
    let mut end = from;
    let mut chars = tail.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        if c == '/' && tail[i..].starts_with("//") {
            while chars.next_if(|&(_, c)| c != '\n').is_some() {}
        } else if !c.is_whitespace() {
            end = from + i + c.len_utf8();
        }
    }
    Span::new(s.start(), end.max(s.start()))
}

/// Parse a whole file. Returns `None` (with the error recorded) on a syntax error; pest
/// stops at the first one, so at most one syntax error is reported per file.
pub(crate) fn parse(source: &str, sink: &mut ErrorSink) -> Option<AstModel> {
    if let Some(at) = too_deep(source) {
        sink.push(CompileError::syntax(
            sink,
            format!("parentheses nested deeper than {MAX_NESTING} levels"),
            Span::new(at, at + 1),
            "split the expression into several terms".into(),
        ));
        return None;
    }
    // Detailed attempts let a syntax error name the exact token expected (`,`, `)`, …).
    pest::set_error_detail(true);
    let mut pairs = match DynParser::parse(Rule::file, source) {
        Ok(p) => p,
        Err(e) => {
            sink.push(crate::syntax_error::from_pest(sink, e));
            return None;
        }
    };
    let file = pairs.next()?;
    let model = file.into_inner().next()?;
    Some(build_model(model, sink))
}

fn too_deep(source: &str) -> Option<usize> {
    let mut depth = 0usize;
    let mut in_comment = false;
    let bytes = source.as_bytes();
    for (i, &c) in bytes.iter().enumerate() {
        if in_comment {
            in_comment = c != b'\n';
            continue;
        }
        match c {
            b'/' if bytes.get(i + 1) == Some(&b'/') => in_comment = true,
            b'(' => {
                depth += 1;
                if depth > MAX_NESTING {
                    return Some(i);
                }
            }
            b')' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    None
}

fn ident(p: Pair<Rule>) -> AstIdent {
    AstIdent {
        name: p.as_str().to_string(),
        span: span_of(&p),
    }
}

fn number(p: Pair<Rule>, sink: &mut ErrorSink) -> AstNumber {
    let span = span_of(&p);
    let value = match p.as_str().parse::<f64>() {
        Ok(v) if v.is_finite() => v,
        _ => {
            sink.push(CompileError::invalid_value(
                sink,
                format!("`{}` is not a finite number", p.as_str()),
                span,
                "write a number within the range of a 64-bit float".into(),
            ));
            0.0
        }
    };
    AstNumber { value, span }
}

fn value(p: Pair<Rule>, sink: &mut ErrorSink) -> AstValue {
    let rule = p.as_rule();
    let n = number(
        p.into_inner().next().expect("grammar: value has a number"),
        sink,
    );
    if rule == Rule::nominal {
        AstValue::Nominal(n)
    } else {
        AstValue::Known(n)
    }
}

fn sigref(p: Pair<Rule>) -> AstSigRef {
    let span = span_of(&p);
    let mut it = p.into_inner();
    let base = ident(it.next().expect("grammar: sigref has a name"));
    let field = it.next().map(ident);
    AstSigRef { base, field, span }
}

fn num_list(p: Pair<Rule>, sink: &mut ErrorSink) -> (Vec<AstNumber>, Span) {
    let span = span_of(&p);
    (p.into_inner().map(|n| number(n, sink)).collect(), span)
}

fn is_keyword(r: Rule) -> bool {
    matches!(
        r,
        Rule::kw_model
            | Rule::kw_body
            | Rule::kw_input
            | Rule::kw_on
            | Rule::kw_measure
            | Rule::kw_reference
            | Rule::kw_control
            | Rule::kw_param
            | Rule::kw_spring
            | Rule::kw_damper
            | Rule::kw_force
            | Rule::kw_excite
            | Rule::kw_levels
            | Rule::kw_filter
            | Rule::kw_corners
            | Rule::kw_order
            | Rule::kw_driven
            | Rule::kw_by
    )
}

/// The children of a pair without the keyword tokens.
fn parts(p: Pair<Rule>) -> Vec<Pair<Rule>> {
    p.into_inner()
        .filter(|c| !is_keyword(c.as_rule()))
        .collect()
}

fn build_model(p: Pair<Rule>, sink: &mut ErrorSink) -> AstModel {
    let span = span_of(&p);
    let mut it = parts(p).into_iter();
    let name = ident(it.next().expect("grammar: model has a name"));
    let items = it.filter_map(|item| build_item(item, sink)).collect();
    AstModel { name, items, span }
}

/// One statement of a model, by its grammar rule.
///
/// Longer than most functions here: one match arm per statement rule of `dyn.pest`, each a
/// few lines; split apart, the arms would only move into functions called once.
fn build_item(p: Pair<Rule>, sink: &mut ErrorSink) -> Option<AstItem> {
    let span = span_of(&p);
    let rule = p.as_rule();
    let mut it = parts(p).into_iter();
    let item = match rule {
        Rule::body => AstItem::Body {
            name: ident(it.next()?),
            mass: it.next().map(|v| value(v, sink)),
            span,
        },
        Rule::input => AstItem::Input {
            name: ident(it.next()?),
            body: ident(it.next()?),
            span,
        },
        Rule::reference => AstItem::Reference {
            name: ident(it.next()?),
            span,
        },
        Rule::control => AstItem::Control {
            input: ident(it.next()?),
            law: build_expr(it.next()?, sink),
            span,
        },
        Rule::measure => AstItem::Measure {
            signals: it.map(sigref).collect(),
            span,
        },
        Rule::param => AstItem::Param {
            name: ident(it.next()?),
            value: it.next().map(|v| value(v, sink)),
            span,
        },
        Rule::spring | Rule::damper | Rule::force => {
            let name = ident(it.next()?);
            let mut nodes = it.next()?.into_inner();
            let a = ident(nodes.next()?);
            let b = ident(nodes.next()?);
            let (kind, value, expr) = match rule {
                Rule::spring => (
                    AstElementKind::Spring,
                    it.next().map(|v| value(v, sink)),
                    None,
                ),
                Rule::damper => (
                    AstElementKind::Damper,
                    it.next().map(|v| value(v, sink)),
                    None,
                ),
                _ => (
                    AstElementKind::Force,
                    None,
                    Some(build_expr(it.next()?, sink)),
                ),
            };
            AstItem::Element {
                kind,
                name,
                nodes: (a, b),
                value,
                expr,
                span,
            }
        }
        Rule::excite => {
            let input = ident(it.next()?);
            let form_pair = it.next()?;
            let form_span = span_of(&form_pair);
            let mut f = form_pair.into_inner();
            let fname = ident(f.next()?);
            let args = f
                .map(|a| {
                    let mut a = a.into_inner();
                    let name = ident(a.next().expect("grammar: named_arg has a name"));
                    let value = number(a.next().expect("grammar: named_arg has a value"), sink);
                    AstNamedArg { name, value }
                })
                .collect();
            let (levels, levels_span) = num_list(it.next()?, sink);
            AstItem::Excite {
                input,
                form: AstForm {
                    name: fname,
                    args,
                    span: form_span,
                },
                levels,
                levels_span,
                span,
            }
        }
        Rule::filter => {
            let (corners, corners_span) = num_list(it.next()?, sink);
            let mut order = None;
            let mut driven_by = Vec::new();
            for c in it {
                match c.as_rule() {
                    Rule::integer => {
                        let s = span_of(&c);
                        match c.as_str().parse::<u32>() {
                            Ok(n) => order = Some((n, s)),
                            Err(_) => sink.push(CompileError::invalid_value(
                                sink,
                                format!("filter order `{}` is too large", c.as_str()),
                                s,
                                "use an order between 1 and 8".into(),
                            )),
                        }
                    }
                    Rule::sigref => driven_by.push(sigref(c)),
                    _ => {}
                }
            }
            AstItem::Filter {
                corners,
                corners_span,
                order,
                driven_by,
                span,
            }
        }
        _ => return None,
    };
    Some(item)
}

fn build_expr(p: Pair<Rule>, sink: &mut ErrorSink) -> AstExpr {
    let span = span_of(&p);
    let mut budget = MAX_EXPR_NODES;
    let e = build_expr_in(p, sink, &mut budget);
    if budget == 0 {
        sink.push(CompileError::invalid_value(
            sink,
            format!("force expression has more than {MAX_EXPR_NODES} operations"),
            span,
            "split the element into several `force` elements".into(),
        ));
        return AstExpr {
            kind: AstExprKind::Num(0.0),
            span,
        };
    }
    e
}

/// An expression, by its grammar rule (`expr`, `term`, `unary`, `power`, `call`, …),
/// within the node `budget` of [`MAX_EXPR_NODES`].
///
/// Longer than most functions here: one match arm per expression rule, as in
/// [`build_item`].
fn build_expr_in(p: Pair<Rule>, sink: &mut ErrorSink, budget: &mut usize) -> AstExpr {
    let span = span_of(&p);
    if *budget == 0 {
        return AstExpr {
            kind: AstExprKind::Num(0.0),
            span,
        };
    }
    *budget -= 1;
    match p.as_rule() {
        Rule::expr | Rule::term => {
            let mut it = p.into_inner();
            let mut acc = build_expr_in(it.next().expect("grammar: operand"), sink, budget);
            while let Some(op) = it.next() {
                if *budget == 0 {
                    break;
                }
                let rhs = build_expr_in(
                    it.next().expect("grammar: operand after operator"),
                    sink,
                    budget,
                );
                let op = match op.as_str() {
                    "+" => AstBinOp::Add,
                    "-" => AstBinOp::Sub,
                    "*" => AstBinOp::Mul,
                    _ => AstBinOp::Div,
                };
                let s = Span::new(acc.span.start, rhs.span.end);
                acc = AstExpr {
                    kind: AstExprKind::Binary(op, Box::new(acc), Box::new(rhs)),
                    span: s,
                };
            }
            acc
        }
        Rule::unary | Rule::exponent => {
            let mut negs = 0usize;
            let mut inner = None;
            for c in p.into_inner() {
                if c.as_rule() == Rule::neg {
                    negs += 1;
                } else {
                    inner = Some(build_expr_in(c, sink, budget));
                }
            }
            let inner = inner.expect("grammar: unary has an operand");
            // An even number of minus signs cancels; keeping one node bounds the depth.
            if negs % 2 == 1 {
                AstExpr {
                    kind: AstExprKind::Neg(Box::new(inner)),
                    span,
                }
            } else {
                inner
            }
        }
        Rule::power => {
            let mut it = p.into_inner();
            let base = build_expr_in(it.next().expect("grammar: power has a base"), sink, budget);
            match it.next() {
                Some(e) => AstExpr {
                    kind: AstExprKind::Pow(
                        Box::new(base),
                        Box::new(build_expr_in(e, sink, budget)),
                    ),
                    span,
                },
                None => base,
            }
        }
        Rule::param_decl => {
            let mut it = p.into_inner();
            let name = ident(it.next().expect("grammar: param_decl has a name"));
            let v = value(it.next().expect("grammar: param_decl has a value"), sink);
            AstExpr {
                kind: AstExprKind::ParamDecl(name, v),
                span,
            }
        }
        Rule::call => {
            let mut it = p.into_inner();
            let name = ident(it.next().expect("grammar: call has a name"));
            let args = it.map(|a| build_expr_in(a, sink, budget)).collect();
            AstExpr {
                kind: AstExprKind::Call(name, args),
                span,
            }
        }
        Rule::number => AstExpr {
            kind: AstExprKind::Num(number(p, sink).value),
            span,
        },
        Rule::sigref => AstExpr {
            kind: AstExprKind::Ref(sigref(p)),
            span,
        },
        _ => AstExpr {
            kind: AstExprKind::Num(0.0),
            span,
        },
    }
}
