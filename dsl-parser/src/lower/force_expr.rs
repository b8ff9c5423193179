//! The expression inside a force term (`expr` rule and below): arithmetic, integer powers,
//! the functions, and references to `s`, `v`, body signals, inputs and parameters, lowered
//! to an `LExpr` with its constants folded.

use super::expr::LExpr;
use super::names::{closest, FUNCTIONS};
use super::{fmt_value, Decl, Lowerer};
use crate::ast::*;
use crate::error::ErrorKind;
use crate::ir::*;

/// The element's relative displacement `s` and velocity `v`, as the names `s` and `v`
/// stand for them inside its force.
pub(super) struct Ctx<'a> {
    pub(super) s: &'a LExpr,
    pub(super) v: &'a LExpr,
    /// Lowering a control law: parameters are their known values, references are signals,
    /// and `s`, `v` and inputs do not exist.
    pub(super) law: bool,
}

impl Lowerer<'_> {
    /// Lower a parameter-free expression (the `expr` rule and below). The occurrence at
    /// `coef` (the term's parameter) stands for 1. Returns `None` after an error.
    pub(super) fn lower_expr(
        &mut self,
        e: &AstExpr,
        ctx: &Ctx,
        coef: Option<Span>,
    ) -> Option<LExpr> {
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
            AstExprKind::ParamDecl(name, value) if ctx.law => match value {
                AstValue::Known(n) => Some(LExpr::Const(n.value)),
                AstValue::Nominal(_) => {
                    self.unknown_gain(&name.name, e.span);
                    None
                }
            },
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
                        Some(c) => format!("did you mean `{c}`? The functions are abs, sign, tanh, sqrt, exp, sin, cos, deadzone(x, gap) and saturate(x, limit)"),
                        None => "the functions are abs, sign, tanh, sqrt, exp, sin, cos, deadzone(x, gap) and saturate(x, limit)".into(),
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
                        let (c, shape) = match self.shape_arg(&args[1], ctx) {
                            Some(found) => found?,
                            None => (self.const_arg(&args[1], ctx, what)?, None),
                        };
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
                            ("deadzone", None) => LExpr::Deadzone(Box::new(x), c, shape),
                            (_, Some(a)) => LExpr::Const(saturate(a, c)),
                            (_, None) => LExpr::Saturate(Box::new(x), c, shape),
                        }
                    }
                    name => {
                        let op = match name {
                            "abs" => UnaryOp::Abs,
                            "sign" => UnaryOp::Sign,
                            "tanh" => UnaryOp::Tanh,
                            "sqrt" => UnaryOp::Sqrt,
                            "sin" => UnaryOp::Sin,
                            "cos" => UnaryOp::Cos,
                            _ => UnaryOp::Exp,
                        };
                        LExpr::unary(op, x?)
                    }
                };
                folded(self, x)
            }
        }
    }

    /// A gap or limit written as a parameter (`deadzone(s, g ~ 0.05)`, `deadzone(s, g)`):
    /// `None` when it is not a plain parameter name; else its value and, for an unknown
    /// parameter, the index of its shape parameter (created at first use, valued at its
    /// nominal). An unknown parameter without a nominal value is an error (`Some(None)`).
    fn shape_arg(&mut self, e: &AstExpr, ctx: &Ctx) -> Option<Option<(f64, Option<usize>)>> {
        if ctx.law {
            return None;
        }
        let name = match &e.kind {
            AstExprKind::ParamDecl(n, _) => &n.name,
            AstExprKind::Ref(r) if r.field.is_none() => &r.base.name,
            _ => return None,
        };
        let p = self.param_of(name)?;
        if let Some(&k) = self.shape_of.get(&p) {
            return Some(Some((self.shapes[k].1, Some(k))));
        }
        match self.pending[p].value {
            Some(AstValue::Known(n)) => Some(Some((n.value, None))),
            Some(AstValue::Nominal(n)) => {
                self.shapes.push((name.clone(), n.value, Vec::new()));
                let k = self.shapes.len() - 1;
                self.shape_of.insert(p, k);
                Some(Some((n.value, Some(k))))
            }
            None => {
                self.err(
                    ErrorKind::NonConstantArgument,
                    format!("the shape parameter `{name}` has no starting value"),
                    e.span,
                    "no nominal value",
                    format!("an unknown gap or limit is profiled from a starting value: write `{name} ~ 0.01`"),
                );
                Some(None)
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
                    "a" => {
                        self.err(
                            ErrorKind::InvalidSignal,
                            format!("a force cannot read the acceleration `{name}.a`"),
                            r.span,
                            "acceleration",
                            format!("an acceleration is measured (`measure {name}.a`), not a force law's argument: inertia is the body's mass; write the force in `{name}.x` or `{name}.v`"),
                        );
                        None
                    }
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
        if ctx.law {
            return self.lower_law_ref(r);
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
            Some((Decl::Reference(_), _)) => {
                self.err(
                    ErrorKind::InvalidControl,
                    format!("a force cannot read the reference `{name}`"),
                    r.span,
                    "a reference",
                    "a reference is a set point that only control laws read (`control u = kp * (r - m.x)`); a force acts through the bodies' motion".into(),
                );
                None
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
}

impl Lowerer<'_> {
    /// A plain name inside a control law (body signals were resolved by the caller).
    fn lower_law_ref(&mut self, r: &AstSigRef) -> Option<LExpr> {
        let name = r.base.name.as_str();
        let refuse = |l: &mut Self, message: String, label: &str, help: &str| {
            l.err(
                ErrorKind::InvalidControl,
                message,
                r.span,
                label,
                help.into(),
            );
            None
        };
        match self.names.get(name).copied() {
            Some((Decl::Reference(k), _)) => Some(LExpr::Sig(SignalId(
                (2 * self.bodies.len() + self.inputs.len()) as u32 + k.0,
            ))),
            Some((Decl::Param(p), _)) | Some((Decl::Element(Some(p)), _)) => {
                self.pending[p].mentioned = true;
                match self.pending[p].value {
                    Some(AstValue::Known(n)) => Some(LExpr::Const(n.value)),
                    _ => {
                        self.unknown_gain(name, r.span);
                        None
                    }
                }
            }
            Some((Decl::Input(_), _)) => refuse(
                self,
                format!("a control law cannot read the input `{name}`"),
                "an input",
                "a law computes its input from body signals (`m.x`, `m.v`), references and known numbers",
            ),
            Some((Decl::Body(_), _)) => refuse(
                self,
                format!("body `{name}` is not a value"),
                "a body",
                "write its position `NAME.x` or velocity `NAME.v`",
            ),
            Some((Decl::Element(None), _)) => refuse(
                self,
                format!("element `{name}` is not a value"),
                "an element",
                "a law reads body signals (`m.x`, `m.v`), references and known numbers",
            ),
            None if matches!(name, "s" | "v" | "t") => refuse(
                self,
                format!("`{name}` has no meaning in a control law"),
                "not available",
                "`s` and `v` belong to force elements; a law reads body signals (`m.x`, `m.v`), references and known numbers",
            ),
            None => {
                self.undefined(&r.base, r.span, "a law reads body signals, references and known parameters");
                None
            }
        }
    }

    fn unknown_gain(&mut self, name: &str, span: Span) {
        self.err(
            ErrorKind::InvalidControl,
            format!("the control law uses `{name}`, which is not a known value"),
            span,
            "unknown",
            format!("a controller's gains are known settings: declare `param {name} = VALUE`"),
        );
    }
}
