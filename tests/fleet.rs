//! The fleet's view on a synthetic fleet: 200 one-mass axes
//! `m x'' + fv v + fc sign(v) + k x = u` (m = 1 kg known), their parameters scattered 3 %
//! around the nominal from part to part, five of them with a fault — friction doubled
//! (three) or 30 % of the stiffness lost (two). Every machine is simulated on its own
//! (three levels of `DURATION` s, 1 % measurement noise on every channel) and identified
//! on its own; the fleet's view must flag exactly the five and name the parameter that
//! moved. The same is checked through the command line on the machines' identification
//! documents, whose report docs/fleet.md shows (`cargo test --test fleet -- --nocapture`
//! prints it).
mod common;
mod figures;

use common::{dynid, stderr};
use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::fleet::{assess, FleetOptions, Machine, MachineEstimate};
use dynid::runtime::ident::Identification;
use dynid::runtime::schema::IdentifyDoc;

/// The doc that shows this fleet's report and quotes its figures.
const DOC: &str = "docs/fleet.md";

const MACHINES: usize = 200;
/// Seconds per level: the shortest record whose slowest filter it fits with room
/// (ω₀ = 2 rad/s).
const DURATION: f64 = 60.0;
/// Relative between-machine scatter of every parameter.
const SCATTER: f64 = 0.03;
/// `(k, fv, fc)` nominal.
const NOMINAL: [f64; 3] = [4.0, 0.4, 0.3];
/// The faulty machines and what moved: `fc` doubled, or `k` down to 70 %.
const FAULTS: [(usize, &str, f64); 5] = [
    (17, "fc", 2.0),
    (58, "k", 0.7),
    (101, "fc", 2.0),
    (150, "k", 0.7),
    (189, "fc", 2.0),
];

fn model(k: f64, fv: f64, fc: f64) -> ModelIr {
    let src = format!(
        "model axis {{
            body m = 1.0
            input u on m
            spring k (ground, m) ~ {k}
            damper fv (ground, m) ~ {fv}
            force friction (ground, m) = fc ~ {fc} * sign(v)
            excite u: lowpass(corner = 10) levels [6, 15, 40]
        }}"
    );
    dynid::dsl_parser::compile_str("axis", &src).expect("valid model")
}

/// Standard normal numbers from a seed (splitmix64 and Box–Muller): the draws of the
/// parameters do not depend on any crate's generator.
fn normals(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    let mut uniform = || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (u1, u2) = (uniform(), uniform());
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        })
        .collect()
}

/// The parameters of machine `i`: scattered around the nominal, with its fault.
fn truth(i: usize) -> [f64; 3] {
    let g = normals(common::seed(1000 + i as u64), 3);
    let mut p = NOMINAL;
    for (p, g) in p.iter_mut().zip(&g) {
        *p *= 1.0 + SCATTER * g;
    }
    if let Some(&(_, name, factor)) = FAULTS.iter().find(|f| f.0 == i) {
        p[["k", "fv", "fc"].iter().position(|n| *n == name).unwrap()] *= factor;
    }
    p
}

/// Machine `i` simulated and identified with the fleet's model `fleet`.
fn identify_machine(fleet: &ModelIr, i: usize) -> Identification {
    let [k, fv, fc] = truth(i);
    let recs = common::simulate(&model(k, fv, fc), DURATION, 0.01, 7000 + i as u64);
    common::identify_with(fleet, &recs, &Default::default())
        .unwrap_or_else(|e| panic!("machine {i}: {e}"))
}

/// Every machine identified, on all cores (the machines are independent).
fn identify_fleet(fleet: &ModelIr) -> Vec<Identification> {
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let mut out: Vec<Option<Identification>> = (0..MACHINES).map(|_| None).collect();
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    (t..MACHINES)
                        .step_by(threads)
                        .map(|i| (i, identify_machine(fleet, i)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        for h in handles {
            for (i, id) in h.join().unwrap() {
                out[i] = Some(id);
            }
        }
    });
    out.into_iter().map(Option::unwrap).collect()
}

fn name(i: usize) -> String {
    format!("m{i:03}")
}

