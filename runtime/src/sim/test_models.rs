//! Hand-built IRs for tests of the back ends, lowered by the same rules as the front end
//! (see the IR documentation). Not part of the stable API.

use dsl_parser::ir::*;

/// Parameters of `m x'' + d x' + k x + k3 x³ + r sign(x') = u`; `m` is known, the others
/// are unknown with these nominal values. A `None` term is left out of the model.
#[derive(Clone, Debug)]
pub struct SdofParams {
    pub m: f64,
    pub d: f64,
    pub k: f64,
    pub k3: Option<f64>,
    pub r: Option<f64>,
}

impl SdofParams {
    /// The benchmark of the method note: m=1, d=0.4, k=4, k3=2, r=0.3.
    pub fn benchmark() -> Self {
        SdofParams {
            m: 1.0,
            d: 0.4,
            k: 4.0,
            k3: Some(2.0),
            r: Some(0.3),
        }
    }
    pub fn linear(m: f64, d: f64, k: f64) -> Self {
        SdofParams {
            m,
            d,
            k,
            k3: None,
            r: None,
        }
    }
}

/// The SDOF oscillator on body `m1` (signals `m1.x`, `m1.v`, `u`) excited through `filter`.
pub fn sdof(p: &SdofParams, filter: FormFilter, levels: Vec<f64>) -> ModelIr {
    let mut arena = ExprArena::default();
    let b = BodyId(0);
    let x = arena.signal(SignalId(0));
    let v = arena.signal(SignalId(1));
    let u = arena.signal(SignalId(2));
    let mut params = vec![ParamIr {
        name: "m".into(),
        kind: ParamKind::Known(p.m),
    }];
    let mut add_param = |name: &str, value: f64| {
        params.push(ParamIr {
            name: name.into(),
            kind: ParamKind::Unknown {
                nominal: Some(value),
            },
        });
        Coef::param(ParamId(params.len() as u32 - 1))
    };
    let d = add_param("d", p.d);
    let k = add_param("k", p.k);
    let k3 = p.k3.map(|v| add_param("k3", v));
    let r = p.r.map(|v| add_param("r", v));

    let mut elements = Vec::new();
    let mut terms = vec![TermIr {
        coef: Coef::param(ParamId(0)),
        basis: Basis::Deriv { body: b, order: 2 },
        origin: TermOrigin::Inertia(b),
    }];
    let nodes = (Node::Ground, Node::Body(b));
    let mut element = |name: &str, kind, force: Vec<ForceTerm>, eq: Vec<(Coef, Basis)>| {
        let id = ElementId(elements.len() as u32);
        elements.push(ElementIr {
            name: name.into(),
            kind,
            nodes,
            s: x,
            v,
            terms: force,
        });
        for (coef, basis) in eq {
            terms.push(TermIr {
                coef,
                basis,
                origin: TermOrigin::Element(id),
            });
        }
    };
    element(
        "damper",
        ElementKind::Damper,
        vec![ForceTerm { coef: d, basis: v }],
        vec![(d, Basis::Deriv { body: b, order: 1 })],
    );
    let mut spring = vec![(k, x)];
    if let Some(k3) = k3 {
        spring.push((k3, arena.intern(ExprNode::Powi(x, 3))));
    }
    element(
        "spring",
        ElementKind::Spring,
        spring
            .iter()
            .map(|&(coef, basis)| ForceTerm { coef, basis })
            .collect(),
        spring.iter().map(|&(c, e)| (c, Basis::Expr(e))).collect(),
    );
    if let Some(r) = r {
        let sg = arena.unary(UnaryOp::Sign, v);
        element(
            "friction",
            ElementKind::Force,
            vec![ForceTerm { coef: r, basis: sg }],
            vec![(r, Basis::Expr(sg))],
        );
    }
    terms.push(TermIr {
        coef: Coef::constant(-1.0),
        basis: Basis::Expr(u),
        origin: TermOrigin::Input(InputId(0)),
    });
    let signal = |name: &str, kind| SignalIr {
        name: name.into(),
        kind,
        measured: true,
    };
    let ir = ModelIr {
        name: "sdof".into(),
        bodies: vec![BodyIr {
            name: "m1".into(),
            mass: Coef::param(ParamId(0)),
        }],
        inputs: vec![InputIr {
            name: "u".into(),
            body: b,
        }],
        params,
        signals: vec![
            signal("m1.x", SignalKind::Position(b)),
            signal("m1.v", SignalKind::Velocity(b)),
            signal("u", SignalKind::Input(InputId(0))),
        ],
        elements,
        exprs: arena.into_nodes(),
        equations: vec![EquationIr { body: b, terms }],
        excitation: vec![ExcitationIr {
            input: InputId(0),
            filter,
            levels,
        }],
        filter: None,
        spans: SpanTable::default(),
    };
    debug_assert!(ir.check_invariants().is_ok());
    ir
}

