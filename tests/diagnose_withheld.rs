//! Diagnosis on data whose effect is withheld from the model: the truth is simulated with
//! an extra force term, `diagnose` sees only the model without it and the data, and must
//! name the location and the effect and remove at least 80 % of the headline (statistical)
//! gap. A model that matches the data must report no significant unmodelled effect.
//!
//! Each case prints one row of the table in `docs/diagnosis.md` (`cargo test --release
//! --test diagnose_withheld -- --nocapture --test-threads 1`); `DYNID_SEED_OFFSET` shifts
//! the seed.

mod common;
mod figures;

use dynid::runtime::diagnose::{
    diagnose, fmt_opt_gap, DiagnoseOptions, Diagnosis, FoundEffect, Verdict,
};
use dynid::runtime::sim::{simulate, SimConfig};

const TWO_MASS: &str = include_str!("../models/two_mass_linear.dyn");
const CHAIN4: &str = include_str!("../models/chain4_linear.dyn");

/// Insert lines before the model's closing brace.
fn with_lines(src: &str, lines: &[&str]) -> String {
    let k = src.rfind('}').expect("closing brace");
    let mut s = src[..k].to_string();
    for l in lines {
        s.push_str("    ");
        s.push_str(l);
        s.push('\n');
    }
    s.push_str(&src[k..]);
    s
}

struct Case {
    name: &'static str,
    base: &'static str,
    /// Lines added to both model and truth (e.g. a `measure` statement).
    common: &'static [&'static str],
    /// The withheld effect(s).
    truth: &'static [&'static str],
    noise: f64,
    duration: f64,
    /// Steps of the input process per sample (1: none between samples).
    oversample: usize,
}

impl Case {
    /// The two-mass model, nothing added or withheld, noise-free, 300 s per level, no input
    /// content between samples; a case names what differs (`..Case::DEFAULT`).
    const DEFAULT: Case = Case {
        name: "",
        base: TWO_MASS,
        common: &[],
        truth: &[],
        noise: 0.0,
        duration: 300.0,
        oversample: 1,
    };
}

fn run(case: &Case) -> Diagnosis {
    run_at(case, common::seed(11))
}

fn run_at(case: &Case, seed: u64) -> Diagnosis {
    // Displacement-only identification needs filter chains of order ≥ 3: let the
    // identification choose them.
    let base: String = if case.common.iter().any(|l| l.starts_with("measure")) {
        case.base
            .lines()
            .filter(|l| !l.trim_start().starts_with("filter"))
            .map(|l| format!("{l}\n"))
            .collect()
    } else {
        case.base.to_string()
    };
    let model = with_lines(&base, case.common);
    let mut all: Vec<&str> = case.common.to_vec();
    all.extend_from_slice(case.truth);
    let truth = with_lines(&base, &all);
    let ir = dynid::dsl_parser::compile_str("truth", &truth).expect("truth compiles");
    let cfg = SimConfig {
        duration: case.duration,
        burn_in: 50.0,
        seed,
        noise: case.noise,
        input_oversample: case.oversample,
        ..Default::default()
    };
    let out = simulate(&ir, &cfg).expect("simulates");
    let origins: Vec<String> = (1..=out.records.len())
        .map(|k| format!("level{k}"))
        .collect();
    let d = diagnose(
        &dynid::dsl_parser::compile_str(case.name, &model).expect("model compiles"),
        &out.records,
        &origins,
        &DiagnoseOptions::default(),
        &|_, _| {},
    )
    .expect("diagnoses");
    let found: Vec<String> = d
        .found
        .iter()
        .map(|f| format!("{} at {}", f.effect.kind(), f.location.label()))
        .collect();
    let pct = |x: f64| format!("{x:.1}");
    eprintln!(
        "| {} (seed {seed}) | {} | {} | {} / {} / {} | {} % / {} % | {} / {} / {} |",
        case.name,
        case.truth.join("; "),
        if found.is_empty() {
            "none".to_string()
        } else {
            found.join("; ")
        },
        pct(d.gap_before),
        pct(d.gap_reidentified),
        pct(d.gap_after),
        d.shrink.map_or("–".into(), |x| format!("{:.0}", 100.0 * x)),
        d.effect_shrink
            .map_or("–".into(), |x| format!("{:.0}", 100.0 * x)),
        pct(d.pathwise_gap_before),
        pct(d.pathwise_gap_reidentified),
        pct(d.pathwise_gap_after),
    );
    for f in &d.found {
        eprintln!(
            "    found {} at {}: {} = {} ± {}{}",
            f.effect.name(),
            f.location.label(),
            f.param,
            f.value,
            f.stderr,
            f.shape_stderr
                .map_or(String::new(), |e| format!(", gap ± {e}"))
        );
    }
    for c in d.ranking.iter().filter(|c| c.gap.is_some()).take(4) {
        eprintln!(
            "    {} at {}: t = {:.1}, cv residual {:.2} %, gap {}, pathwise {}",
            c.effect.name(),
            c.location.label(),
            c.t_ratio,
            c.cv_residual,
            fmt_opt_gap(c.gap),
            fmt_opt_gap(c.pathwise_gap)
        );
    }
    if seed == DOC_SEED {
        check_doc_row(&d);
    }
    // The corrected model must compile.
    dynid::dsl_parser::compile_str("fixed", &d.fixed_source).expect("corrected model compiles");
    d
}

