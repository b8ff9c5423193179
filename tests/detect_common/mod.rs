//! Helpers of detection on simulated data, shared by `tests/detect_models.rs` and
//! `examples/detect_measurements.rs`: compile a model of `models/`, simulate its levels,
//! run detection with the linear counterpart.
#![allow(dead_code)] // the example uses a subset (the hit-rate matrix is the tests')

use dynid::dsl_parser::{compile_file, ir::ModelIr};
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::detect::{
    detect_from_data_with_progress, DetectOptions, Detection, ElementFinding, LevelFits,
};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{simulate, SimConfig};
use dynid::runtime::IdentifyOptions;
use std::path::Path;

/// `models/NAME.dyn`, compiled.
pub fn model(name: &str) -> ModelIr {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(format!("{name}.dyn"));
    compile_file(&p).unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

/// The model's excitation levels, `duration` seconds each after a 20 s burn-in.
pub fn simulate_levels(ir: &ModelIr, duration: f64, seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration,
        seed,
        burn_in: 20.0,
        ..Default::default()
    };
    simulate(ir, &cfg).expect("simulate").records
}

/// Detection with the linear model `ir` on `records` (one per level).
pub fn detect_levels(ir: &ModelIr, records: &[Record], balance: bool) -> (Detection, LevelFits) {
    let srcs: Vec<RecordSource> = records
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = IdentifyOptions {
        balance,
        ..Default::default()
    };
    // The progress contract: one call per template simulation, numbered 1…N, each with a
    // total at least its number, the last total N; a simulation for every estimator fit.
    let calls = std::sync::Mutex::new(Vec::new());
    let progress = |done: usize, total: usize| calls.lock().unwrap().push((done, total));
    let found = detect_from_data_with_progress(
        ir,
        &levels,
        &opts,
        &DetectOptions::default(),
        &[],
        &progress,
    )
    .expect("detect");
    let mut calls = calls.into_inner().unwrap();
    calls.sort_unstable();
    let n = calls.len();
    assert!(
        calls
            .iter()
            .enumerate()
            .all(|(i, &(d, t))| d == i + 1 && t >= d),
        "{calls:?}"
    );
    assert_eq!(calls.iter().map(|c| c.1).max().unwrap_or(0), n, "{calls:?}");
    let fits: usize = found.0.elements.iter().map(|e| e.estimator.len()).sum();
    assert!(
        n >= fits,
        "{n} simulations reported for {fits} estimator fits"
    );
    found
}

/// The finding of `element`.
pub fn finding<'a>(d: &'a Detection, element: &str) -> &'a ElementFinding {
    d.elements
        .iter()
        .find(|e| e.element == element)
        .unwrap_or_else(|| panic!("no element {element}"))
}

/// A nonlinear effect of the detection matrix (one at one element of a structure).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effect {
    Cubic,
    Coulomb,
    Quadratic,
    Backlash,
    Prestress,
}

impl Effect {
    pub const ALL: [Effect; 5] = [
        Effect::Cubic,
        Effect::Coulomb,
        Effect::Quadratic,
        Effect::Backlash,
        Effect::Prestress,
    ];

    /// The template's name in a verdict.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Cubic => "cubic stiffness",
            Effect::Coulomb => "Coulomb friction",
            Effect::Quadratic => "quadratic damping",
            Effect::Backlash => "backlash",
            Effect::Prestress => "prestress",
        }
    }
}

/// The structures of the detection matrix: the effect sits at the element named by
/// [`Structure::element`] (for the chain, a middle element with a neighbour on each side).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Structure {
    Sdof,
    TwoMass,
    Chain4,
}

impl Structure {
    pub const ALL: [Structure; 3] = [Structure::Sdof, Structure::TwoMass, Structure::Chain4];

