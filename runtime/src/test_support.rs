//! Hand-built models and a small deterministic simulator for tests and benchmarks.
//!
//! The IRs follow the lowering rules of the front end (inertia `mass · Deriv{i,2}`, linear
//! dampers as `Deriv{·,1}`, input forces as `−1 · u`). The simulator mirrors the reference
//! Python simulator: the input is an Ornstein–Uhlenbeck form filter `u' = −a u + level·w`
//! advanced exactly and held over each step, the mechanics by classical RK4, and the record is
//! decimated to the sample interval.

use crate::record::Record;
use dsl_parser::ir::*;
use rand::{rngs::StdRng, Rng, SeedableRng};
use rand_distr::StandardNormal;

fn signals(bodies: &[&str], inputs: &[&str], measured_v: bool) -> Vec<SignalIr> {
    let mut s = Vec::new();
    for (i, b) in bodies.iter().enumerate() {
        s.push(SignalIr {
            name: format!("{b}.x"),
            kind: SignalKind::Position(BodyId(i as u32)),
            measured: true,
        });
        s.push(SignalIr {
            name: format!("{b}.v"),
            kind: SignalKind::Velocity(BodyId(i as u32)),
            measured: measured_v,
        });
    }
    for (j, u) in inputs.iter().enumerate() {
        s.push(SignalIr {
            name: u.to_string(),
            kind: SignalKind::Input(InputId(j as u32)),
            measured: true,
        });
    }
    s
}

fn unknown(name: &str, nominal: f64) -> ParamIr {
    ParamIr {
        name: name.into(),
        kind: ParamKind::Unknown {
            nominal: Some(nominal),
        },
    }
}

fn term(coef: Coef, basis: Basis, origin: TermOrigin) -> TermIr {
    TermIr {
        coef,
        basis,
        origin,
    }
}

/// Parameters of the SDOF oscillator `m x'' + d x' + k x + k3 x³ + r sign(x') = u`.
#[derive(Clone, Copy, Debug)]
pub struct Sdof {
    pub m: f64,
    pub d: f64,
    pub k: f64,
    pub k3: f64,
    pub r: f64,
}

impl Default for Sdof {
    fn default() -> Self {
        Sdof {
            m: 1.0,
            d: 0.4,
            k: 4.0,
            k3: 2.0,
            r: 0.3,
        }
    }
}

/// The SDOF model with `m` known and `d, k, k3, r` unknown. With `coulomb = false` the
/// friction term is left out (a Duffing oscillator); with `measured_v = false` the velocity
/// is declared unmeasured.
pub fn sdof_ir(p: Sdof, coulomb: bool, measured_v: bool) -> ModelIr {
    let mut a = ExprArena::default();
    let x = a.signal(SignalId(0));
    let v = a.signal(SignalId(1));
    let u = a.signal(SignalId(2));
    let x3 = a.intern(ExprNode::Powi(x, 3));
    let sv = a.unary(UnaryOp::Sign, v);
    let mut params = vec![
        ParamIr {
            name: "m".into(),
            kind: ParamKind::Known(p.m),
        },
        unknown("d", p.d),
        unknown("k", p.k),
        unknown("k3", p.k3),
    ];
    let e = TermOrigin::Element(ElementId(0));
    let mut terms = vec![
        term(
            Coef::param(ParamId(0)),
            Basis::Deriv {
                body: BodyId(0),
                order: 2,
            },
            TermOrigin::Inertia(BodyId(0)),
        ),
        term(
            Coef::param(ParamId(1)),
            Basis::Deriv {
                body: BodyId(0),
                order: 1,
            },
            e,
        ),
        term(Coef::param(ParamId(2)), Basis::Expr(x), e),
        term(Coef::param(ParamId(3)), Basis::Expr(x3), e),
    ];
    let mut el_terms = vec![
        ForceTerm {
            coef: Coef::param(ParamId(1)),
            basis: v,
        },
        ForceTerm {
            coef: Coef::param(ParamId(2)),
            basis: x,
        },
        ForceTerm {
            coef: Coef::param(ParamId(3)),
            basis: x3,
        },
    ];
    if coulomb {
        params.push(unknown("r", p.r));
        terms.push(term(Coef::param(ParamId(4)), Basis::Expr(sv), e));
        el_terms.push(ForceTerm {
            coef: Coef::param(ParamId(4)),
            basis: sv,
        });
    }
    terms.push(term(
        Coef::constant(-1.0),
        Basis::Expr(u),
        TermOrigin::Input(InputId(0)),
    ));
    ModelIr {
        name: "sdof".into(),
        bodies: vec![BodyIr {
            name: "m1".into(),
            mass: Coef::param(ParamId(0)),
        }],
        inputs: vec![InputIr {
            name: "u".into(),
            body: BodyId(0),
        }],
        params,
        signals: signals(&["m1"], &["u"], measured_v),
        elements: vec![ElementIr {
            name: "e1".into(),
            kind: ElementKind::Force,
            nodes: (Node::Ground, Node::Body(BodyId(0))),
            s: x,
            v,
            terms: el_terms,
        }],
        exprs: a.into_nodes(),
        equations: vec![EquationIr {
            body: BodyId(0),
            terms,
        }],
        excitation: vec![ExcitationIr {
            input: InputId(0),
            filter: FormFilter::Lowpass { corner: 10.0 },
            levels: vec![6.0, 15.0, 40.0],
        }],
        filter: None,
        spans: SpanTable::default(),
    }
}

