//! What a model answers about itself: the signal of a body or input, the parameters and
//! their kinds, the terms of an equation, and the check of the invariants listed in the
//! parent module.

use super::eval::eval_node;
use super::{
    Basis, BinaryOp, BodyId, Coef, ControlIr, ElementGroup, ElementId, ExprId, ExprNode, InputId,
    ModelIr, Node, ParamId, ParamKind, ReferenceId, ShapeIr, SignalId, SignalIr, SignalKind,
    TermOrigin, UnaryOp,
};

impl ModelIr {
    pub fn position(&self, b: BodyId) -> SignalId {
        SignalId(2 * b.0)
    }
    pub fn velocity(&self, b: BodyId) -> SignalId {
        SignalId(2 * b.0 + 1)
    }
    pub fn input_signal(&self, i: InputId) -> SignalId {
        SignalId(2 * self.bodies.len() as u32 + i.0)
    }
    pub fn reference_signal(&self, r: ReferenceId) -> SignalId {
        SignalId((2 * self.bodies.len() + self.inputs.len()) as u32 + r.0)
    }
    /// The measured acceleration signal of body `b`, if the body has an accelerometer.
    pub fn acceleration(&self, b: BodyId) -> Option<SignalId> {
        let first = 2 * self.bodies.len() + self.inputs.len() + self.references.len();
        (first..self.signals.len())
            .find(|&k| self.signals[k].kind == SignalKind::Acceleration(b))
            .map(|k| SignalId(k as u32))
    }
    /// Whether body `b` is measured by its acceleration alone (neither its position nor its
    /// velocity is a column of the data): its linear terms are formed from the acceleration
    /// by filters with zeros at the origin, and nonlinear terms in its motion are refused.
    pub fn acceleration_only(&self, b: BodyId) -> bool {
        self.acceleration(b)
            .is_some_and(|a| self.signal(a).measured)
            && !self.signal(self.position(b)).measured
            && !self.signal(self.velocity(b)).measured
    }
    /// The control law of input `i`, if it is computed in closed loop.
    pub fn control_of(&self, i: InputId) -> Option<&ControlIr> {
        self.controls.iter().find(|c| c.input == i)
    }
    pub fn signal(&self, s: SignalId) -> &SignalIr {
        &self.signals[s.index()]
    }
    pub fn expr(&self, e: ExprId) -> ExprNode {
        self.exprs[e.index()]
    }
    pub fn param_id(&self, name: &str) -> Option<ParamId> {
        self.params
            .iter()
            .position(|p| p.name == name)
            .map(|i| ParamId(i as u32))
    }
    pub fn signal_id(&self, name: &str) -> Option<SignalId> {
        self.signals
            .iter()
            .position(|s| s.name == name)
            .map(|i| SignalId(i as u32))
    }
    /// Unknown parameters in declaration order: the columns of the least-squares problem.
    pub fn unknowns(&self) -> Vec<ParamId> {
        (0..self.params.len() as u32)
            .map(ParamId)
            .filter(|p| self.params[p.index()].is_unknown())
            .collect()
    }
    /// A copy whose unknown parameters have `values` (in [`Self::unknowns`] order) as their
    /// nominal values: the model a simulation with those values runs.
    ///
    /// # Panics
    /// If `values` does not hold one value per unknown parameter.
    pub fn with_nominals(&self, values: &[f64]) -> ModelIr {
        let unknowns = self.unknowns();
        assert_eq!(
            values.len(),
            unknowns.len(),
            "model `{}` has {} unknown parameters",
            self.name,
            unknowns.len()
        );
        let mut ir = self.clone();
        for (p, &v) in unknowns.iter().zip(values) {
            ir.params[p.index()].kind = ParamKind::Unknown { nominal: Some(v) };
        }
        ir
    }
    /// A copy whose shape parameters take `values` (one per shape, in order) at every site,
    /// and as their nominal values.
    ///
    /// # Panics
    /// If `values` does not hold one value per shape parameter.
    pub fn with_shapes(&self, values: &[f64]) -> ModelIr {
        assert_eq!(
            values.len(),
            self.shapes.len(),
            "one value per shape parameter"
        );
        let mut ir = self.clone();
        for (shape, &v) in ir.shapes.iter_mut().zip(values) {
            shape.nominal = v;
            for site in &shape.sites {
                let node = &mut ir.exprs[site.index()];
                *node = match *node {
                    ExprNode::Deadzone(a, _) => ExprNode::Deadzone(a, v.to_bits()),
                    ExprNode::Saturate(a, _) => ExprNode::Saturate(a, v.to_bits()),
                    other => other,
                };
            }
        }
        ir
    }
    /// The shape parameter whose value node `e` holds, if any.
    pub fn shape_at(&self, e: ExprId) -> Option<&ShapeIr> {
        self.shapes.iter().find(|s| s.sites.contains(&e))
    }
    /// The elements grouped by the pair of nodes they connect (in either order): one
    /// group per pair, in order of first appearance, with the nodes of its first element.
    /// Springs, dampers and forces between the same two nodes act as one connection.
    pub fn element_groups(&self) -> Vec<ElementGroup> {
        let key = |n: Node| match n {
            Node::Ground => 0usize,
            Node::Body(b) => b.index() + 1,
        };
        let mut out: Vec<((usize, usize), ElementGroup)> = Vec::new();
        for (i, e) in self.elements.iter().enumerate() {
            let (a, b) = (key(e.nodes.0), key(e.nodes.1));
            let k = (a.min(b), a.max(b));
            let id = ElementId(i as u32);
            match out.iter_mut().find(|(x, _)| *x == k) {
                Some((_, g)) => g.members.push(id),
                None => out.push((
                    k,
                    ElementGroup {
                        nodes: e.nodes,
                        members: vec![id],
                    },
                )),
            }
        }
        out.into_iter().map(|(_, g)| g).collect()
    }
    pub fn measured_signals(&self) -> Vec<SignalId> {
        (0..self.signals.len() as u32)
            .map(SignalId)
            .filter(|s| self.signals[s.index()].measured)
            .collect()
    }
    /// The static basis expressions of all equations, deduplicated, in first-use order.
    /// This is the list of columns a compiled evaluator computes per sample; the macro's
    /// generated code and the interpreter both compute exactly this list, in this order.
    pub fn eval_roots(&self) -> Vec<ExprId> {
        let mut seen = std::collections::HashSet::new();
        let mut out = Vec::new();
        for eq in &self.equations {
            for t in &eq.terms {
                if let Basis::Expr(e) = t.basis {
                    if seen.insert(e) {
                        out.push(e);
                    }
                }
            }
        }
        out
    }
    /// Whether `e` is a constant: the basis of a constant force is the number 1 (lowering
    /// makes no other constant basis).
    pub fn is_constant(&self, e: ExprId) -> bool {
        matches!(self.expr(e), ExprNode::Const(_))
    }
    /// Which nodes the `roots` depend on (the roots included): `needed[i]` for node `i`,
    /// up to the largest root. Evaluators compute exactly these nodes.
    pub fn needed_nodes(&self, roots: &[ExprId]) -> Vec<bool> {
        let n = roots.iter().map(|r| r.index() + 1).max().unwrap_or(0);
        let mut needed = vec![false; n];
        for r in roots {
            needed[r.index()] = true;
        }
        // Topological order: a node's children have smaller ids.
        for i in (0..n).rev() {
            if needed[i] {
                for c in self.exprs[i].children() {
                    needed[c.index()] = true;
                }
            }
        }
        needed
    }

