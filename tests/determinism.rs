//! The same inputs and seed give byte-identical outputs: `simulate` files, `identify --json`
//! and `diagnose --json`, run after run and whatever the number of threads (the parallel
//! reductions have a fixed order).

mod common;

use common::dynid;
use std::path::Path;

fn model(name: &str) -> String {
    common::model_path(name).display().to_string()
}

/// Run `dynid args` with `threads` worker threads; panics unless it succeeds.
fn run(args: &[&str], threads: usize) -> Vec<u8> {
    let out = dynid()
        .args(args)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "dynid {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn the_same_seed_gives_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = |s: &str| dir.path().join(s).display().to_string();
    let truth = model("sdof_cubic_coulomb.dyn");
    let sim = |out: &str, threads| {
        let args = [
            "simulate",
            &truth,
            "--duration",
            "100",
            "--noise",
            "0.02",
            "--seed",
            "7",
            "--input-oversample",
            "4",
            "--out",
            out,
        ];
        run(&args, threads);
    };
    sim(&d("a"), 1);
    sim(&d("b"), 2);
    for f in ["level_1.csv", "level_2.csv", "level_3.csv", "truth.json"] {
        let (a, b) = (
            read(&dir.path().join("a").join(f)),
            read(&dir.path().join("b").join(f)),
        );
        assert!(a == b, "simulate: {f} differs between runs");
    }

    let levels: Vec<String> = (1..=3).map(|k| d(&format!("a/level_{k}.csv"))).collect();
    let with_levels = |head: &[&str], tail: &[&str]| -> Vec<String> {
        head.iter()
            .map(|s| s.to_string())
            .chain(levels.iter().cloned())
            .chain(tail.iter().map(|s| s.to_string()))
            .collect()
    };
    let json = |cmd: &str, m: &str, name: &str, threads| -> Vec<u8> {
        let out = d(name);
        let args = with_levels(&[cmd, m], &["--json", &out]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args, threads);
        read(Path::new(&out))
    };
    let (i1, i2) = (
        json("identify", &truth, "id1.json", 1),
        json("identify", &truth, "id2.json", 2),
    );
    assert!(
        !i1.is_empty() && i1 == i2,
        "identify --json differs between runs"
    );

    let linear = model("sdof_linear.dyn");
    let (g1, g2) = (
        json("diagnose", &linear, "dg1.json", 2),
        json("diagnose", &linear, "dg2.json", 1),
    );
    assert!(
        !g1.is_empty() && g1 == g2,
        "diagnose --json differs between runs"
    );
}