/// Add an unknown-parameter term `kd · deadzone(x, gap)` to the SDOF model's equation.
pub fn with_deadzone(mut ir: ModelIr, gap: f64, name: &str) -> ModelIr {
    let mut a = ExprArena::default();
    for n in &ir.exprs {
        a.intern(*n);
    }
    let x = a.signal(SignalId(0));
    let dz = a.intern(ExprNode::Deadzone(x, gap.to_bits()));
    ir.exprs = a.into_nodes();
    ir.params.push(unknown(name, 1.0));
    let p = ParamId(ir.params.len() as u32 - 1);
    let at = ir.equations[0].terms.len() - 1;
    ir.equations[0].terms.insert(
        at,
        term(
            Coef::param(p),
            Basis::Expr(dz),
            TermOrigin::Element(ElementId(0)),
        ),
    );
    ir
}

/// Parameters of the two-mass chain: ground –(k1, d1, k3 cubic)– m1 –(k2, d2, r Coulomb)– m2,
/// input force `u` on m2.
#[derive(Clone, Copy, Debug)]
pub struct TwoMass {
    pub m1: f64,
    pub m2: f64,
    pub k1: f64,
    pub d1: f64,
    pub k3: f64,
    pub k2: f64,
    pub d2: f64,
    pub r: f64,
}

impl Default for TwoMass {
    fn default() -> Self {
        TwoMass {
            m1: 1.0,
            m2: 0.5,
            k1: 4.0,
            d1: 0.3,
            k3: 2.0,
            k2: 6.0,
            d2: 0.2,
            r: 0.3,
        }
    }
}