/// The seed of the table in `docs/diagnosis.md`.
const DOC_SEED: u64 = 11;

/// The gaps of `d` as a row of the table in `docs/diagnosis.md` ("Validated on withheld
/// effects") writes them — headline gaps, shrinks, pathwise gaps — must stand in that table:
/// a change that moves a documented gap fails here until the table is updated (the row to
/// paste is printed by `--nocapture`).
fn check_doc_row(d: &Diagnosis) {
    let pct = |x: f64| format!("{x:.1}");
    let share = |x: Option<f64>| x.map_or("–".into(), |x| format!("{:.0} %", 100.0 * x));
    let cells = if d.found.is_empty() {
        format!(
            "| {} / {} / – | – | {} / {} / – |",
            pct(d.gap_before),
            pct(d.gap_reidentified),
            pct(d.pathwise_gap_before),
            pct(d.pathwise_gap_reidentified),
        )
    } else {
        format!(
            "| {} / {} / {} | {} / {} | {} / {} / {} |",
            pct(d.gap_before),
            pct(d.gap_reidentified),
            pct(d.gap_after),
            share(d.shrink),
            share(d.effect_shrink),
            pct(d.pathwise_gap_before),
            pct(d.pathwise_gap_reidentified),
            pct(d.pathwise_gap_after),
        )
    };
    let doc = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/diagnosis.md"),
    )
    .expect("docs/diagnosis.md");
    // A profiled backlash gap as the table's "found" cell gives it.
    let gap = d.found.iter().find_map(|f| match f.effect {
        dynid::runtime::diagnose::Effect::Backlash { gap } => Some(format!("(g = {gap:.4})")),
        _ => None,
    });
    assert!(
        doc.lines()
            .any(|l| l.ends_with(&cells) && gap.as_ref().is_none_or(|g| l.contains(g))),
        "docs/diagnosis.md: no row of the withheld-effects table ends in\n{cells}{}\n{}",
        gap.map_or(String::new(), |g| format!("\nwith {g} in it")),
        d.summary()
    );
}

/// The single effect found, checked to be `kind` at `(a, b)` in that order.
fn the_one_found<'d>(d: &'d Diagnosis, kind: &str, (a, b): (&str, &str)) -> &'d FoundEffect {
    assert_eq!(d.verdict, Verdict::MissingEffect, "{}", d.summary());
    assert_eq!(d.found.len(), 1, "{}", d.summary());
    let f = &d.found[0];
    assert_eq!(f.effect.kind(), kind, "{}", d.summary());
    assert_eq!((f.location.a.as_str(), f.location.b.as_str()), (a, b));
    f
}

