//! Shape parameters by variable projection: the backlash gap of `models/backlash.dyn`
//! (0.1) identified as an unknown `deadzone(s, g ~ 0.05)` from a start a factor 2 off,
//! with the stiffnesses solved at every trial gap.
//!
//! The figures of docs/method.md ("Shape parameters by variable projection") come from
//! here: the default run checks seed 2 (its gap and stiffness as the doc quotes them); the
//! long form, `DYNID_SHAPE_LONG=1 cargo test --release --test shape_profile --
//! --nocapture`, runs seeds 1–8 and checks the ranges, the count within one standard error
//! and the worst seed. Measured there (noise-free, 300 s per level): g from −12 % to
//! +4.3 % of the truth, kb from −4 % to +12.6 %. The profile is flat where the gap trades
//! against the two stiffnesses, so a small systematic equation error moves its minimum:
//! seven seeds of eight lie within one reported standard error, seed 5 (g = 0.0883) lies
//! 6.7 of them away (the leave-one-level-out profiles agree with it). The bounds below
//! (20 % on g and kb) are about twice the largest error of the eight seeds.

mod common;
mod figures;

const TRUTH: &str = include_str!("../models/backlash.dyn");

/// Where the figures stand.
const DOC: &str = "docs/method.md";

/// One seed's profiled gap: `(g, se(g), kb)`.
fn profile(seed: u64) -> (f64, f64, f64) {
    let truth = dynid::dsl_parser::compile_str("backlash.dyn", TRUTH).unwrap();
    let model_src = TRUTH.replace("deadzone(s, 0.1)", "deadzone(s, g ~ 0.05)");
    let model = dynid::dsl_parser::compile_str("backlash_g.dyn", &model_src).unwrap();
    assert_eq!(model.shapes.len(), 1);
    assert_eq!(
        model.unknowns().len(),
        3,
        "the gap is not a least-squares column"
    );
    let recs = common::simulate(&truth, 300.0, 0.0, seed);
    let id = common::identify_records(&model, &recs);
    let g = &id.shapes[0];
    let se = g.stderr.expect("a resolved gap has a standard error");
    let kb = id.param("kb").unwrap();
    eprintln!(
        "seed {seed}: g = {:.5} ± {se:.5} ({:+.1} %, {:.1} standard errors), \
         kb = {:.4} ± {:.4} ({:+.1} %), k = {:.4}",
        g.value,
        100.0 * (g.value / 0.1 - 1.0),
        (g.value - 0.1).abs() / se,
        kb.value,
        kb.stderr,
        100.0 * (kb.value / 4.0 - 1.0),
        id.param("k").unwrap().value
    );
    assert!((g.value - 0.1).abs() < 0.2 * 0.1, "gap {}", g.value);
    assert!((kb.value - 4.0).abs() < 0.2 * 4.0, "kb {}", kb.value);
    // The linear estimates' errors carry the gap's: kb's is not the conditional 0.01 %.
    assert!(
        kb.stderr > 0.1 * (kb.value - 4.0).abs(),
        "kb ± {}",
        kb.stderr
    );
    // Every trial of the search is kept, and the start was improved on.
    assert!(g.profile.len() > 10);
    let at_start = g
        .profile
        .iter()
        .find(|t| t.0 == 0.05)
        .expect("the start is tried")
        .1;
    assert!(id.ssr < at_start);
    (g.value, se, kb.value)
}

#[test]
fn the_backlash_gap_is_profiled_from_a_start_a_factor_two_off() {
    let long = std::env::var_os("DYNID_SHAPE_LONG").is_some();
    let seeds: Vec<u64> = if long { (1..=8).collect() } else { vec![2] };
    let runs: Vec<(u64, (f64, f64, f64))> = seeds.iter().map(|&s| (s, profile(s))).collect();
    if !common::seeds_as_documented() {
        return;
    }
    let pct = |x: f64, truth: f64| 100.0 * (x / truth - 1.0);
    let (_, (g, se, kb)) = *runs.iter().find(|r| r.0 == 2).expect("seed 2 runs");
    figures::check(DOC, "shape.seed2.g", g);
    figures::check(DOC, "shape.seed2.g_stderr", se);
    figures::check(DOC, "shape.seed2.kb", kb);
    if long {
        let range = |f: &dyn Fn(&(f64, f64, f64)) -> f64| {
            let v: Vec<f64> = runs.iter().map(|r| f(&r.1)).collect();
            (
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            )
        };
        let (g_lo, g_hi) = range(&|r| pct(r.0, 0.1));
        let (kb_lo, kb_hi) = range(&|r| pct(r.2, 4.0));
        figures::check(DOC, "shape.g.lo", g_lo);
        figures::check(DOC, "shape.g.hi", g_hi);
        figures::check(DOC, "shape.kb.lo", kb_lo);
        figures::check(DOC, "shape.kb.hi", kb_hi);
        let z = |r: &(f64, f64, f64)| (r.0 - 0.1).abs() / r.1;
        let within = runs.iter().filter(|r| z(&r.1) <= 1.0).count();
        figures::check(DOC, "shape.within_one_se", within as f64);
        let worst = runs
            .iter()
            .max_by(|a, b| z(&a.1).total_cmp(&z(&b.1)))
            .expect("seeds ran");
        figures::check(DOC, "shape.worst.seed", worst.0 as f64);
        figures::check(DOC, "shape.worst.z", z(&worst.1));
    }
}

#[test]
fn a_model_with_a_shape_parameter_prints_and_compiles_back() {
    let src = std::fs::read_to_string(common::model_path("backlash_gap.dyn")).unwrap();
    let ir = dynid::dsl_parser::compile_str("backlash_gap.dyn", &src).unwrap();
    let text = dynid::dsl_parser::print::to_source(&ir);
    assert!(text.contains("deadzone(s, g ~ 0.1)"), "{text}");
    let again = dynid::dsl_parser::compile_str("again.dyn", &text).unwrap();
    assert_eq!(again.shapes, ir.shapes);
    // A known gap written as a parameter is a number; an unknown one without a start is an
    // error that says what to write.
    let known = src.replace("g ~ 0.1", "g = 0.1");
    assert!(dynid::dsl_parser::compile_str("k.dyn", &known)
        .unwrap()
        .shapes
        .is_empty());
    let bare = src.replace(
        "force gap (ground, m) = kb ~ 4.0 * deadzone(s, g ~ 0.1)",
        "param g\n    force gap (ground, m) = kb ~ 4.0 * deadzone(s, g)",
    );
    let e = dynid::dsl_parser::compile_str("b.dyn", &bare).unwrap_err();
    assert!(e.errors[0].help_text().contains("g ~ 0.01"), "{e:?}");
}
