//! Detection end to end: each nonlinear model is simulated with the project simulator at
//! its three excitation levels, its linear counterpart is identified per level, and the
//! verdict and the implied nonlinear parameter are checked against the truth.
//!
//! Each bound is about 2–3 times the error measured over five seeds, the test's own and the
//! four after it: `for o in 0 1 2 3 4; do DYNID_SEED_OFFSET=$o cargo test --test
//! detect_models -- --nocapture; done` prints the implied parameters (the verdicts, not the
//! bounds, fail on some of the other seeds: they hold on the seeds tried).

mod common;
mod detect_common;
mod figures;

use dynid::dsl_parser::{compile_str, ir::ModelIr};
use dynid::runtime::detect::{Detection, LevelFits, Verdict};
use dynid::runtime::record::Record;

use detect_common::{detect_levels, finding, model};

fn sim(truth: &str, duration: f64, seed: u64) -> Vec<Record> {
    sim_ir(&model(truth), duration, seed)
}

fn sim_ir(ir: &ModelIr, duration: f64, seed: u64) -> Vec<Record> {
    detect_common::simulate_levels(ir, duration, common::seed(seed))
}

fn run(linear: &str, records: &[Record], balance: bool) -> (Detection, LevelFits) {
    detect_levels(&model(linear), records, balance)
}

fn run_ir(ir: &ModelIr, records: &[Record], balance: bool) -> (Detection, LevelFits) {
    detect_levels(ir, records, balance)
}

/// The verdict's template and its implied effect parameters by name.
fn best(d: &Detection, element: &str) -> (String, Vec<(String, f64)>) {
    let f = finding(d, element);
    let name = match &f.verdict {
        Verdict::Nonlinear { best, .. } => best.clone(),
        v => panic!(
            "{element}: expected a nonlinear verdict, got {v}\n{}",
            d.render_table()
        ),
    };
    let est = f.ranking[0]
        .effect_estimates()
        .iter()
        .map(|e| (e.name.clone(), e.value))
        .collect();
    (name, est)
}

fn implied(est: &[(String, f64)], name: &str) -> f64 {
    est.iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no estimate {name} in {est:?}"))
        .1
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b) / b
}

/// The doc whose table of measured verdicts these tests produce (seed 7), and the figure of
/// the default part of the detection matrix.
const DOC: &str = "docs/detection.md";

/// Check the figure marked `name` in docs/detection.md, which quotes the tests' own seeds:
/// only when they run on those.
fn doc_figure(name: &str, measured: f64) {
    if common::seeds_as_documented() {
        figures::check(DOC, name, measured);
    }
}

/// Simulate `truth`, detect on `linear`, check the verdict at `element` and the implied
/// parameters against the truth within `tol` (relative); `expect` holds each parameter's
/// truth and the name of its figure in docs/detection.md.
fn check(
    truth: &str,
    linear: &str,
    element: &str,
    template: &str,
    expect: &[(&str, f64, &str)],
    tol: f64,
) {
    let recs = sim(truth, DURATION, 7);
    let (d, _) = run(linear, &recs, false);
    println!("{truth}:\n{}", d.render_table());
    let (name, est) = best(&d, element);
    assert_eq!(name, template, "{truth}\n{}", d.render_table());
    for (p, t, figure) in expect {
        let e = rel(implied(&est, p), *t);
        println!(
            "{truth}: {p} = {:.4} (truth {t}, {:+.1} %)",
            implied(&est, p),
            100.0 * e
        );
        assert!(e.abs() < tol, "{truth}: {p} off by {:.1} %", 100.0 * e);
        doc_figure(figure, implied(&est, p));
    }
}

/// Seconds per level: long enough that every verdict below held on the seeds tried.
const DURATION: f64 = 400.0;

