//! Edits of a compiled model, made on the IR.
//!
//! A back end that changes a model (the diagnosis adds a force element and writes identified
//! values as nominals) does it here, never on the source text: the edited IR is the model,
//! and [`crate::print::to_source`] writes it as `.dyn` text when a file is wanted.
//!
//! The equations of motion are a function of the bodies, elements and inputs
//! ([`assemble_equations`]); lowering and every edit build them with that one function, so
//! an edited IR has the equations that compiling the printed model gives.

use crate::ir::*;
use std::fmt;

/// Why an edit was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum EditError {
    /// The name is already a body, input, parameter or element of the model.
    NameTaken(String),
    /// No body (and not `ground`) of that name.
    UnknownNode(String),
    /// No parameter of that name.
    UnknownParam(String),
    /// The parameter is known (its value is part of the model, not a nominal).
    KnownParam(String),
    /// Both ends of an element are the same node.
    SameNode(String),
    /// An element without terms.
    NoTerms(String),
    /// A value that is not a finite number.
    NotFinite(String),
}

impl fmt::Display for EditError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EditError::NameTaken(n) => write!(f, "the name `{n}` is already used in the model"),
            EditError::UnknownNode(n) => write!(f, "no body `{n}` in the model"),
            EditError::UnknownParam(n) => write!(f, "no parameter `{n}` in the model"),
            EditError::KnownParam(n) => {
                write!(
                    f,
                    "parameter `{n}` is known; only unknowns have a nominal value"
                )
            }
            EditError::SameNode(n) => write!(f, "element `{n}` would connect a node to itself"),
            EditError::NoTerms(n) => write!(f, "force element `{n}` needs at least one term"),
            EditError::NotFinite(n) => write!(f, "the value for `{n}` is not a finite number"),
        }
    }
}

impl std::error::Error for EditError {}

/// One term `param · basis(s, v)` of a new force element.
pub struct NewTerm<'a> {
    /// Name of the new unknown parameter (must be free in the model).
    pub param: &'a str,
    /// Its nominal value (the value a simulation of the edited model uses).
    pub nominal: Option<f64>,
    /// Builds the basis from the element's relative displacement `s` and velocity `v`.
    pub basis: &'a dyn Fn(&mut ExprArena, ExprId, ExprId) -> ExprId,
}

impl ModelIr {
    /// Whether `name` is taken by a body, input, parameter or element.
    pub fn name_taken(&self, name: &str) -> bool {
        name == "ground"
            || self.params.iter().any(|p| p.name == name)
            || self.elements.iter().any(|e| e.name == name)
            || self.bodies.iter().any(|b| b.name == name)
            || self.inputs.iter().any(|i| i.name == name)
            || self.shapes.iter().any(|s| s.name == name)
    }

    /// `stem` if it is free, else the first free `stem_2`, `stem_3`, …
    pub fn fresh_name(&self, stem: &str) -> String {
        if !self.name_taken(stem) {
            return stem.to_string();
        }
        let mut k = 2usize;
        loop {
            let n = format!("{stem}_{k}");
            if !self.name_taken(&n) {
                return n;
            }
            k += 1;
        }
    }

    /// The node called `name` (`ground` or a body).
    pub fn node(&self, name: &str) -> Option<Node> {
        if name == "ground" {
            return Some(Node::Ground);
        }
        self.bodies
            .iter()
            .position(|b| b.name == name)
            .map(|i| Node::Body(BodyId(i as u32)))
    }

    /// The name of a node, as the language writes it.
    pub fn node_name(&self, n: Node) -> &str {
        match n {
            Node::Ground => "ground",
            Node::Body(b) => &self.bodies[b.index()].name,
        }
    }

    /// Set the nominal value of the unknown parameter `name`.
    pub fn set_nominal(&mut self, name: &str, value: f64) -> Result<(), EditError> {
        if !value.is_finite() {
            return Err(EditError::NotFinite(name.into()));
        }
        let p = self
            .params
            .iter_mut()
            .find(|p| p.name == name)
            .ok_or_else(|| EditError::UnknownParam(name.into()))?;
        match &mut p.kind {
            ParamKind::Unknown { nominal } => {
                *nominal = Some(value);
                Ok(())
            }
            ParamKind::Known(_) => Err(EditError::KnownParam(name.into())),
        }
    }