    pub fn label(self) -> &'static str {
        match self {
            Structure::Sdof => "sdof",
            Structure::TwoMass => "two-mass",
            Structure::Chain4 => "chain4",
        }
    }

    /// The detection element that carries the effect.
    pub fn element(self) -> &'static str {
        match self {
            Structure::Sdof => "k/d (ground, m)",
            Structure::TwoMass => "k2/d2 (m1, m2)",
            Structure::Chain4 => "k3/d3 (m2, m3)",
        }
    }

    /// Model source of the structure (linear), with `effect` added at its element as the
    /// force `nl` when given. Sizes follow `models/`: sdof_duffing, sdof_coulomb,
    /// quadratic_damping, backlash and prestress for the single mass; two_mass for the
    /// coupling; chain4 for the chain.
    pub fn source(self, effect: Option<Effect>) -> String {
        let term = |e: Effect| -> String {
            let (k3, r, c, kb, g, f0) = match self {
                Structure::Sdof => (2.0, 0.3, 0.2, 4.0, 0.1, 0.5),
                Structure::TwoMass => (1.5, 0.2, 0.2, 3.0, 0.05, 0.3),
                Structure::Chain4 => (1.0, 0.1, 0.1, 2.0, 0.05, 0.1),
            };
            match e {
                Effect::Cubic => format!("p ~ {k3} * s^3"),
                Effect::Coulomb => format!("p ~ {r} * sign(v)"),
                Effect::Quadratic => format!("p ~ {c} * v * abs(v)"),
                Effect::Backlash => format!("p ~ {kb} * deadzone(s, {g})"),
                Effect::Prestress => format!("p ~ {f0} * sign(s)"),
            }
        };
        let excite = "    excite u: lowpass(corner = 10) levels [6, 15, 40]\n";
        let mut s = String::from("model m {\n");
        match self {
            Structure::Sdof => {
                // A backlash needs a soft linear spring beside it to show (models/backlash.dyn).
                let k = if effect == Some(Effect::Backlash) {
                    1.0
                } else {
                    4.0
                };
                s += "    body m = 1.0\n    input u on m\n";
                s += &format!("    spring k (ground, m) ~ {k}\n    damper d (ground, m) ~ 0.4\n");
                if let Some(e) = effect {
                    s += &format!("    force nl (ground, m) = {}\n", term(e));
                }
                s += excite;
            }
            Structure::TwoMass => {
                s += "    body m1 = 1.0\n    body m2 ~ 2.0\n    input u on m1\n";
                s += "    spring k1 (ground, m1) ~ 4.0\n    damper d1 (ground, m1) ~ 0.4\n";
                s += "    spring k2 (m1, m2) ~ 3.0\n    damper d2 (m1, m2) ~ 0.2\n";
                if let Some(e) = effect {
                    s += &format!("    force nl (m1, m2) = {}\n", term(e));
                }
                s += excite;
                s += "    filter corners [0.5, 1, 2, 4, 8, 16] order 2\n";
            }
            Structure::Chain4 => {
                s += "    body m1 = 1.0\n    body m2 = 1.0\n    body m3 = 1.0\n    body m4 = 1.0\n";
                s += "    input u on m4\n";
                for (i, (a, b, k)) in [
                    ("ground", "m1", 6.0),
                    ("m1", "m2", 5.0),
                    ("m2", "m3", 4.0),
                    ("m3", "m4", 3.0),
                ]
                .iter()
                .enumerate()
                {
                    s += &format!(
                        "    spring k{n} ({a}, {b}) ~ {k}\n    damper d{n} ({a}, {b}) ~ 0.3\n",
                        n = i + 1
                    );
                }
                if let Some(e) = effect {
                    s += &format!("    force nl (m2, m3) = {}\n", term(e));
                }
                s += excite;
                s += "    filter corners [0.5, 1, 2, 4, 8, 16] order 2\n";
            }
        }
        s + "}\n"
    }
}

/// How one detection run of the matrix came out at the element that carries the effect,
/// and whether any other element was flagged.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Outcome {
    /// The verdict is exactly the effect, nothing suspected beside it.
    pub exact: bool,
    /// The effect is named, with a second one (a pair, `also suspected`, or ambiguous).
    pub extra: bool,
    /// The effect is not named at its element.
    pub missed: bool,
    /// Another element is not linear.
    pub neighbour: bool,
}

/// Classify a detection of the matrix: `effect` at `element`, or a linear control (`None`:
/// every element must be linear).
pub fn classify(d: &Detection, element: &str, effect: Option<Effect>) -> Outcome {
    use dynid::runtime::detect::Verdict;
    let mut o = Outcome::default();
    for f in &d.elements {
        let target = effect.is_some() && f.element == element;
        if !target {
            if f.verdict != Verdict::Linear {
                o.neighbour = true;
            }
            continue;
        }
        let name = effect.map(Effect::name).unwrap_or_default();
        match &f.verdict {
            Verdict::Nonlinear { best, .. } if best == name => {
                if f.suspected.is_some() {
                    o.extra = true;
                } else {
                    o.exact = true;
                }
            }
            Verdict::Nonlinear { best, .. } if best.split(" + ").any(|e| e == name) => {
                o.extra = true;
            }
            Verdict::Ambiguous { candidates }
                if candidates.iter().any(|c| c.split(" + ").any(|e| e == name)) =>
            {
                o.extra = true;
            }
            _ => o.missed = true,
        }
    }
    o
}

/// Simulate `truth` (source) for `duration` s per level with measurement `noise` (fraction
/// of each signal's σ), and detect with `linear`.
pub fn detect_case(truth: &str, linear: &str, duration: f64, noise: f64, seed: u64) -> Detection {
    let truth = dynid::dsl_parser::compile_str("truth.dyn", truth).expect("truth model");
    let linear = dynid::dsl_parser::compile_str("linear.dyn", linear).expect("linear model");
    let cfg = SimConfig {
        duration,
        seed,
        noise,
        burn_in: 20.0,
        ..Default::default()
    };
    let recs = simulate(&truth, &cfg).expect("simulate").records;
    detect_levels(&linear, &recs, false).0
}