#[test]
fn duffing_is_cubic_at_the_spring() {
    // The hardening spring makes s light-tailed at the loudest level; linearised over the
    // measured distribution of s the implied k3 is 2.08 (a Gaussian s gave 1.50).
    check(
        "sdof_duffing",
        "sdof_linear",
        "k/d (ground, m)",
        "cubic stiffness",
        &[("k3", 2.0, "detect.models.duffing.k3")],
        // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): k3 +4.3, −6.8, −0.4, −1.1, −1.0 %.
        0.10,
    );
}

#[test]
fn coulomb_is_friction_at_the_damper() {
    check(
        "sdof_coulomb",
        "sdof_linear",
        "k/d (ground, m)",
        "Coulomb friction",
        &[("r", 0.3, "detect.models.coulomb.r")],
        // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): r +2.2, −1.5, −0.1, +2.9, +0.9 %.
        0.06,
    );
}

#[test]
fn quadratic_damping_is_found() {
    check(
        "quadratic_damping",
        "quadratic_damping_linear",
        "k/d (ground, m)",
        "quadratic damping",
        &[("c", 0.2, "detect.models.quadratic_damping.c")],
        // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): c −0.2, −4.4, −4.3, −2.2, −6.2 %.
        0.12,
    );
}

#[test]
fn prestress_is_found() {
    check(
        "prestress",
        "prestress_linear",
        "d/k (ground, m)",
        "prestress",
        &[("f0", 0.5, "detect.models.prestress.f0")],
        // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): f0 −0.9, −0.2, −2.3, −3.4, −1.1 %.
        0.07,
    );
}

/// The gap and the stiffness trade off along three points, so the two are not resolved
/// separately: over seeds 7–10 (`DYNID_SEED_OFFSET=0…3`) kb is off by −17, −36, −7, −54 %
/// and g by +20, +56, +6, +129 % (on seed 11 the verdict is not backlash). A bound on the
/// values would have to pass almost anything; what the test checks is that the stated
/// errors (from the joint covariance of the coefficient and the log gap) say so, i.e.
/// that the truth lies within three of them (seeds 7–10: kb −0.04, −0.37, −0.02, −1.74
/// errors, g +0.03, +0.23, +0.01, +0.71).
#[test]
fn backlash_is_found() {
    let recs = sim("backlash", DURATION, 7);
    let (d, _) = run("backlash_linear", &recs, false);
    println!("backlash:\n{}", d.render_table());
    let (name, _) = best(&d, "k/d (ground, m)");
    assert_eq!(name, "backlash", "{}", d.render_table());
    let top = &finding(&d, "k/d (ground, m)").ranking[0];
    for (p, t, figure, figure_se) in [
        (
            "kb",
            4.0,
            "detect.models.backlash.kb",
            "detect.models.backlash.kb_stderr",
        ),
        (
            "g",
            0.1,
            "detect.models.backlash.g",
            "detect.models.backlash.g_stderr",
        ),
    ] {
        let e = top
            .effect_estimates()
            .iter()
            .find(|e| e.name == p)
            .unwrap_or_else(|| panic!("no estimate {p}"));
        let z = (e.value - t) / e.stderr;
        println!(
            "backlash: {e} (truth {t}, {:+.1} %, {z:+.2} errors)",
            100.0 * rel(e.value, t)
        );
        assert!(z.abs() < 3.0, "backlash: {e}, truth {t}");
        doc_figure(figure, e.value);
        doc_figure(figure_se, e.stderr);
    }
}