    /// Add a force element `name` between `a` and `b` (node names) with the given terms, each
    /// with a new unknown parameter. The element acts like one written in the model as
    /// `force name (a, b) = p1 ~ n1 * basis1 + …`: it pushes `a` by `+f` and `b` by `−f`.
    /// On error the model is unchanged.
    pub fn add_force(
        &mut self,
        name: &str,
        (a, b): (&str, &str),
        terms: &[NewTerm<'_>],
    ) -> Result<ElementId, EditError> {
        if self.name_taken(name) {
            return Err(EditError::NameTaken(name.into()));
        }
        if terms.is_empty() {
            return Err(EditError::NoTerms(name.into()));
        }
        for (k, t) in terms.iter().enumerate() {
            if self.name_taken(t.param) || terms[..k].iter().any(|u| u.param == t.param) {
                return Err(EditError::NameTaken(t.param.into()));
            }
            if t.nominal.is_some_and(|v| !v.is_finite()) {
                return Err(EditError::NotFinite(t.param.into()));
            }
        }
        let na = self
            .node(a)
            .ok_or_else(|| EditError::UnknownNode(a.into()))?;
        let nb = self
            .node(b)
            .ok_or_else(|| EditError::UnknownNode(b.into()))?;
        if na == nb {
            return Err(EditError::SameNode(name.into()));
        }

        let mut arena = ExprArena::from_nodes(std::mem::take(&mut self.exprs));
        let rel = |arena: &mut ExprArena, body_signal: fn(&ModelIr, BodyId) -> SignalId| {
            let sig = |arena: &mut ExprArena, n: Node| match n {
                Node::Ground => None,
                Node::Body(id) => Some(arena.signal(body_signal(self, id))),
            };
            match (sig(arena, na), sig(arena, nb)) {
                (None, Some(xb)) => xb,
                (Some(xa), None) => arena.unary(UnaryOp::Neg, xa),
                (Some(xa), Some(xb)) => arena.binary(BinaryOp::Sub, xb, xa),
                (None, None) => arena.constant(0.0),
            }
        };
        let s = rel(&mut arena, ModelIr::position);
        let v = rel(&mut arena, ModelIr::velocity);
        let mut force_terms = Vec::with_capacity(terms.len());
        for t in terms {
            let basis = (t.basis)(&mut arena, s, v);
            let pid = ParamId(self.params.len() as u32);
            self.params.push(ParamIr {
                name: t.param.to_string(),
                kind: ParamKind::Unknown { nominal: t.nominal },
            });
            self.spans.params.push(self.spans.model);
            force_terms.push(ForceTerm {
                coef: Coef::param(pid),
                basis,
            });
        }
        self.exprs = arena.into_nodes();
        let id = ElementId(self.elements.len() as u32);
        self.elements.push(ElementIr {
            name: name.to_string(),
            kind: ElementKind::Force,
            nodes: (na, nb),
            s,
            v,
            terms: force_terms,
        });
        self.spans.elements.push(self.spans.model);
        self.equations = assemble_equations(self);
        Ok(id)
    }
}

/// The equations of motion of a model from its bodies, elements and inputs (the rules are
/// in the [`crate::ir`] documentation): the inertia term of each body, each element's terms
/// on its two ends (a term in the element's own relative velocity becomes velocity
/// derivative terms, which a back end can move onto its filter), and each input force.
pub fn assemble_equations(ir: &ModelIr) -> Vec<EquationIr> {
    let mut eqs: Vec<EquationIr> = (0..ir.bodies.len())
        .map(|i| {
            let body = BodyId(i as u32);
            EquationIr {
                body,
                terms: vec![TermIr {
                    coef: ir.bodies[i].mass,
                    basis: Basis::Deriv { body, order: 2 },
                    origin: TermOrigin::Inertia(body),
                }],
            }
        })
        .collect();
    for (ei, e) in ir.elements.iter().enumerate() {
        let origin = TermOrigin::Element(ElementId(ei as u32));
        let ends = [(e.nodes.1, 1.0), (e.nodes.0, -1.0)];
        for t in &e.terms {
            for &(node, sign) in &ends {
                let Node::Body(eq) = node else { continue };
                let terms = &mut eqs[eq.index()].terms;
                if t.basis == e.v {
                    // f = coef (v_b − v_a): the derivative can move onto the filter.
                    for &(end, s2) in &ends {
                        if let Node::Body(b) = end {
                            terms.push(TermIr {
                                coef: t.coef.scaled(sign * s2),
                                basis: Basis::Deriv { body: b, order: 1 },
                                origin,
                            });
                        }
                    }
                } else {
                    terms.push(TermIr {
                        coef: t.coef.scaled(sign),
                        basis: Basis::Expr(t.basis),
                        origin,
                    });
                }
            }
        }
    }
    for (j, i) in ir.inputs.iter().enumerate() {
        let input = InputId(j as u32);
        let signal = ir.input_signal(input);
        let Some(expr) = ir.exprs.iter().position(|n| *n == ExprNode::Signal(signal)) else {
            continue;
        };
        if let Some(eq) = eqs.get_mut(i.body.index()) {
            eq.terms.push(TermIr {
                coef: Coef::constant(-1.0),
                basis: Basis::Expr(ExprId(expr as u32)),
                origin: TermOrigin::Input(input),
            });
        }
    }
    eqs
}
