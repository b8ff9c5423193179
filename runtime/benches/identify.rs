//! Identification throughput: the two-mass model (cubic stiffness + Coulomb friction) on
//! three levels of 10⁶ samples each, from memory and from CSV files.
//!
//! Run: `cargo bench -p dynid-runtime --features test-support --bench identify`
//! (`DYNID_BENCH_SAMPLES` overrides the samples per level.)

use dynid_runtime::data::{CsvOptions, CsvSource, LevelSource, RecordSource};
use dynid_runtime::ident::{identify, IdentifyOptions, PhaseTimes};
use dynid_runtime::record::Record;
use dynid_runtime::test_support::{simulate_two_mass, two_mass_ir, SimSpec, TwoMass};
use rayon::prelude::*;
use std::io::Write;
use std::time::Instant;

fn shares(t: &PhaseTimes) -> String {
    let parts = [
        ("read/parse", t.read),
        ("filter", t.filter),
        ("evaluate", t.evaluate),
        ("accumulate", t.accumulate),
        ("solve", t.solve),
    ];
    let total: f64 = parts.iter().map(|(_, d)| d.as_secs_f64()).sum();
    parts
        .iter()
        .map(|(n, d)| {
            format!(
                "{n} {:.0}% ({:.3} s)",
                100.0 * d.as_secs_f64() / total,
                d.as_secs_f64()
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn main() {
    let n: usize = std::env::var("DYNID_BENCH_SAMPLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let p = TwoMass::default();
    let ir = two_mass_ir(p);
    let t = Instant::now();
    let recs: Vec<Record> = [6.0, 15.0, 40.0]
        .par_iter()
        .enumerate()
        .map(|(i, &l)| simulate_two_mass(p, SimSpec::new(l, n as f64 * 0.01, 500 + i as u64)))
        .collect();
    eprintln!(
        "simulated 3 × {n} samples in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let total = (3 * n) as f64;
    let opts = IdentifyOptions::default();

    let srcs: Vec<RecordSource> = recs
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, &ir, format!("level {}", i + 1)).unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..3 {
        let t = Instant::now();
        let id = identify(&ir, &levels, &opts).unwrap();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(id);
    }
    let id = last.unwrap();
    println!(
        "memory: {:.3} s for 3 × {n} samples ({:.1} M samples/s) on {} threads; {}",
        best,
        total / best / 1e6,
        rayon::current_num_threads(),
        shares(&id.times)
    );
    for e in &id.params {
        println!("  {:<3} {:>9.4} ± {:.4}", e.name, e.value, e.stderr);
    }

    let dir = std::env::temp_dir().join(format!("dynid-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let paths: Vec<_> = recs
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let path = dir.join(format!("level{i}.csv"));
            let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
            writeln!(f, "t,{}", r.names.join(",")).unwrap();
            for k in 0..r.len() {
                write!(f, "{:.2}", k as f64 * r.ts).unwrap();
                for c in &r.columns {
                    write!(f, ",{:.9e}", c[k]).unwrap();
                }
                writeln!(f).unwrap();
            }
            path
        })
        .collect();
    let t = Instant::now();
    let csvs: Vec<CsvSource> = paths
        .iter()
        .map(|p| CsvSource::open(p, &ir, &CsvOptions::default()).unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = csvs.iter().map(|s| s as &dyn LevelSource).collect();
    let id = identify(&ir, &levels, &opts).unwrap();
    let dt = t.elapsed().as_secs_f64();
    println!(
        "csv:    {:.3} s for 3 × {n} samples ({:.2} M samples/s); {}",
        dt,
        total / dt / 1e6,
        shares(&id.times)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