/// Both effects in one element at three levels: the cubic spring is the verdict, the
/// friction is reported as suspected (the damping curve drifts too, and the pair ranks
/// second with r ≈ 0.2 of 0.3). Over seeds 7, 8, 9 the pair won once at three levels
/// (`cargo run --release --example detect_measurements -- cubic_coulomb_level_count`).
#[test]
fn cubic_and_coulomb_in_one_element() {
    let recs = sim("sdof_cubic_coulomb", DURATION, 7);
    let (d, _) = run("sdof_linear", &recs, false);
    println!("{}", d.render_table());
    let (name, est) = best(&d, "k/d (ground, m)");
    assert_eq!(name, "cubic stiffness");
    println!("k3 = {:.4} (truth 2.0)", implied(&est, "k3"));
    // Seeds 7 and 9, where this verdict holds (`DYNID_SEED_OFFSET=0, 2`): k3 +2.4, −1.8 %.
    assert!(rel(implied(&est, "k3"), 2.0).abs() < 0.06, "{est:?}");
    doc_figure("detect.models.cubic_coulomb.k3", implied(&est, "k3"));
    let f = finding(&d, "k/d (ground, m)");
    let sus = f.suspected.as_ref().expect("the friction is suspected");
    assert_eq!(sus.effect, "Coulomb friction");
    assert_eq!(sus.curve, "d");
    let pair = f
        .ranking
        .iter()
        .find(|t| t.name == "cubic stiffness + Coulomb friction")
        .unwrap();
    let r = pair
        .effect_estimates()
        .iter()
        .find(|e| e.name == "r")
        .unwrap()
        .value;
    println!("pair: r = {r:.3} (truth 0.3)");
    // The friction shows in the pair fit, low (seeds 7, 9: r −29, −22 %).
    assert!(rel(r, 0.3).abs() < 0.6, "r = {r}");
    doc_figure("detect.models.cubic_coulomb.pair_r", r);
    doc_figure(
        "detect.models.cubic_coulomb.pair_rank",
        sus.pair_rank as f64,
    );
    doc_figure(
        "detect.models.cubic_coulomb.pair_delta_aicc",
        sus.pair_delta_aicc,
    );
}

/// With four levels over the same range the pair is the verdict (seeds 7, 8, 9 all, and
/// with 5, 6, 7 levels too): k3 within 3 %, r 0.21–0.29 of 0.3.
#[test]
fn cubic_and_coulomb_separate_at_four_levels() {
    let ir = cubic_coulomb_levels(4);
    let recs = sim_ir(&ir, DURATION, 7);
    let (d, _) = run("sdof_linear", &recs, false);
    println!("{}", d.render_table());
    let (name, est) = best(&d, "k/d (ground, m)");
    assert_eq!(name, "cubic stiffness + Coulomb friction");
    println!(
        "four levels: k3 = {:.4} (truth 2.0), r = {:.4} (truth 0.3)",
        implied(&est, "k3"),
        implied(&est, "r")
    );
    // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): k3 −4.6, −2.7, −3.4, −1.1, +2.3 %; r −23, −15,
    // −30, −4, −15 %: low throughout (mean −18 %, sd 10 %), so its bound is one-sided.
    assert!(rel(implied(&est, "k3"), 2.0).abs() < 0.1, "{est:?}");
    let r = rel(implied(&est, "r"), 0.3);
    assert!(r > -0.45 && r < 0.1, "{est:?}");
    doc_figure("detect.models.four_levels.k3", implied(&est, "k3"));
    doc_figure("detect.models.four_levels.r", implied(&est, "r"));
}