    /// `e` as a linear form `Σ aₖ sₖ` in signals (no constant offset), if it is one.
    pub fn linear_form(&self, e: ExprId) -> Option<Vec<(SignalId, f64)>> {
        let scale =
            |v: Vec<(SignalId, f64)>, f: f64| v.into_iter().map(|(s, a)| (s, a * f)).collect();
        match self.exprs[e.index()] {
            ExprNode::Signal(s) => Some(vec![(s, 1.0)]),
            ExprNode::Unary(UnaryOp::Neg, a) => Some(scale(self.linear_form(a)?, -1.0)),
            ExprNode::Binary(op, a, b) => {
                let (na, nb) = (self.exprs[a.index()], self.exprs[b.index()]);
                match op {
                    BinaryOp::Add | BinaryOp::Sub => {
                        let mut out = self.linear_form(a)?;
                        let sign = if op == BinaryOp::Add { 1.0 } else { -1.0 };
                        for (s, c) in self.linear_form(b)? {
                            match out.iter_mut().find(|(t, _)| *t == s) {
                                Some(e) => e.1 += sign * c,
                                None => out.push((s, sign * c)),
                            }
                        }
                        out.retain(|(_, c)| *c != 0.0);
                        Some(out)
                    }
                    BinaryOp::Mul => match (na, nb) {
                        (ExprNode::Const(c), _) => {
                            Some(scale(self.linear_form(b)?, f64::from_bits(c)))
                        }
                        (_, ExprNode::Const(c)) => {
                            Some(scale(self.linear_form(a)?, f64::from_bits(c)))
                        }
                        _ => None,
                    },
                    BinaryOp::Div => match nb {
                        ExprNode::Const(c) if f64::from_bits(c) != 0.0 => {
                            Some(scale(self.linear_form(a)?, 1.0 / f64::from_bits(c)))
                        }
                        _ => None,
                    },
                }
            }
            _ => None,
        }
    }