#[test]
fn the_fleet_view_flags_exactly_the_five_faulty_machines_and_names_what_moved() {
    let fleet = model(NOMINAL[0], NOMINAL[1], NOMINAL[2]);
    let ids = identify_fleet(&fleet);
    let machines: Vec<Machine> = ids
        .iter()
        .enumerate()
        .map(|(i, id)| Machine {
            name: name(i),
            estimate: Ok(MachineEstimate::from_identification(id)),
        })
        .collect();
    let view = assess(&machines, &FleetOptions::default()).unwrap();
    let flagged: Vec<&str> = view.flagged().map(|m| m.name.as_str()).collect();
    let faulty: Vec<String> = FAULTS.iter().map(|f| name(f.0)).collect();
    assert_eq!(flagged, faulty, "{view:#?}");
    for &(i, param, factor) in &FAULTS {
        let m = view.machine(&name(i)).unwrap();
        // The fault is the parameter that moved most (and the only one: the others keep
        // their values, and their estimates are unbiased by the fault).
        let moved: Vec<&str> = m.moved.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(moved, [param], "{m:#?}");
        let ratio = m.moved[0].ratio.unwrap();
        // The machine's own part scatter (3 %, up to 3 σ) rides on the factor.
        assert!((ratio / factor - 1.0).abs() < 3.0 * SCATTER, "{m:#?}");
    }
    assert!(view.machines.iter().all(|m| m.test.is_some()));
    // The fleet's model: its centre the nominal (standard error 3 %/√195 = 0.2 %, the
    // bound 3 of them), its between-machine spread the 3 % drawn (a standard deviation from
    // 195 machines is known to 5 %; bound 3 times that) and well above the machines' own
    // errors — the reason a test with those alone flags healthy machines, below.
    for (p, nominal) in view.params.iter().zip(NOMINAL) {
        assert!((p.value / nominal - 1.0).abs() < 3.0 * 0.002, "{p:?}");
        assert!((p.spread / nominal / SCATTER - 1.0).abs() < 0.15, "{p:?}");
        assert!(p.within < p.spread, "{p:?}");
    }
    let naive = assess(
        &machines,
        &FleetOptions {
            between: false,
            ..Default::default()
        },
    )
    .unwrap();
    let naive_count = naive.flagged().count();
    println!(
        "against the pooled value with each machine's own covariance alone: {naive_count} of {MACHINES} flagged"
    );
    assert!(naive_count > 50, "{naive_count}");
    // The figures docs/fleet.md quotes: the thresholds for this fleet, the range over the
    // parameters of the machines' own standard errors (the report's `within`, relative),
    // and the count of the test without `Σ` (on the seeds the doc was written for).
    figures::check(DOC, "fleet.critical_d2", view.critical_d2);
    figures::check(DOC, "fleet.critical_z", view.critical_z);
    if common::seeds_as_documented() {
        let within: Vec<f64> = view
            .params
            .iter()
            .map(|p| 100.0 * p.within / p.value.abs())
            .collect();
        let lo = within.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = within.iter().copied().fold(0.0, f64::max);
        println!("machines' own standard errors (rms over the held machines): {lo:.3} … {hi:.3} %");
        figures::check(DOC, "fleet.machine_stderr.lo", lo);
        figures::check(DOC, "fleet.machine_stderr.hi", hi);
        figures::check(DOC, "fleet.naive_flagged", naive_count as f64);
    }

    // The same through the command line, from the machines' identification documents.
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<std::path::PathBuf> = ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let path = dir.path().join(format!("{}.json", name(i)));
            let value = serde_json::to_value(IdentifyDoc::new(id)).unwrap();
            std::fs::write(&path, serde_json::to_string_pretty(&value).unwrap()).unwrap();
            path
        })
        .collect();
    let out = dir.path().join("fleet.json");
    let o = dynid()
        .arg("fleet")
        .args(&files)
        .arg("--json")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    println!("$ dynid fleet m000.json … m199.json --json fleet.json\n{text}");
    for f in &faulty {
        assert!(text.contains(&format!("  {f} ")), "{text}");
    }
    if common::seeds_as_documented() {
        report_as_shown(&text);
    }
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(doc["schema_version"], 2);
    let cli_flagged: Vec<&str> = doc["machines"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["status"] == "flagged")
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(cli_flagged, flagged);
    // The documents hold the parameters in another order (sorted by name): d² does not
    // depend on it, and the documents carry every digit.
    for (m, v) in doc["machines"]
        .as_array()
        .unwrap()
        .iter()
        .zip(&view.machines)
    {
        let d2 = m["test"]["d2"].as_f64().unwrap();
        let want = v.test.as_ref().unwrap().d2;
        assert!((d2 - want).abs() <= 1e-9 * want.max(1.0), "{m} {v:?}");
    }
    for p in &view.params {
        assert!(doc["between"][&p.name][&p.name].as_f64().unwrap() > 0.0);
    }
}