/// two_mass hides cubic stiffness and Coulomb friction in the coupling: at three levels
/// the coupling's verdict is the cubic spring (k3 = 1.49 of 1.5) with the friction
/// suspected, and the ground element stays linear.
#[test]
fn two_mass_nonlinear_coupling_linear_ground() {
    let recs = sim("two_mass", DURATION, 7);
    let (d, _) = run("two_mass_linear", &recs, false);
    println!("{}", d.render_table());
    assert_eq!(finding(&d, "k1/d1 (ground, m1)").verdict, Verdict::Linear);
    let (name, est) = best(&d, "k2/d2 (m1, m2)");
    assert_eq!(name, "cubic stiffness");
    println!(
        "two_mass coupling: k3 = {:.4} (truth 1.5)",
        implied(&est, "k3")
    );
    // Seeds 7–10 (`DYNID_SEED_OFFSET=0…3`): k3 −1.6, +0.3, +0.1, −0.4 %.
    assert!(rel(implied(&est, "k3"), 1.5).abs() < 0.04, "{est:?}");
    doc_figure("detect.models.two_mass.k3", implied(&est, "k3"));
    let f = finding(&d, "k2/d2 (m1, m2)");
    let sus = f.suspected.as_ref().expect("the friction is suspected");
    assert_eq!(sus.effect, "Coulomb friction");
    assert_eq!(f.ranking[1].name, "cubic stiffness + Coulomb friction");
    let r = f.ranking[1]
        .effect_estimates()
        .iter()
        .find(|e| e.name == "r")
        .expect("the pair's friction")
        .value;
    println!("pair: r = {r:.3} (truth 0.2)");
    doc_figure("detect.models.two_mass.pair_r", r);
    doc_figure("detect.models.two_mass.pair_rank", sus.pair_rank as f64);
    doc_figure(
        "detect.models.two_mass.pair_delta_aicc",
        sus.pair_delta_aicc,
    );
}

/// models/two_mass_friction.dyn (the demo's true system): Coulomb friction in the coupling.
#[test]
fn two_mass_friction_in_the_coupling() {
    check(
        "two_mass_friction",
        "two_mass_linear",
        "k2/d2 (m1, m2)",
        "Coulomb friction",
        &[("r", 0.3, "detect.models.two_mass_friction.r")],
        // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): r +0.1, +4.2, +3.7, +0.5, +5.4 %.
        0.10,
    );
    let (d, _) = run(
        "two_mass_linear",
        &sim("two_mass_friction", DURATION, 7),
        false,
    );
    assert_eq!(finding(&d, "k1/d1 (ground, m1)").verdict, Verdict::Linear);
}

/// chain4 spreads seven terms over four elements. At its three levels the two hardening
/// springs dominate and are found with their k3 (2.0 at (ground, m1), 1.0 at (m2, m3));
/// the weaker terms are not resolved at 400 s per level and must not be misnamed: the
/// quadratic damper of (m1, m2) moves d2 within its error, and at (m3, m4) the backlash
/// (gap 0.05, far below σ_s ≈ 1) and the preload pull the stiffness in opposite directions
/// by about 1 %. Measured (seed 7): k3 +3.9 % and +1.4 %; (m1, m2) and (m3, m4) linear.
#[test]
fn chain4_hardening_springs_are_found() {
    let recs = sim("chain4", DURATION, 7);
    let (d, _) = run("chain4_linear", &recs, false);
    println!("{}", d.render_table());
    for (element, k3) in [("k1/d1 (ground, m1)", 2.0), ("k3/d3 (m2, m3)", 1.0)] {
        let (name, est) = best(&d, element);
        assert_eq!(name, "cubic stiffness", "{element}");
        let e = rel(implied(&est, "k3"), k3);
        println!("chain4 {element}: k3 {:+.1} %", 100.0 * e);
        // Seeds 7, 10, 11 (`DYNID_SEED_OFFSET=0, 3, 4`; the others fail the verdicts):
        // k3 +3.9, +2.0, +3.0 % at (ground, m1) and +1.4, +1.8, +2.9 % at (m2, m3).
        assert!(e.abs() < 0.08, "{element}: k3 off by {:.1} %", 100.0 * e);
    }
    for element in ["k2/d2 (m1, m2)", "k4/d4 (m3, m4)"] {
        match &finding(&d, element).verdict {
            Verdict::Linear => {}
            Verdict::Nonlinear { best, .. } => assert!(
                [
                    "quadratic damping",
                    "backlash",
                    "prestress",
                    "prestress + backlash"
                ]
                .iter()
                .any(|t| best.contains(t)),
                "{element}: {best} is not among its true effects"
            ),
            // Schiehlen & Krause's inverse pair (prestress against backlash) may be reported
            // as such.
            Verdict::Ambiguous { candidates } if element.starts_with("k4") => assert!(
                candidates
                    .iter()
                    .all(|c| c.contains("backlash") || c.contains("prestress")),
                "{element}: {candidates:?}"
            ),
            v => panic!("{element}: {v}"),
        }
    }
}