fn assert_found(d: &Diagnosis, expected: &[(&str, &str, &str)]) {
    if let Err(e) = found(d, expected, 0.8) {
        panic!("{e}:\n{}", d.summary());
    }
}

/// Whether `d` names exactly the `expected` effects (kind, location in either order) and
/// removes at least `min_shrink` of the headline gap; else what it got wrong.
fn found(d: &Diagnosis, expected: &[(&str, &str, &str)], min_shrink: f64) -> Result<(), String> {
    if d.verdict != Verdict::MissingEffect {
        return Err(format!("verdict {:?}", d.verdict));
    }
    if d.found.len() != expected.len() {
        let got: Vec<String> = d
            .found
            .iter()
            .map(|f| format!("{} at {}", f.effect.kind(), f.location.label()))
            .collect();
        return Err(format!("found {} effects: {}", got.len(), got.join("; ")));
    }
    for (kind, a, b) in expected {
        if !d.found.iter().any(|f| {
            f.effect.kind() == *kind
                && ((f.location.a == *a && f.location.b == *b)
                    || (f.location.a == *b && f.location.b == *a))
        }) {
            return Err(format!("no {kind} at ({a}, {b})"));
        }
    }
    match d.shrink {
        Some(s) if s >= min_shrink => Ok(()),
        s => Err(format!("shrink {s:?} below {min_shrink}")),
    }
}

/// On how many of the diagnoses (one per seed) the verdict `what` holds (each failing seed
/// printed).
fn rate(
    what: &str,
    runs: &[(u64, Diagnosis)],
    check: impl Fn(&Diagnosis) -> Result<(), String>,
) -> usize {
    let mut pass = 0;
    for (seed, d) in runs {
        match check(d) {
            Ok(()) => pass += 1,
            Err(e) => eprintln!("{what}, seed {seed}: fails ({e})"),
        }
    }
    eprintln!("{what}: holds on {pass} of {} seeds", runs.len());
    pass
}

/// The headline gap shrinks by at least `min` overall.
fn assert_shrink(d: &Diagnosis, min: f64) {
    let s = d.shrink.expect("finite gaps");
    assert!(s >= min, "shrink {s:.3}:\n{}", d.summary());
}

#[test]
fn cubic_in_the_two_mass_coupling() {
    let d = run(&Case {
        name: "two_mass cubic (m1, m2)",
        truth: &["force nl (m1, m2) = k3 ~ 1.5 * s^3"],
        ..Case::DEFAULT
    });
    assert_found(&d, &[("cubic", "m1", "m2")]);
}

#[test]
fn coulomb_friction_at_the_wall() {
    let d = run(&Case {
        name: "two_mass Coulomb (ground, m1)",
        truth: &["force fr (ground, m1) = r ~ 0.3 * sign(v)"],
        ..Case::DEFAULT
    });
    assert_found(&d, &[("coulomb", "ground", "m1")]);
}

#[test]
fn quadratic_damping_on_a_body_without_a_ground_element() {
    let d = run(&Case {
        name: "two_mass quadratic damping (ground, m2)",
        truth: &["force qd (ground, m2) = q ~ 0.5 * v * abs(v)"],
        ..Case::DEFAULT
    });
    assert_found(&d, &[("quadratic_damping", "ground", "m2")]);
}

#[test]
fn backlash_in_the_chain() {
    let d = run(&Case {
        name: "chain4 backlash (m3, m4)",
        base: CHAIN4,
        truth: &["force bl (m3, m4) = kb ~ 4.0 * deadzone(s, 0.1)"],
        ..Case::DEFAULT
    });
    assert_found(&d, &[("backlash", "m3", "m4")]);
    // The gap profiled, not gridded: DYNID_SEED_OFFSET=0..3 gave the gap −0.4 … +0.8 % and
    // kb −0.7 … +0.3 % off (the grid value alone: gap 0.09–0.107, kb −5.5 … +9.4 %).
    assert_backlash(&d, 0.02, 0.02);
    // docs/detection.md quotes the profiled gap of this case at the table's seed.
    if common::seeds_as_documented() {
        let gap = d.found.iter().find_map(|f| match f.effect {
            dynid::runtime::diagnose::Effect::Backlash { gap } => Some(gap),
            _ => None,
        });
        figures::check(
            "docs/detection.md",
            "diagnose.chain4.backlash_gap",
            gap.expect("a backlash found"),
        );
    }
}