/// The two-mass model, masses known, the six force parameters unknown.
pub fn two_mass_ir(p: TwoMass) -> ModelIr {
    let mut a = ExprArena::default();
    let x1 = a.signal(SignalId(0));
    let v1 = a.signal(SignalId(1));
    let x2 = a.signal(SignalId(2));
    let v2 = a.signal(SignalId(3));
    let u = a.signal(SignalId(4));
    let x13 = a.intern(ExprNode::Powi(x1, 3));
    let s2 = a.binary(BinaryOp::Sub, x2, x1);
    let w2 = a.binary(BinaryOp::Sub, v2, v1);
    let sg = a.unary(UnaryOp::Sign, w2);
    let params = vec![
        ParamIr {
            name: "m1".into(),
            kind: ParamKind::Known(p.m1),
        },
        ParamIr {
            name: "m2".into(),
            kind: ParamKind::Known(p.m2),
        },
        unknown("k1", p.k1),
        unknown("d1", p.d1),
        unknown("k3", p.k3),
        unknown("k2", p.k2),
        unknown("d2", p.d2),
        unknown("r", p.r),
    ];
    let (e1, e2) = (
        TermOrigin::Element(ElementId(0)),
        TermOrigin::Element(ElementId(1)),
    );
    let d = |b: u32, o: u8| Basis::Deriv {
        body: BodyId(b),
        order: o,
    };
    let c = |i: u32| Coef::param(ParamId(i));
    let eq1 = vec![
        term(c(0), d(0, 2), TermOrigin::Inertia(BodyId(0))),
        term(c(2), Basis::Expr(x1), e1),
        term(c(3), d(0, 1), e1),
        term(c(4), Basis::Expr(x13), e1),
        // m1 is node a of the coupling element: its terms enter with −coef.
        term(c(5).scaled(-1.0), Basis::Expr(s2), e2),
        term(c(6).scaled(-1.0), d(1, 1), e2),
        term(c(6), d(0, 1), e2),
        term(c(7).scaled(-1.0), Basis::Expr(sg), e2),
    ];
    let eq2 = vec![
        term(c(1), d(1, 2), TermOrigin::Inertia(BodyId(1))),
        term(c(5), Basis::Expr(s2), e2),
        term(c(6), d(1, 1), e2),
        term(c(6).scaled(-1.0), d(0, 1), e2),
        term(c(7), Basis::Expr(sg), e2),
        term(
            Coef::constant(-1.0),
            Basis::Expr(u),
            TermOrigin::Input(InputId(0)),
        ),
    ];
    ModelIr {
        name: "two_mass".into(),
        bodies: vec![
            BodyIr {
                name: "m1".into(),
                mass: c(0),
            },
            BodyIr {
                name: "m2".into(),
                mass: c(1),
            },
        ],
        inputs: vec![InputIr {
            name: "u".into(),
            body: BodyId(1),
        }],
        params,
        signals: signals(&["m1", "m2"], &["u"], true),
        elements: vec![
            ElementIr {
                name: "ground_m1".into(),
                kind: ElementKind::Force,
                nodes: (Node::Ground, Node::Body(BodyId(0))),
                s: x1,
                v: v1,
                terms: vec![],
            },
            ElementIr {
                name: "m1_m2".into(),
                kind: ElementKind::Force,
                nodes: (Node::Body(BodyId(0)), Node::Body(BodyId(1))),
                s: s2,
                v: w2,
                terms: vec![],
            },
        ],
        exprs: a.into_nodes(),
        equations: vec![
            EquationIr {
                body: BodyId(0),
                terms: eq1,
            },
            EquationIr {
                body: BodyId(1),
                terms: eq2,
            },
        ],
        excitation: vec![],
        filter: None,
        spans: SpanTable::default(),
    }
}

/// Simulation settings mirroring the reference simulator.
#[derive(Clone, Copy, Debug)]
pub struct SimSpec {
    /// White-noise intensity of the form filter.
    pub level: f64,
    /// Corner of the form filter `u' = −a u + level·w`.
    pub a: f64,
    /// Recorded duration (after the burn-in) in seconds.
    pub duration: f64,
    pub dt: f64,
    /// Record every `decimate`-th step.
    pub decimate: usize,
    pub burn_in: f64,
    pub seed: u64,
}

impl SimSpec {
    pub fn new(level: f64, duration: f64, seed: u64) -> SimSpec {
        SimSpec {
            level,
            a: 10.0,
            duration,
            dt: 1e-3,
            decimate: 10,
            burn_in: 20.0,
            seed,
        }
    }
}