const FRICTION_AT_GROUND: &str = "
model two_mass_friction {
    body m1 = 1.0
    body m2 ~ 2.0
    input u on m1
    spring k1 (ground, m1) ~ 4.0
    damper d1 (ground, m1) ~ 0.4
    force fr (ground, m1) = r ~ 0.3 * sign(v)
    spring k2 (m1, m2) ~ 3.0
    damper d2 (m1, m2) ~ 0.2
    excite u: lowpass(corner = 10) levels [6, 15, 40]
    filter corners [0.5, 1, 2, 4, 8, 16] order 2
}";

#[test]
fn two_mass_friction_at_ground_only() {
    let truth = compile_str("two_mass_friction", FRICTION_AT_GROUND).unwrap();
    let recs = sim_ir(&truth, DURATION, 7);
    let (d, _) = run("two_mass_linear", &recs, false);
    println!("{}", d.render_table());
    assert_eq!(finding(&d, "k2/d2 (m1, m2)").verdict, Verdict::Linear);
    let (name, est) = best(&d, "k1/d1 (ground, m1)");
    assert_eq!(name, "Coulomb friction");
    let r = implied(&est, "r");
    println!(
        "two_mass_friction at ground: r = {r:.4} (truth 0.3, {:+.1} %)",
        100.0 * rel(r, 0.3)
    );
    // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): r −0.9, +0.9, −4.4, +9.2, −1.2 % (sd 5 %).
    assert!(rel(r, 0.3).abs() < 0.15, "r = {r}");
    doc_figure("detect.models.friction_at_ground.r", r);
}

fn linear_detections(seeds: std::ops::Range<u64>) -> (usize, usize) {
    let two = model("two_mass_linear");
    let sdof = model("sdof_linear");
    let (mut alarms, mut total) = (0, 0);
    for seed in seeds {
        for ir in [&sdof, &two] {
            let recs = sim_ir(ir, DURATION, 1000 + seed);
            let (d, _) = run_ir(ir, &recs, false);
            for e in &d.elements {
                total += 1;
                if e.verdict != Verdict::Linear {
                    alarms += 1;
                    println!("seed {seed} {}: {}", ir.name, e.verdict);
                }
            }
        }
    }
    (alarms, total)
}

/// Three seeds here; 25 seeds with `cargo run --release --example detect_measurements --
/// false_positive_rate`.
#[test]
fn linear_systems_give_no_detection() {
    let (alarms, total) = linear_detections(0..3);
    assert_eq!(alarms, 0, "{alarms} of {total} linear elements flagged");
}

const SDOF_POSITIONS_ONLY: &str = "
model sdof_linear_x {
    body m = 1.0
    input u on m
    spring k (ground, m) ~ 4.0
    damper d (ground, m) ~ 0.4
    measure m.x, u
}";

