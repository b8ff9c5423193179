//! Simulation throughput on `models/two_mass.dyn` (cubic stiffness + Coulomb friction).
//!
//! Run: `cargo bench -p dynid-runtime --bench simulate`
//! (`DYNID_BENCH_SIM_SECONDS=2000` sets the simulated seconds per level.)
//!
//! 1. RK4 sub-steps per second on ONE thread (one level), against a reference measured in
//!    the same run: the same equations of motion written out by hand in Rust with the same
//!    integrator, sub-steps and input interpolation (what generated code at best achieves).
//! 2. Writing CSV: the same simulation (every level, all threads) into CSV files against
//!    into memory, so the ratio shows what text output costs on top of integration.

use dynid_runtime::sim::{self, CsvSink, SampleSink, SimConfig, DEFAULT_SUBSTEPS};
use std::hint::black_box;
use std::io::BufWriter;
use std::path::Path;

mod common;
use common::{bench_env, best_of, print_row};

/// two_mass written out by hand: m1 = 1, m2 = 2, k1 = 4, d1 = 0.4, k2 = 3, d2 = 0.2,
/// k3 = 1.5, r = 0.2; the input `u` on m1.
#[inline(always)]
fn accel(x: [f64; 2], v: [f64; 2], u: f64) -> [f64; 2] {
    let s = x[1] - x[0];
    let w = v[1] - v[0];
    let sign = if w > 0.0 {
        1.0
    } else if w < 0.0 {
        -1.0
    } else {
        0.0
    };
    let coupling = 3.0 * s + 0.2 * w + 1.5 * s * s * s + 0.2 * sign;
    let a1 = u - 4.0 * x[0] - 0.4 * v[0] + coupling;
    let a2 = -coupling / 2.0;
    [a1, a2]
}

/// The reference: RK4 over `input` (linear between samples), `substeps` per interval;
/// returns a checksum of the state so the work is not optimised away.
fn hand_written(input: &[f64], ts: f64, substeps: usize) -> f64 {
    let h = ts / substeps as f64;
    let (h2, h6) = (0.5 * h, h / 6.0);
    let n = substeps as f64;
    let (mut x, mut v) = ([0.0; 2], [0.0; 2]);
    let mut sum = 0.0;
    for w in input.windows(2) {
        let (u0, u1) = (w[0], w[1]);
        for j in 0..substeps {
            let j = j as f64;
            let ua = u0 + (u1 - u0) * j / n;
            let ub = u0 + (u1 - u0) * (j + 0.5) / n;
            let uc = u0 + (u1 - u0) * (j + 1.0) / n;
            let a1 = accel(x, v, ua);
            let xt = [x[0] + h2 * v[0], x[1] + h2 * v[1]];
            let v2 = [v[0] + h2 * a1[0], v[1] + h2 * a1[1]];
            let a2 = accel(xt, v2, ub);
            let xt = [x[0] + h2 * v2[0], x[1] + h2 * v2[1]];
            let v3 = [v[0] + h2 * a2[0], v[1] + h2 * a2[1]];
            let a3 = accel(xt, v3, ub);
            let xt = [x[0] + h * v3[0], x[1] + h * v3[1]];
            let v4 = [v[0] + h * a3[0], v[1] + h * a3[1]];
            let a4 = accel(xt, v4, uc);
            for i in 0..2 {
                x[i] += h6 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
                v[i] += h6 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
            }
        }
        sum += x[0] + x[1];
    }
    sum
}

/// A sink that only counts (so the time is the integration's).
struct Discard(usize);

impl SampleSink for Discard {
    fn begin(&mut self, _: &[String], _: f64) -> std::io::Result<()> {
        Ok(())
    }
    fn push(&mut self, cols: &[&[f64]], len: usize) -> std::io::Result<()> {
        self.0 += len + black_box(cols.len());
        Ok(())
    }
}