/// Simulate `M ẍ = f(x, v) + B u` with `accel(x, v, u, a)` writing `ẍ`. Returns a record
/// with columns `{body}.x`, `{body}.v` per body and `u`.
pub fn simulate<const N: usize>(
    bodies: [&str; N],
    accel: impl Fn(&[f64; N], &[f64; N], f64, &mut [f64; N]),
    spec: SimSpec,
) -> Record {
    let dt = spec.dt;
    let n_burn = (spec.burn_in / dt).round() as usize;
    let n = (spec.duration / dt).round() as usize;
    let mut rng = StdRng::seed_from_u64(spec.seed);
    let phi = (-spec.a * dt).exp();
    let q = spec.level * ((1.0 - phi * phi) / (2.0 * spec.a)).sqrt();
    let n_rec = n.div_ceil(spec.decimate);
    let mut cols = vec![Vec::with_capacity(n_rec); 2 * N + 1];
    let (mut x, mut v) = ([0.0; N], [0.0; N]);
    let g: f64 = rng.sample(StandardNormal);
    let mut u = spec.level / (2.0 * spec.a).sqrt() * g;
    let (h, h2, h6) = (dt, 0.5 * dt, dt / 6.0);
    let (mut a1, mut a2, mut a3, mut a4) = ([0.0; N], [0.0; N], [0.0; N], [0.0; N]);
    for i in 0..n + n_burn {
        if i >= n_burn && (i - n_burn).is_multiple_of(spec.decimate) {
            for b in 0..N {
                cols[2 * b].push(x[b]);
                cols[2 * b + 1].push(v[b]);
            }
            cols[2 * N].push(u);
        }
        accel(&x, &v, u, &mut a1);
        let x2: [f64; N] = std::array::from_fn(|b| x[b] + h2 * v[b]);
        let v2: [f64; N] = std::array::from_fn(|b| v[b] + h2 * a1[b]);
        accel(&x2, &v2, u, &mut a2);
        let x3: [f64; N] = std::array::from_fn(|b| x[b] + h2 * v2[b]);
        let v3: [f64; N] = std::array::from_fn(|b| v[b] + h2 * a2[b]);
        accel(&x3, &v3, u, &mut a3);
        let x4: [f64; N] = std::array::from_fn(|b| x[b] + h * v3[b]);
        let v4: [f64; N] = std::array::from_fn(|b| v[b] + h * a3[b]);
        accel(&x4, &v4, u, &mut a4);
        for b in 0..N {
            x[b] += h6 * (v[b] + 2.0 * v2[b] + 2.0 * v3[b] + v4[b]);
            v[b] += h6 * (a1[b] + 2.0 * a2[b] + 2.0 * a3[b] + a4[b]);
        }
        let w: f64 = rng.sample(StandardNormal);
        u = phi * u + q * w;
    }
    let mut names = Vec::new();
    for b in bodies {
        names.push(format!("{b}.x"));
        names.push(format!("{b}.v"));
    }
    names.push("u".into());
    Record {
        names,
        columns: cols,
        ts: dt * spec.decimate as f64,
        t0: 0.0,
    }
}

/// Simulate the SDOF oscillator.
pub fn simulate_sdof(p: Sdof, spec: SimSpec) -> Record {
    let im = 1.0 / p.m;
    simulate(
        ["m1"],
        |x, v, u, a| {
            let (x, v) = (x[0], v[0]);
            a[0] = (u - p.d * v - p.k * x - p.k3 * x * x * x - p.r * sgn(v)) * im;
        },
        spec,
    )
}

/// Simulate the two-mass chain.
pub fn simulate_two_mass(p: TwoMass, spec: SimSpec) -> Record {
    simulate(
        ["m1", "m2"],
        |x, v, u, a| {
            let (s, w) = (x[1] - x[0], v[1] - v[0]);
            let f2 = p.k2 * s + p.d2 * w + p.r * sgn(w);
            a[0] = (f2 - p.k1 * x[0] - p.d1 * v[0] - p.k3 * x[0].powi(3)) / p.m1;
            a[1] = (u - f2) / p.m2;
        },
        spec,
    )
}

fn sgn(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Add white Gaussian noise of standard deviation `eta · std(column)` to the named columns.
pub fn add_noise(rec: &mut Record, columns: &[&str], eta: f64, seed: u64) {
    let mut rng = StdRng::seed_from_u64(seed);
    for name in columns {
        let k = rec.names.iter().position(|n| n == name).expect("column");
        let c = &mut rec.columns[k];
        let n = c.len() as f64;
        let mean = c.iter().sum::<f64>() / n;
        let sd = (c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        for v in c.iter_mut() {
            let e: f64 = rng.sample(StandardNormal);
            *v += eta * sd * e;
        }
    }
}

/// Drop a column (e.g. velocities for displacement-only data).
pub fn drop_column(rec: &mut Record, name: &str) {
    if let Some(k) = rec.names.iter().position(|n| n == name) {
        rec.names.remove(k);
        rec.columns.remove(k);
    }
}