/// The found backlash's profiled gap and stiffness within `tol_gap` and `tol_kb` (relative)
/// of the truth `4.0 * deadzone(s, 0.1)`, and the gap's standard error reported.
fn assert_backlash(d: &Diagnosis, tol_gap: f64, tol_kb: f64) {
    let f = the_one_found(d, "backlash", ("m3", "m4"));
    let dynid::runtime::diagnose::Effect::Backlash { gap } = f.effect else {
        unreachable!("a backlash")
    };
    assert!((gap / 0.1 - 1.0).abs() < tol_gap, "gap {gap}");
    assert!((f.value / 4.0 - 1.0).abs() < tol_kb, "kb {}", f.value);
    assert!(f.shape_stderr.is_some_and(|e| e > 0.0), "{}", d.summary());
}

#[test]
fn prestress_in_the_chain() {
    let d = run(&Case {
        name: "chain4 prestress (ground, m1)",
        base: CHAIN4,
        truth: &["force pre (ground, m1) = f0 ~ 1.0 * sign(s)"],
        ..Case::DEFAULT
    });
    assert_found(&d, &[("prestress", "ground", "m1")]);
}

#[test]
fn asymmetric_spring_at_the_wall() {
    // A hardening spring that is stiffer one way: the model has the cubic term, the
    // quadratic one (force monotonic in s: 3 s² + 2 s + 4 > 0) is withheld.
    let d = run(&Case {
        name: "two_mass asymmetric spring (ground, m1)",
        common: &["force nl (ground, m1) = k3 ~ 1.0 * s^3"],
        truth: &["force asym (ground, m1) = kq ~ 1.0 * s^2"],
        ..Case::DEFAULT
    });
    // Seeds 11–15 (`for o in 0 1 2 3 4; do DYNID_SEED_OFFSET=$o cargo test --test
    // diagnose_withheld -- --nocapture asymmetric; done`): kq = 0.99996 … 1.00016, withheld
    // gap 14.1–15.1 % → 0.1 % (99–100 % removed).
    let f = the_one_found(&d, "quadratic_stiffness", ("ground", "m1"));
    eprintln!("kq = {:.5}", f.value);
    assert!((f.value - 1.0).abs() < 5e-4, "{}", d.summary());
    assert_shrink(&d, 0.95);
}

const TWO_MISSING: Case = Case {
    name: "two_mass cubic (m1, m2) + Coulomb (ground, m1)",
    truth: &[
        "force nl (m1, m2) = k3 ~ 1.5 * s^3",
        "force fr (ground, m1) = r ~ 0.3 * sign(v)",
    ],
    ..Case::DEFAULT
};

/// Both withheld effects, over seeds: a verdict that holds on the seed it was written for
/// need not hold on the next, so it is asserted as a rate. Measured over seeds 11–30
/// (`DYNID_SEEDS=20 cargo test --test diagnose_withheld two_missing -- --nocapture`):
/// Coulomb at (ground, m1) and a hardening element at (m1, m2) on 20 of 20; the element
/// named a cubic spring on 16 of 20 — seeds 12, 14, 16 and 18 take it for backlash (a wide
/// dead zone mimics a cubic spring), remove 86–91 % of the headline gap instead of 100 %,
/// and leave 2.9–6.2 % of it instead of 0.0–0.1 %. The suite runs seeds 11–16, three of
/// the four misses among them: located on 6 of 6, the cubic on 3 of 6.
#[test]
fn two_missing_effects() {
    let runs: Vec<(u64, Diagnosis)> = common::rate_seeds(11, 6)
        .into_iter()
        .map(|seed| (seed, run_at(&TWO_MISSING, seed)))
        .collect();
    let n = runs.len();
    let located = rate("both located", &runs, |d| {
        let cubic = found(
            d,
            &[("cubic", "m1", "m2"), ("coulomb", "ground", "m1")],
            0.8,
        );
        let backlash = found(
            d,
            &[("backlash", "m1", "m2"), ("coulomb", "ground", "m1")],
            0.8,
        );
        cubic.or(backlash)
    });
    let cubic = rate("the cubic named", &runs, |d| {
        found(
            d,
            &[("cubic", "m1", "m2"), ("coulomb", "ground", "m1")],
            0.8,
        )
    });
    assert!(
        6 * located >= 5 * n,
        "both located on {located} of {n} seeds"
    );
    assert!(2 * cubic >= n, "the cubic named on {cubic} of {n} seeds");
}