/// σ_v from positions (Rice's zero-crossing rate) against the measured velocity, on a
/// linear and on a friction-damped oscillator; and friction is still detected without
/// velocities.
#[test]
fn sigma_v_from_zero_crossings() {
    let x_only = compile_str("sdof_linear_x", SDOF_POSITIONS_ONLY).unwrap();
    for truth in ["sdof_linear", "sdof_coulomb", "sdof_duffing"] {
        let recs = sim(truth, DURATION, 7);
        let (_, with_v) = run("sdof_linear", &recs, false);
        let (d, no_v) = run_ir(&x_only, &recs, false);
        let (a, b) = (&with_v.input.elements[0], &no_v.input.elements[0]);
        let errs: Vec<f64> = a
            .sigma_v
            .iter()
            .zip(&b.sigma_v)
            .map(|(m, z)| rel(*z, *m))
            .collect();
        println!("{truth}: σ_v zero-crossing error per level {errs:+.4?}");
        // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`), worst level: sdof_linear up to −6.4 %;
        // sdof_coulomb up to −12.5 % and sdof_duffing −12…−16 % at the loudest level (not
        // Gaussian, Rice's formula is biased there).
        let tol = if truth == "sdof_linear" { 0.12 } else { 0.2 };
        for e in &errs {
            assert!(e.abs() < tol, "{truth}: {errs:?}");
        }
        // docs/detection.md ("Intensities") quotes this seed's errors, in %.
        let pct: Vec<f64> = errs.iter().map(|e| 100.0 * e).collect();
        match truth {
            "sdof_linear" => doc_figure(
                "detect.sigma_v.linear_worst",
                pct.iter().fold(0.0, |w: f64, e| w.max(e.abs())),
            ),
            "sdof_coulomb" => doc_figure("detect.sigma_v.coulomb_quietest", pct[0]),
            _ => {
                for (name, e) in [
                    "detect.sigma_v.duffing_1",
                    "detect.sigma_v.duffing_2",
                    "detect.sigma_v.duffing_3",
                ]
                .iter()
                .zip(&pct)
                {
                    doc_figure(name, *e);
                }
            }
        }
        if truth == "sdof_coulomb" {
            let (name, est) = best(&d, "k/d (ground, m)");
            assert_eq!(name, "Coulomb friction");
            let r = implied(&est, "r");
            println!("positions only: r = {r:.4} (truth 0.3)");
            doc_figure("detect.sigma_v.positions_only_r", r);
            // Seeds 7–11 (`DYNID_SEED_OFFSET=0…4`): r −2.4, −4.1, −8.5, −3.8, −5.3 %.
            assert!(rel(r, 0.3).abs() < 0.17, "positions only: r = {r}");
        }
    }
}

/// The prototype system with `n` levels geometrically spaced over 6…40.
fn cubic_coulomb_levels(n: usize) -> ModelIr {
    let mut ir = model("sdof_cubic_coulomb");
    ir.excitation[0].levels = (0..n)
        .map(|i| {
            let t = i as f64 / (n - 1) as f64;
            // Three decimals, as a model file would write them.
            format!("{:.3}", 6.0 * (40.0f64 / 6.0).powf(t))
                .parse()
                .unwrap()
        })
        .collect();
    ir
}