/// Two bodies in a chain, ground –(k1, d1)– m1 –(k2, d2)– m2, force `u` on `m2`; all
/// coefficients known (for multi-body tests).
pub fn two_mass_chain(
    m: [f64; 2],
    k: [f64; 2],
    d: [f64; 2],
    filter: FormFilter,
    levels: Vec<f64>,
) -> ModelIr {
    let mut arena = ExprArena::default();
    let (b1, b2) = (BodyId(0), BodyId(1));
    let x1 = arena.signal(SignalId(0));
    let v1 = arena.signal(SignalId(1));
    let x2 = arena.signal(SignalId(2));
    let v2 = arena.signal(SignalId(3));
    let u = arena.signal(SignalId(4));
    let s12 = arena.binary(BinaryOp::Sub, x2, x1);
    let v12 = arena.binary(BinaryOp::Sub, v2, v1);
    let c = Coef::constant;
    let term = |coef, basis, origin| TermIr {
        coef,
        basis,
        origin,
    };
    let el = |i| TermOrigin::Element(ElementId(i));
    // Element 0 (ground, m1): s = x1. Element 1 (m1, m2): s = x2 − x1, pushes m1 by +f.
    let eq1 = vec![
        term(
            c(m[0]),
            Basis::Deriv { body: b1, order: 2 },
            TermOrigin::Inertia(b1),
        ),
        term(c(k[0]), Basis::Expr(x1), el(0)),
        term(c(d[0]), Basis::Deriv { body: b1, order: 1 }, el(0)),
        term(c(-k[1]), Basis::Expr(s12), el(1)),
        term(c(-d[1]), Basis::Deriv { body: b2, order: 1 }, el(1)),
        term(c(d[1]), Basis::Deriv { body: b1, order: 1 }, el(1)),
    ];
    let eq2 = vec![
        term(
            c(m[1]),
            Basis::Deriv { body: b2, order: 2 },
            TermOrigin::Inertia(b2),
        ),
        term(c(k[1]), Basis::Expr(s12), el(1)),
        term(c(d[1]), Basis::Deriv { body: b2, order: 1 }, el(1)),
        term(c(-d[1]), Basis::Deriv { body: b1, order: 1 }, el(1)),
        term(c(-1.0), Basis::Expr(u), TermOrigin::Input(InputId(0))),
    ];
    let signal = |name: &str, kind| SignalIr {
        name: name.into(),
        kind,
        measured: true,
    };
    let elements = vec![
        ElementIr {
            name: "k1".into(),
            kind: ElementKind::Spring,
            nodes: (Node::Ground, Node::Body(b1)),
            s: x1,
            v: v1,
            terms: vec![
                ForceTerm {
                    coef: c(k[0]),
                    basis: x1,
                },
                ForceTerm {
                    coef: c(d[0]),
                    basis: v1,
                },
            ],
        },
        ElementIr {
            name: "k2".into(),
            kind: ElementKind::Spring,
            nodes: (Node::Body(b1), Node::Body(b2)),
            s: s12,
            v: v12,
            terms: vec![
                ForceTerm {
                    coef: c(k[1]),
                    basis: s12,
                },
                ForceTerm {
                    coef: c(d[1]),
                    basis: v12,
                },
            ],
        },
    ];
    let ir = ModelIr {
        name: "chain2".into(),
        bodies: vec![
            BodyIr {
                name: "m1".into(),
                mass: c(m[0]),
            },
            BodyIr {
                name: "m2".into(),
                mass: c(m[1]),
            },
        ],
        inputs: vec![InputIr {
            name: "u".into(),
            body: b2,
        }],
        params: Vec::new(),
        signals: vec![
            signal("m1.x", SignalKind::Position(b1)),
            signal("m1.v", SignalKind::Velocity(b1)),
            signal("m2.x", SignalKind::Position(b2)),
            signal("m2.v", SignalKind::Velocity(b2)),
            signal("u", SignalKind::Input(InputId(0))),
        ],
        elements,
        exprs: arena.into_nodes(),
        equations: vec![
            EquationIr {
                body: b1,
                terms: eq1,
            },
            EquationIr {
                body: b2,
                terms: eq2,
            },
        ],
        excitation: vec![ExcitationIr {
            input: InputId(0),
            filter,
            levels,
        }],
        filter: None,
        spans: SpanTable::default(),
    };
    debug_assert!(ir.check_invariants().is_ok());
    ir
}