#[test]
fn coulomb_with_five_percent_noise() {
    let d = run(&Case {
        name: "two_mass Coulomb (m1, m2), 5 % noise",
        truth: &["force fr (m1, m2) = r ~ 0.3 * sign(v)"],
        noise: 0.05,
        ..Case::DEFAULT
    });
    assert_eq!(d.found.len(), 1, "{}", d.summary());
    assert_eq!(d.found[0].effect.kind(), "coulomb", "{}", d.summary());
    assert_eq!(d.found[0].location.label(), "(m1, m2)");
    // Measurement noise stays in the withheld comparison: shrink is measured on the gap
    // above that floor.
    assert_shrink(&d, 0.8);
}

#[test]
fn cubic_from_displacement_only_data() {
    let d = run(&Case {
        name: "chain4 cubic (m1, m2), displacement only",
        base: CHAIN4,
        common: &["measure m1.x, m2.x, m3.x, m4.x, u"],
        truth: &["force nl (m1, m2) = c ~ 3.0 * s^3"],
        ..Case::DEFAULT
    });
    // Velocity candidates are searched too, on velocities estimated from the positions,
    // and must not be taken for the cubic.
    assert!(
        d.ranking.iter().any(|c| c.effect.kind() == "coulomb"),
        "{}",
        d.summary()
    );
    assert_found(&d, &[("cubic", "m1", "m2")]);
}

#[test]
fn a_matching_model_reports_no_effect() {
    let d = run(&Case {
        name: "two_mass, nothing withheld",
        ..Case::DEFAULT
    });
    assert!(d.found.is_empty(), "{}", d.summary());
    assert_eq!(d.verdict, Verdict::Consistent, "{}", d.summary());
    assert!(d.summary().contains("No significant unmodelled effect"));
}

// Input with content between the samples (the input process stepped 10 times per sample,
// recorded at the samples): the free run interpolates the input linearly between samples,
// so even the true model cannot follow the measured path. The statistical gap still falls
// to its floor once the effect is added; the pathwise one keeps the floor of the input it
// cannot see.

#[test]
fn cubic_with_input_between_samples() {
    let d = run(&Case {
        name: "two_mass cubic (m1, m2), input between samples",
        truth: &["force nl (m1, m2) = k3 ~ 1.5 * s^3"],
        oversample: 10,
        ..Case::DEFAULT
    });
    assert_found(&d, &[("cubic", "m1", "m2")]);
}

#[test]
fn backlash_with_input_between_samples() {
    let d = run(&Case {
        name: "chain4 backlash (m3, m4), input between samples",
        base: CHAIN4,
        truth: &["force bl (m3, m4) = kb ~ 4.0 * deadzone(s, 0.1)"],
        oversample: 10,
        ..Case::DEFAULT
    });
    assert_found(&d, &[("backlash", "m3", "m4")]);
    // Input content between samples biases the equations the profile minimises:
    // DYNID_SEED_OFFSET=0..3 gave the gap −6.3 … +6.4 % and kb −4.6 … +6.8 % off (the grid
    // value alone: kb −2.7 … +27 %).
    assert_backlash(&d, 0.16, 0.17);
}

#[test]
fn coulomb_with_input_between_samples() {
    let d = run(&Case {
        name: "two_mass Coulomb (ground, m1), input between samples",
        truth: &["force fr (ground, m1) = r ~ 0.3 * sign(v)"],
        oversample: 10,
        ..Case::DEFAULT
    });
    assert_found(&d, &[("coulomb", "ground", "m1")]);
}