/// The detection matrix: each built-in effect alone at one element of a single mass, of
/// the coupling of two masses and of the middle of a four-mass chain, at the three levels
/// 6/15/40, without and with 5 % measurement noise, over seeds 1–5; and the three linear
/// structures as controls. Prints per case how often the effect was named exactly, with
/// an extra effect, missed, and how often another element was flagged.
///
/// `DYNID_DETECT_MATRIX=1 cargo test --test detect_models matrix -- --nocapture`
/// (`DYNID_MATRIX_SECONDS` sets the seconds per level, default 300).
#[test]
fn matrix() {
    if std::env::var_os("DYNID_DETECT_MATRIX").is_none() {
        return;
    }
    let seconds: f64 = std::env::var("DYNID_MATRIX_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300.0);
    let rows = matrix_rows(&Structure::ALL, &Effect::ALL, &[0.0, 0.05], 1..6, seconds);
    print_matrix(&rows, seconds);
    // The "now" columns of the hit-rate table in docs/detection.md are this matrix at
    // 300 s per level: every cell, the controls and the totals.
    if seconds == 300.0 {
        let doc = std::fs::read_to_string(figures::root().join(DOC)).unwrap();
        let mut controls = [0usize; 2];
        let mut total = [0usize; 4];
        for r in &rows {
            let c = counts(r);
            let col = noise_column(r.noise);
            match r.effect {
                Some(_) => {
                    assert_eq!(
                        table_now(&doc, &doc_case(r), col).map(Option::unwrap),
                        c,
                        "{DOC}: the hit-rate row `{}` ({} % noise) is stale: the matrix counts \
                         exact, extra, missed, neighbour = {c:?}",
                        doc_case(r),
                        100.0 * r.noise
                    );
                    for (t, c) in total.iter_mut().zip(c) {
                        *t += c;
                    }
                }
                None => controls[col] += c[3],
            }
        }
        for (col, flagged) in controls.into_iter().enumerate() {
            assert_eq!(
                table_now(&doc, "linear controls (3 structures)", col)[3],
                Some(flagged),
                "{DOC}: the controls' row is stale"
            );
        }
        let names = [
            "detect.matrix.all.exact",
            "detect.matrix.all.extra",
            "detect.matrix.all.missed",
            "detect.matrix.all.neighbour",
        ];
        for (name, n) in names.iter().zip(total) {
            figures::check(DOC, name, n as f64);
        }
    }
}

/// The case of `r` as the first column of the hit-rate table in docs/detection.md names it.
fn doc_case(r: &MatrixRow) -> String {
    let structure = match r.structure {
        Structure::Sdof => "single mass",
        Structure::TwoMass => "two masses",
        Structure::Chain4 => "chain",
    };
    match r.effect {
        Some(e) => format!("{structure}, {}", e.name()),
        None => "linear controls (3 structures)".into(),
    }
}

/// The table's column of a noise level (cells are written `0 % / 5 %`).
fn noise_column(noise: f64) -> usize {
    if noise == 0.0 {
        0
    } else {
        assert_eq!(noise, 0.05, "the table has columns for 0 and 5 % noise");
        1
    }
}

/// A row's counts: exact, extra effect, missed, neighbour flagged.
fn counts(r: &MatrixRow) -> [usize; 4] {
    let n = |f: fn(&Outcome) -> bool| r.outcomes.iter().filter(|o| f(o)).count();
    [
        n(|o| o.exact),
        n(|o| o.extra),
        n(|o| o.missed),
        n(|o| o.neighbour),
    ]
}

/// The "now" cells (exact, extra, missed, neighbour) of the hit-rate table's row `case` in
/// `doc`, at noise column `col`; `None` for a cell written `—`.
fn table_now(doc: &str, case: &str, col: usize) -> [Option<usize>; 4] {
    let line = doc
        .lines()
        .find(|l| l.starts_with(&format!("| {case} |")))
        .unwrap_or_else(|| panic!("{DOC}: no row `{case}` in the hit-rate table"));
    let cells: Vec<&str> = line.split('|').map(str::trim).collect();
    assert!(
        cells.len() >= 10,
        "{DOC}: the row `{case}` has too few cells"
    );
    std::array::from_fn(|k| {
        let cell = cells[6 + k];
        if cell == "—" {
            return None;
        }
        let cell = cell.split(" of ").next().unwrap_or(cell);
        let v = cell.split('/').map(str::trim).nth(col);
        Some(
            v.and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("{DOC}: the cell `{cell}` of `{case}` is not `N / N`")),
        )
    })
}

use detect_common::{classify, detect_case, Effect, Outcome, Structure};

struct MatrixRow {
    case: String,
    structure: Structure,
    effect: Option<Effect>,
    noise: f64,
    outcomes: Vec<Outcome>,
}