fn main() {
    let seconds: f64 = std::env::var("DYNID_BENCH_SIM_SECONDS")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(2000.0);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/two_mass.dyn");
    let ir = dsl_parser::compile_file(&path).expect("models/two_mass.dyn");
    let ts = 0.01;
    let cfg = SimConfig {
        duration: seconds,
        sample: ts,
        seed: 500,
        burn_in: 0.0,
        ..Default::default()
    };

    // 1. One level on one thread.
    let one = SimConfig {
        levels: Some(vec![15.0]),
        ..cfg.clone()
    };
    let samples = sim::total_samples(&one, 1);
    let substeps = samples as f64 * DEFAULT_SUBSTEPS as f64;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let (t_sim, rec) = pool.install(|| {
        best_of(3, || {
            let mut sink = Discard(0);
            sim::simulate_into(&ir, &one, &|_| {}, &mut [&mut sink]).expect("simulation");
            sink.0
        })
    });
    let input = sim::simulate(&ir, &one).expect("simulation").records;
    let u = input[0].column("u").expect("column u").to_vec();
    let (t_ref, _) = best_of(3, || black_box(hand_written(&u, ts, DEFAULT_SUBSTEPS)));
    println!(
        "\n== two_mass, one level × {samples} samples × {DEFAULT_SUBSTEPS} RK4 sub-steps, 1 thread ({rec} written)"
    );
    println!(
        "rk4:  {:.2} M sub-steps/s ({t_sim:.3} s); {:.2}× the hand-written equations ({:.2} M sub-steps/s)",
        substeps / t_sim / 1e6,
        t_sim / t_ref,
        substeps / t_ref / 1e6,
    );

    // 2. Every level, all threads: into memory, then into CSV files.
    let n_levels = sim::level_count(&ir, &cfg).expect("levels");
    let (t_mem, _) = best_of(1, || sim::simulate(&ir, &cfg).expect("simulation"));
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (t_csv, bytes) = best_of(1, || {
        let mut sinks: Vec<CsvSink<BufWriter<std::fs::File>>> = (0..n_levels)
            .map(|k| {
                let f = std::fs::File::create(dir.path().join(format!("level_{k}.csv")))
                    .expect("a CSV file");
                CsvSink::new(BufWriter::with_capacity(1 << 16, f))
            })
            .collect();
        let mut dyns: Vec<&mut dyn SampleSink> =
            sinks.iter_mut().map(|s| s as &mut dyn SampleSink).collect();
        sim::simulate_into(&ir, &cfg, &|_| {}, &mut dyns).expect("simulation");
        drop(dyns);
        for s in sinks {
            use std::io::Write;
            s.into_inner().flush().expect("flush");
        }
        (0..n_levels)
            .map(|k| {
                std::fs::metadata(dir.path().join(format!("level_{k}.csv"))).map_or(0, |m| m.len())
            })
            .sum::<u64>()
    });
    let total = sim::total_samples(&cfg, n_levels) as f64;
    println!(
        "\n== two_mass, {n_levels} levels × {} samples, {} threads",
        sim::total_samples(&cfg, 1),
        rayon::current_num_threads()
    );
    println!(
        "csv:  {t_csv:.3} s, {:.2} M samples/s, {:.0} MB/s of text; {:.2}× the same simulation into memory ({t_mem:.3} s)",
        total / t_csv / 1e6,
        bytes as f64 / t_csv / 1e6,
        t_csv / t_mem,
    );
    print_row(
        "simulate",
        &format!(
            "RK4 {:.2}× the hand-written time ({:.1} M sub-steps/s); into CSV {:.2}× the \
             time into memory",
            t_sim / t_ref,
            substeps / t_sim / 1e6,
            t_csv / t_mem
        ),
        "the same equations of motion written out by hand with the same integrator; \
         the same simulation into memory",
        &format!(
            "{}cargo bench -p dynid-runtime --bench simulate",
            bench_env()
        ),
    );
}