#[test]
fn asymmetric_spring_with_input_between_samples() {
    let d = run(&Case {
        name: "two_mass asymmetric spring (ground, m1), input between samples",
        common: &["force nl (ground, m1) = k3 ~ 1.0 * s^3"],
        truth: &["force asym (ground, m1) = kq ~ 1.0 * s^2"],
        oversample: 10,
        ..Case::DEFAULT
    });
    // The nominal model misses only by 2.1–3.4 %, 3–4 times the floor that even the true
    // model keeps here (0.5–0.7 %, `a_matching_model_with_input_between_samples`): overall
    // 81 / 60 / 77 % removed on seeds 11 / 12 / 13, short of 80 %. What the effect adds
    // to the re-identified model is measured instead: 91 / 91 / 92 %.
    the_one_found(&d, "quadratic_stiffness", ("ground", "m1"));
    let s = d.effect_shrink.expect("finite gaps");
    assert!(s >= 0.8, "effect shrink {s:.3}:\n{}", d.summary());
}

#[test]
fn a_matching_model_with_input_between_samples() {
    let d = run(&Case {
        name: "two_mass, nothing withheld, input between samples",
        oversample: 10,
        ..Case::DEFAULT
    });
    assert!(d.found.is_empty(), "{}", d.summary());
    assert_eq!(d.verdict, Verdict::Consistent, "{}", d.summary());
}

#[test]
fn a_level_without_response_is_unavailable_not_nan() {
    let ir = dynid::dsl_parser::compile_str("two_mass", TWO_MASS).expect("compiles");
    let cfg = SimConfig {
        duration: 100.0,
        burn_in: 50.0,
        seed: common::seed(11),
        ..Default::default()
    };
    let mut records = simulate(&ir, &cfg).expect("simulates").records;
    let origins: Vec<String> = (1..=records.len()).map(|k| format!("level{k}")).collect();
    // Level 1 with every column zero (no excitation at all) is refused up front.
    let mut dead = records.clone();
    for c in dead[0].columns.iter_mut() {
        c.iter_mut().for_each(|v| *v = 0.0);
    }
    let refused = diagnose(
        &ir,
        &dead,
        &origins,
        &DiagnoseOptions::default(),
        &|_, _| {},
    );
    let Err(err) = refused else {
        panic!("a level without any motion must be refused");
    };
    assert!(
        matches!(
            err,
            dynid::runtime::diagnose::DiagnoseError::Identify(
                dynid::runtime::IdentifyError::NoExcitation { .. }
            )
        ),
        "{err:?}"
    );
    // Level 1 with the input kept but no motion (a blocked axis): its gap is unavailable.
    let input = records[0]
        .names
        .iter()
        .position(|n| n == "u")
        .expect("input column");
    for (k, c) in records[0].columns.iter_mut().enumerate() {
        if k != input {
            c.iter_mut().for_each(|v| *v = 0.0);
        }
    }
    let d = diagnose(
        &ir,
        &records,
        &origins,
        &DiagnoseOptions::default(),
        &|_, _| {},
    )
    .expect("diagnoses");
    let text = d.summary();
    let json = serde_json::to_string(&d).expect("serialises");
    let html = dynid::plot::render_html(&d);
    for out in [&text, &json, &html] {
        assert!(!has_word(out, "NaN") && !has_word(out, "inf"), "{out}");
    }
    assert!(d.nominal.levels[0].gap.is_none(), "{text}");
    assert!(text.contains("level1: no response signal varies"), "{text}");
    assert!(d.gap_before.is_finite(), "{text}");
}

/// Whether `word` occurs in `text` with no letter on either side.
fn has_word(text: &str, word: &str) -> bool {
    text.match_indices(word).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let after = text[i + word.len()..].chars().next();
        !before.is_some_and(char::is_alphabetic) && !after.is_some_and(char::is_alphabetic)
    })
}