    /// The signals an expression depends on.
    pub fn expr_signals(&self, e: ExprId) -> Vec<SignalId> {
        let needed = self.needed_nodes(&[e]);
        let mut out: Vec<SignalId> = (0..needed.len())
            .filter(|&i| needed[i])
            .filter_map(|i| match self.exprs[i] {
                ExprNode::Signal(s) => Some(s),
                _ => None,
            })
            .collect();
        out.sort();
        out.dedup();
        out
    }
    /// Evaluate an expression at one point, given every signal's value (index = SignalId).
    /// For printing, tests and the statistical-linearisation templates; hot loops use a
    /// compiled evaluator instead.
    pub fn eval_scalar(&self, e: ExprId, signals: &[f64]) -> f64 {
        let mut vals = vec![0.0; e.index() + 1];
        for i in 0..=e.index() {
            vals[i] = eval_node(self.exprs[i], &vals, signals);
        }
        vals[e.index()]
    }

    /// Check the structural invariants listed in the module documentation.
    pub fn check_invariants(&self) -> Result<(), String> {
        for (i, n) in self.exprs.iter().enumerate() {
            for c in n.children() {
                if c.index() >= i {
                    return Err(format!("expr {i} refers forward to {}", c.index()));
                }
            }
        }
        let nb = self.bodies.len();
        let first_acc = 2 * nb + self.inputs.len() + self.references.len();
        if self.signals.len() < first_acc || self.signals.len() > first_acc + nb {
            return Err("signal table does not match bodies, inputs and references".into());
        }
        for (i, b) in self.bodies.iter().enumerate() {
            let id = BodyId(i as u32);
            if self.signals[2 * i].kind != SignalKind::Position(id)
                || self.signals[2 * i + 1].kind != SignalKind::Velocity(id)
            {
                return Err(format!("signals of body {} are out of place", b.name));
            }
        }
        if self.equations.len() != nb {
            return Err("one equation per body expected".into());
        }
        self.check_references()
    }