fn matrix_rows(
    structures: &[Structure],
    effects: &[Effect],
    noises: &[f64],
    seeds: std::ops::Range<u64>,
    seconds: f64,
) -> Vec<MatrixRow> {
    let mut cases: Vec<(Structure, Option<Effect>, f64)> = Vec::new();
    for &s in structures {
        for &n in noises {
            for &e in effects {
                cases.push((s, Some(e), n));
            }
            cases.push((s, None, n));
        }
    }
    let run = |&(s, e, n): &(Structure, Option<Effect>, f64)| {
        let outcomes = seeds
            .clone()
            .map(|seed| {
                let d = detect_case(&s.source(e), &s.source(None), seconds, n, seed);
                classify(&d, s.element(), e)
            })
            .collect();
        MatrixRow {
            case: format!(
                "{} {} noise {:.0} %",
                s.label(),
                e.map_or("linear", Effect::name),
                100.0 * n
            ),
            structure: s,
            effect: e,
            noise: n,
            outcomes,
        }
    };
    // Two workers: the matrix is dozens of independent simulations.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let out = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|sc| {
        for _ in 0..2 {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(c) = cases.get(i) else { break };
                let row = run(c);
                out.lock()
                    .expect("invariant: no worker panics holding the lock")
                    .push((i, row));
            });
        }
    });
    let mut rows = out.into_inner().expect("invariant: workers joined");
    rows.sort_by_key(|r| r.0);
    rows.into_iter().map(|r| r.1).collect()
}

fn print_matrix(rows: &[MatrixRow], seconds: f64) {
    println!("| case ({seconds} s per level) | named exactly | extra effect | missed | neighbour flagged |");
    println!("|---|---|---|---|---|");
    let count = |r: &MatrixRow, f: fn(&Outcome) -> bool| r.outcomes.iter().filter(|o| f(o)).count();
    for r in rows {
        let n = r.outcomes.len();
        println!(
            "| {} | {}/{n} | {}/{n} | {}/{n} | {}/{n} |",
            r.case,
            count(r, |o| o.exact),
            count(r, |o| o.extra),
            count(r, |o| o.missed),
            count(r, |o| o.neighbour),
        );
    }
}

/// The part of the matrix that runs by default: the hardening spring (where the
/// statistical-linearisation templates read the fit's own damping artefact as a second
/// effect) at the single mass without noise and in the middle of the chain with 5 % noise,
/// with both linear controls, over seeds 1–5 at 300 s per level. Measured by `matrix`
/// (docs/detection.md): named exactly on 5 of 5 seeds in both cases, no extra effect, no
/// neighbour or control flagged; before the estimator's templates, 4 of 5 each with an
/// extra effect on the fifth. The bounds allow one seed fewer in all.
#[test]
fn matrix_hardening_spring() {
    let mut rows = matrix_rows(&[Structure::Sdof], &[Effect::Cubic], &[0.0], 1..6, 300.0);
    rows.extend(matrix_rows(
        &[Structure::Chain4],
        &[Effect::Cubic],
        &[0.05],
        1..6,
        300.0,
    ));
    print_matrix(&rows, 300.0);
    let all: Vec<Outcome> = rows
        .iter()
        .filter(|r| !r.case.contains("linear"))
        .flat_map(|r| r.outcomes.iter().copied())
        .collect();
    let count = |f: fn(&Outcome) -> bool| all.iter().filter(|o| f(o)).count();
    assert_eq!(all.len(), 10);
    assert!(
        count(|o| o.exact) >= 9,
        "named exactly on fewer than 9 of 10"
    );
    assert!(
        count(|o| o.extra) <= 1,
        "an extra effect on more than 1 of 10"
    );
    assert_eq!(count(|o| o.missed), 0, "missed");
    doc_figure("detect.matrix.hardening_exact", count(|o| o.exact) as f64);
    // Its two rows stand in the hit-rate table of docs/detection.md, which the long form
    // (`matrix`) checks whole.
    let doc = std::fs::read_to_string(figures::root().join(DOC)).unwrap();
    for r in rows.iter().filter(|r| r.effect.is_some()) {
        assert_eq!(
            table_now(&doc, &doc_case(r), noise_column(r.noise)).map(Option::unwrap),
            counts(r),
            "{DOC}: the hit-rate row `{}` ({} % noise) is stale",
            doc_case(r),
            100.0 * r.noise
        );
    }
    assert!(
        rows.iter().flat_map(|r| &r.outcomes).all(|o| !o.neighbour),
        "another element (or a linear control) flagged"
    );
}