/// The report of `dynid fleet` printed `text` as docs/fleet.md shows it: its code block
/// that starts with `Fleet of 200`, line for line (trailing blanks aside).
fn report_as_shown(text: &str) {
    let doc = std::fs::read_to_string(figures::root().join(DOC)).unwrap();
    let start = doc
        .find("```\nFleet of ")
        .unwrap_or_else(|| panic!("{DOC}: no code block starting with `Fleet of `"));
    let block = &doc[start + 4..];
    let block = &block[..block.find("```").expect("the code block is closed")];
    let lines = |t: &str| -> Vec<String> {
        let mut v: Vec<String> = t.lines().map(|l| l.trim_end().to_string()).collect();
        while v.last().is_some_and(String::is_empty) {
            v.pop();
        }
        v
    };
    let (shown, printed) = (lines(block), lines(text));
    for (i, (a, b)) in shown.iter().zip(&printed).enumerate() {
        assert_eq!(
            a,
            b,
            "{DOC}: line {} of the fleet's report differs from what `dynid fleet` prints \
             (update the doc or find what changed); printed:\n{text}",
            i + 1
        );
    }
    assert_eq!(
        shown.len(),
        printed.len(),
        "{DOC}: the fleet's report has another number of lines than `dynid fleet` prints:\n{text}"
    );
}

/// A hand-written identification document of the one-mass axis (`fc` left out where
/// `identified_fc` is false).
fn document(k: f64, identified_fc: bool) -> serde_json::Value {
    let mut params = serde_json::json!({
        "k": {"value": k, "stderr": 0.01, "significant": true},
        "fv": {"value": 0.4, "stderr": 0.004, "significant": true},
    });
    let mut cov = serde_json::json!({
        "k": {"k": 1e-4, "fv": 0.0},
        "fv": {"k": 0.0, "fv": 1.6e-5},
    });
    let mut unident = serde_json::json!([]);
    if identified_fc {
        params["fc"] = serde_json::json!({"value": 0.3, "stderr": 0.003, "significant": true});
        cov["k"]["fc"] = 0.0.into();
        cov["fv"]["fc"] = 0.0.into();
        cov["fc"] = serde_json::json!({"k": 0.0, "fv": 0.0, "fc": 9e-6});
    } else {
        unident = serde_json::json!([{"name": "fc", "reason": "its column is zero"}]);
    }
    serde_json::json!({
        "schema_version": 2,
        "parameters": params,
        "covariance": cov,
        "unidentifiable": unident,
        "residual": {"m": [0.01, 0.01, 0.01]},
    })
}

#[test]
fn fleet_documents_of_other_models_versions_and_failed_identifications_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, v: &serde_json::Value| {
        let p = dir.path().join(name);
        std::fs::write(&p, v.to_string()).unwrap();
        p
    };
    let mut files: Vec<std::path::PathBuf> = (0..12)
        .map(|i| {
            write(
                &format!("a{i:02}.json"),
                &document(4.0 + 0.01 * i as f64, true),
            )
        })
        .collect();
    let run = |files: &[std::path::PathBuf], extra: &[&str]| {
        dynid()
            .arg("fleet")
            .args(files)
            .args(extra)
            .output()
            .unwrap()
    };
    // A rank-deficient machine is listed, not dropped; NAME=FILE names a machine.
    let mut with = files.clone();
    with.push(write("b.json", &document(4.0, false)));
    let mut named = with.clone();
    named.push(format!("spare={}", files[0].display()).into());
    let o = run(&named, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let b = text
        .lines()
        .find(|l| l.starts_with("  b "))
        .unwrap_or_default();
    assert!(
        b.ends_with("not identified: `fc` (its column is zero)"),
        "{text}"
    );
    assert!(text.contains("14 machine(s): 13 tested"), "{text}");

    let mut other = document(4.0, true);
    other["residual"] = serde_json::json!({"m2": [0.01]});
    files.push(write("other.json", &other));
    let e = stderr(&run(&files, &[]));
    assert!(
        e.contains("is not of the same model as a00: its equations differ"),
        "{e}"
    );
    files.pop();

    let mut old = document(4.0, true);
    old["schema_version"] = 1.into();
    files.push(write("old.json", &old));
    let e = stderr(&run(&files, &[]));
    assert!(
        e.contains("schema version 1; this version of dynid reads version 2"),
        "{e}"
    );
    files.pop();

    let mut bare = document(4.0, true);
    bare.as_object_mut().unwrap().remove("covariance");
    files.push(write("bare.json", &bare));
    let e = stderr(&run(&files, &[]));
    assert!(
        e.contains("bare.json: the document has no `covariance`"),
        "{e}"
    );
    files.pop();

    files.push(write(
        "detect.json",
        &serde_json::json!({"schema_version": 2, "detection": {}}),
    ));
    let out = dir.path().join("out.json");
    let o = run(&files, &["--json", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no `parameters`"), "{}", stderr(&o));
    assert!(!out.exists());
    files.pop();

    let e = stderr(&run(&files, &["--alpha", "2"]));
    assert!(e.contains("α = 2 is not between 0 and 1"), "{e}");
}