    /// Every index in the model names something that exists, every number is finite and
    /// every known mass is positive: what a model read from JSON must satisfy before any
    /// back end indexes with it (the compiler guarantees it for models it lowered).
    pub fn check_references(&self) -> Result<(), String> {
        let (np, ns, ne, nb) = (
            self.params.len(),
            self.signals.len(),
            self.exprs.len(),
            self.bodies.len(),
        );
        let coef = |c: &Coef, at: &str| -> Result<(), String> {
            if !c.scale.is_finite() {
                return Err(format!("{at}: coefficient {} is not finite", c.scale));
            }
            match c.param {
                Some(p) if p.index() >= np => {
                    Err(format!("{at}: parameter #{} does not exist", p.index()))
                }
                _ => Ok(()),
            }
        };
        let expr = |e: ExprId, at: &str| -> Result<(), String> {
            if e.index() >= ne {
                return Err(format!("{at}: expression #{} does not exist", e.index()));
            }
            Ok(())
        };
        let body = |b: BodyId, at: &str| -> Result<(), String> {
            if b.index() >= nb {
                return Err(format!("{at}: body #{} does not exist", b.index()));
            }
            Ok(())
        };
        let node = |n: Node, at: &str| match n {
            Node::Ground => Ok(()),
            Node::Body(b) => body(b, at),
        };
        for p in &self.params {
            let v = match p.kind {
                ParamKind::Known(v) => Some(v),
                ParamKind::Unknown { nominal } => nominal,
            };
            if v.is_some_and(|v| !v.is_finite()) {
                return Err(format!(
                    "parameter `{}` has a value that is not finite",
                    p.name
                ));
            }
        }
        for b in &self.bodies {
            let at = format!("body `{}`", b.name);
            coef(&b.mass, &at)?;
            let known = match b.mass.param {
                None => Some(b.mass.scale),
                Some(p) => match self.params[p.index()].kind {
                    ParamKind::Known(v) => Some(b.mass.scale * v),
                    ParamKind::Unknown { .. } => None,
                },
            };
            if known.is_some_and(|m| m <= 0.0) {
                return Err(format!("{at}: the known mass must be positive"));
            }
        }
        for (j, i) in self.inputs.iter().enumerate() {
            body(i.body, &format!("input #{j} `{}`", i.name))?;
        }
        for (k, n) in self.exprs.iter().enumerate() {
            let at = format!("expression #{k}");
            match *n {
                ExprNode::Signal(sig) if sig.index() >= ns => {
                    return Err(format!("{at}: signal #{} does not exist", sig.index()))
                }
                ExprNode::Const(b) | ExprNode::Deadzone(_, b) | ExprNode::Saturate(_, b)
                    if !f64::from_bits(b).is_finite() =>
                {
                    return Err(format!("{at}: a constant is not finite"))
                }
                _ => {}
            }
        }
        for e in &self.elements {
            let at = format!("element `{}`", e.name);
            node(e.nodes.0, &at)?;
            node(e.nodes.1, &at)?;
            expr(e.s, &at)?;
            expr(e.v, &at)?;
            for t in &e.terms {
                coef(&t.coef, &at)?;
                expr(t.basis, &at)?;
            }
        }
        for (k, eq) in self.equations.iter().enumerate() {
            let at = format!("equation #{k}");
            body(eq.body, &at)?;
            for t in &eq.terms {
                coef(&t.coef, &at)?;
                match t.basis {
                    Basis::Expr(e) => expr(e, &at)?,
                    Basis::Deriv { body: b, order } => {
                        body(b, &at)?;
                        if !(1..=2).contains(&order) {
                            return Err(format!("{at}: derivative of order {order}"));
                        }
                    }
                }
                let origin_ok = match t.origin {
                    TermOrigin::Inertia(b) => b.index() < nb,
                    TermOrigin::Element(el) => el.index() < self.elements.len(),
                    TermOrigin::Input(i) => i.index() < self.inputs.len(),
                };
                if !origin_ok {
                    return Err(format!("{at}: a term's origin does not exist"));
                }
            }
        }
        let nr = self.references.len();
        for c in &self.controls {
            if c.input.index() >= self.inputs.len() {
                return Err(format!(
                    "control law of input #{} that does not exist",
                    c.input.index()
                ));
            }
            expr(c.law, "a control law")?;
        }
        for sh in &self.shapes {
            if !sh.nominal.is_finite() {
                return Err(format!("shape parameter `{}` is not finite", sh.name));
            }
            for &site in &sh.sites {
                expr(site, "a shape parameter")?;
                if !matches!(
                    self.exprs[site.index()],
                    ExprNode::Deadzone(..) | ExprNode::Saturate(..)
                ) {
                    return Err(format!(
                        "shape parameter `{}` sits on a node that is no gap or limit",
                        sh.name
                    ));
                }
            }
        }
        let first_acc = 2 * nb + self.inputs.len() + nr;
        let mut last: Option<usize> = None;
        for (k, s) in self.signals.iter().enumerate() {
            let acc = match s.kind {
                SignalKind::Acceleration(b) => Some(b),
                _ => None,
            };
            if k < first_acc {
                if acc.is_some() {
                    return Err(format!("acceleration signal `{}` is out of place", s.name));
                }
                continue;
            }
            let Some(b) = acc else {
                return Err(format!(
                    "signal `{}` after the references is no acceleration",
                    s.name
                ));
            };
            body(b, &format!("acceleration signal `{}`", s.name))?;
            if last.is_some_and(|l| l >= b.index()) {
                return Err(format!(
                    "acceleration signals are not in body order at `{}`",
                    s.name
                ));
            }
            last = Some(b.index());
        }
        for x in &self.reference_excitation {
            if x.reference.index() >= nr {
                return Err(format!(
                    "excitation of reference #{} that does not exist",
                    x.reference.index()
                ));
            }
        }
        for (k, r) in self.references.iter().enumerate() {
            let s = self.reference_signal(ReferenceId(k as u32));
            if self.signals.get(s.index()).map(|s| s.kind)
                != Some(SignalKind::Reference(ReferenceId(k as u32)))
            {
                return Err(format!(
                    "the signal of reference `{}` is out of place",
                    r.name
                ));
            }
        }
        for x in &self.excitation {
            if x.input.index() >= self.inputs.len() {
                return Err(format!(
                    "excitation of input #{} that does not exist",
                    x.input.index()
                ));
            }
        }
        if let Some(f) = &self.filter {
            if let Some(s) = f.driven_by.iter().find(|s| s.index() >= ns) {
                return Err(format!(
                    "the filter is driven by signal #{} that does not exist",
                    s.index()
                ));
            }
        }
        Ok(())
    }
}
