//! Identification throughput on `models/two_mass.dyn` (cubic stiffness + Coulomb friction):
//! three levels from memory and from CSV files, at two record lengths; then the scaling of
//! the filter-and-moment pass with the number of threads on one long level; then the cost
//! of the rows `identify` chooses for accelerations (each weighted by its own estimated
//! error, the weighting iterated) against the unit-norm rows on the same records: the
//! jointed five-body structure `models/structure5_joint_accel.dyn` from its accelerations
//! and force, four multisine levels with 5 % noise on every channel
//! (`DYNID_BENCH_ACCEL_SECONDS=200` the seconds per level, 0 to skip), with the mean
//! |error| of the masses and stiffnesses each gives.
//!
//! Run: `cargo bench -p dynid-runtime --bench identify`
//! (`DYNID_BENCH_SAMPLES=100000,1000000` sets the samples per level of each run, 0 none,
//! `DYNID_BENCH_SCALING_SAMPLES=10000000` the samples of the one level of the thread table,
//! 0 to skip it, `DYNID_BENCH_THREADS=1,2,4,8` its thread counts: by default powers of
//! two up to the number of cores, and `DYNID_BENCH_CHUNK=8192` the samples per streamed
//! chunk of every identification.)
//!
//! Every time is also given as a ratio to a reference measured in the same run on the same
//! data: from memory, one pass that streams the records and sums every value; from CSV,
//! one pass that splits every line and parses every field. Peak memory is the process's
//! high-water mark (`VmHWM`) above its resident size before the CSV identification, with
//! the peak reset beforehand (`/proc/self/clear_refs`), so it shows what identification
//! itself holds — it must not grow with the record length.
//!
//! `pass` is the wall time of the streamed filter-and-moment pass alone (all levels), the
//! part of identification that the time-parallel filter bank speeds up; its ratio to the
//! reference pass is what the speed targets are stated in.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::{CsvOptions, CsvSource, LevelSource, RecordSource};
use dynid_runtime::ident::{identify, IdentifyOptions, PhaseTimes};
use dynid_runtime::record::Record;
use dynid_runtime::sim::{self, Grid, Phases, SimConfig, TestSignal};
use rayon::prelude::*;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod common;
use common::{bench_env, best_of, memory, print_row, reset_peak};

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
        .map(|(n, d)| format!("{n} {:.0}%", 100.0 * d.as_secs_f64() / total))
        .collect::<Vec<_>>()
        .join(", ")
}

fn write_csvs(recs: &[Record], dir: &Path) -> Vec<PathBuf> {
    recs.par_iter()
        .enumerate()
        .map(|(i, r)| {
            let p = dir.join(format!("level_{}.csv", i + 1));
            let mut w = std::io::BufWriter::new(std::fs::File::create(&p).unwrap());
            sim::write_csv(&mut w, r).unwrap();
            p
        })
        .collect()
}

/// Reference for CSV: split and parse every field of every file (levels in parallel).
fn csv_reference(paths: &[PathBuf]) -> f64 {
    paths
        .par_iter()
        .map(|p| {
            let mut rdr = csv::Reader::from_path(p).unwrap();
            let mut rec = csv::ByteRecord::new();
            let mut sum = 0.0;
            while rdr.read_byte_record(&mut rec).unwrap() {
                for f in rec.iter() {
                    sum += std::str::from_utf8(f).unwrap().parse::<f64>().unwrap();
                }
            }
            sum
        })
        .sum()
}

/// Every record as a level source, named `level 1`, `level 2`, …
fn record_sources<'r>(recs: &'r [Record], ir: &ModelIr) -> Vec<RecordSource<'r>> {
    recs.iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect()
}

/// Reference for memory: stream every source and sum its values (levels in parallel).
fn memory_reference(levels: &[&dyn LevelSource], chunk: usize) -> f64 {
    levels
        .par_iter()
        .map(|src| {
            let mut sum = 0.0;
            src.stream(chunk, &mut |cols, len| {
                for c in cols.iter().filter(|c| !c.is_empty()) {
                    sum += c[..len].iter().sum::<f64>();
                }
            })
            .unwrap();
            sum
        })
        .sum()
}

/// The ratios of one run: identification and its pass against the reference pass, the CSV
/// identification and dynid's parse alone against the reference parse.
struct Ratios {
    memory: f64,
    pass: f64,
    csv: f64,
    parse: f64,
}

fn run(n: usize) -> Ratios {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/two_mass.dyn");
    let ir = dsl_parser::compile_file(&path).expect("models/two_mass.dyn");
    let ts = 0.01;
    let cfg = SimConfig {
        duration: n as f64 * ts,
        sample: ts,
        seed: 500,
        ..Default::default()
    };
    let t = Instant::now();
    let recs = sim::simulate(&ir, &cfg).expect("simulation").records;
    let total = recs.iter().map(Record::len).sum::<usize>() as f64;
    println!(
        "\n== two_mass, {} levels × {} samples ({:.0} s each; simulated in {:.1} s), {} threads",
        recs.len(),
        recs[0].len(),
        n as f64 * ts,
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    let opts = options();

    let srcs = record_sources(&recs, &ir);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let (t_ref, _) = best_of(3, || black_box(memory_reference(&levels, opts.chunk_len)));
    let (t_mem, id) = best_of(3, || identify(&ir, &levels, &opts).unwrap());
    let (memory_ratio, pass_ratio) = (t_mem / t_ref, id.times.pass.as_secs_f64() / t_ref);
    println!(
        "memory: {t_mem:.3} s, {:.1} M samples/s, {:.0}× the reference pass ({t_ref:.4} s); \
         pass {:.3} s = {:.1}× the reference; {}",
        total / t_mem / 1e6,
        t_mem / t_ref,
        id.times.pass.as_secs_f64(),
        id.times.pass.as_secs_f64() / t_ref,
        shares(&id.times)
    );
    let estimates: Vec<String> = id
        .params
        .iter()
        .map(|e| format!("{} {:.4}±{:.4}", e.name, e.value, e.stderr))
        .collect();
    println!("  estimates: {}", estimates.join(", "));

    let dir = tempfile::tempdir().unwrap();
    let paths = write_csvs(&recs, dir.path());
    drop(srcs);
    drop(recs);
    let (t_ref, _) = best_of(1, || black_box(csv_reference(&paths)));
    // dynid's parse alone: one validated pass over every file (levels in parallel).
    let (t_parse, _) = best_of(1, || {
        paths
            .par_iter()
            .map(|p| {
                let src = CsvSource::open(p, &ir, &CsvOptions::default())
                    .unwrap()
                    .without_replay();
                let mut sum = 0.0;
                src.stream(opts.chunk_len, &mut |cols, len| {
                    for c in cols.iter().filter(|c| !c.is_empty()) {
                        sum += c[..len].iter().sum::<f64>();
                    }
                })
                .unwrap();
                black_box(sum)
            })
            .sum::<f64>()
    });
    let before = memory();
    let peak_reset = reset_peak();
    let t = Instant::now();
    let csvs: Vec<CsvSource> = paths
        .iter()
        .map(|p| CsvSource::open(p, &ir, &CsvOptions::default()).unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = csvs.iter().map(|s| s as &dyn LevelSource).collect();
    let id = identify(&ir, &levels, &opts).unwrap();
    let t_csv = t.elapsed().as_secs_f64();
    let peak = match (before, memory(), peak_reset) {
        (Some((_, rss0)), Some((hwm, _)), true) => {
            format!("peak memory {:.1} MiB above the start", hwm - rss0)
        }
        (_, Some((hwm, _)), false) => format!("peak memory (process) {hwm:.1} MiB"),
        _ => "peak memory n/a".into(),
    };
    println!(
        "csv:    {t_csv:.3} s, {:.2} M samples/s, {:.2}× the reference parse ({t_ref:.3} s); {}; {peak}",
        total / t_csv / 1e6,
        t_csv / t_ref,
        shares(&id.times)
    );
    println!(
        "  parse alone (one validated pass): {t_parse:.3} s, {:.2}× the reference parse",
        t_parse / t_ref
    );
    Ratios {
        memory: memory_ratio,
        pass: pass_ratio,
        csv: t_csv / t_ref,
        parse: t_parse / t_ref,
    }
}

/// Thread scaling of identification on one level of `n` samples from memory: per thread
/// count (a rayon pool of that size), the best of three of the whole identification, of
/// the filter-and-moment pass inside it, and of the reference pass (one level: one thread
/// streams it whatever the pool).
fn scaling(n: usize, threads: &[usize]) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/two_mass.dyn");
    let ir = dsl_parser::compile_file(&path).expect("models/two_mass.dyn");
    let ts = 0.01;
    let cfg = SimConfig {
        levels: Some(vec![15.0]),
        duration: n as f64 * ts,
        sample: ts,
        seed: 501,
        ..Default::default()
    };
    let t = Instant::now();
    let rec = sim::simulate(&ir, &cfg)
        .expect("simulation")
        .records
        .remove(0);
    println!(
        "\n== thread scaling: two_mass, one level × {} samples (simulated in {:.1} s), {} cores",
        rec.len(),
        t.elapsed().as_secs_f64(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    let src = RecordSource::new(&rec, &ir, "level").unwrap();
    let levels: Vec<&dyn LevelSource> = vec![&src];
    let opts = options();
    println!(
        "threads  identify (s)  pass (s)  pass speed-up  pass / reference  M samples/s (pass)"
    );
    let mut base = None;
    let mut speed_up = String::new();
    for &k in threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(k)
            .build()
            .unwrap();
        let (t_ref, _) =
            pool.install(|| best_of(3, || black_box(memory_reference(&levels, opts.chunk_len))));
        let mut t_pass = f64::INFINITY;
        let (t_id, _) = pool.install(|| {
            best_of(3, || {
                let id = identify(&ir, &levels, &opts).unwrap();
                t_pass = t_pass.min(id.times.pass.as_secs_f64());
            })
        });
        let base = *base.get_or_insert(t_pass);
        println!(
            "{k:>7}  {t_id:>12.3}  {t_pass:>8.3}  {:>12.2}×  {:>15.1}×  {:>18.1}",
            base / t_pass,
            t_pass / t_ref,
            rec.len() as f64 / t_pass / 1e6
        );
        speed_up = format!("1 → {k} threads: the pass's speed-up {:.2}×", base / t_pass);
    }
    speed_up
}

/// The rows `identify` chooses for accelerations against the unit-norm rows
/// (`IdentifyOptions::instrument_rows`) on the jointed five-body structure, four multisine
/// levels (0.2–10 Hz, 4 whole periods, random phases) of `seconds` each at Ts = 0.01 s with
/// 5 % noise on every channel: the best of three of each identification, their ratio, and
/// each one's mean |error| of the masses and stiffnesses against the simulated truth.
fn accelerations(seconds: f64) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/structure5_joint_accel.dyn");
    let ir = dsl_parser::compile_file(&path).expect("models/structure5_joint_accel.dyn");
    let cfg = SimConfig {
        duration: seconds,
        sample: 0.01,
        seed: 502,
        noise: 0.05,
        noise_on_inputs: true,
        levels: Some(vec![1.0, 3.0, 10.0, 30.0]),
        ..Default::default()
    };
    let signal = TestSignal::Multisine {
        f_min_hz: 0.2,
        f_max_hz: 10.0,
        periods: 4,
        grid: Grid::Full,
        phases: Phases::Random,
    };
    let t = Instant::now();
    let recs = sim::simulate_signal(&ir, &cfg, &signal)
        .expect("simulation")
        .records;
    println!(
        "\n== accelerations: structure5_joint_accel, {} levels × {} samples ({seconds:.0} s each, \
         5 % noise; simulated in {:.1} s), {} threads",
        recs.len(),
        recs[0].len(),
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    let srcs = record_sources(&recs, &ir);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    // Mean |error| of the masses and stiffnesses (`m…`, `k…`), per cent.
    let error = |id: &dynid_runtime::ident::Identification| {
        let errs: Vec<f64> = id
            .params
            .iter()
            .filter(|e| e.name.starts_with('m') || e.name.starts_with('k'))
            .filter_map(|e| {
                let truth = ir.params.iter().find(|p| p.name == e.name)?.nominal()?;
                Some(100.0 * (e.value / truth - 1.0).abs())
            })
            .collect();
        errs.iter().sum::<f64>() / errs.len().max(1) as f64
    };
    let unit_opts = IdentifyOptions {
        chunk_len: options().chunk_len,
        ..IdentifyOptions::instrument_rows()
    };
    let (t_unit, unit) = best_of(3, || identify(&ir, &levels, &unit_opts).unwrap());
    let (t_chosen, chosen) = best_of(3, || identify(&ir, &levels, &options()).unwrap());
    assert!(chosen.filter.weighted_rows && !unit.filter.weighted_rows);
    println!(
        "unit-norm rows: {t_unit:.3} s, masses and stiffnesses {:.2} % off (mean |error|)\n\
         rows chosen (each weighted by its own estimated error, {} solves): {t_chosen:.3} s \
         = {:.2}× the unit-norm rows, {:.2} % off",
        error(&unit),
        chosen.filter.weight_steps,
        t_chosen / t_unit,
        error(&chosen)
    );
    format!(
        "accelerations ({seconds:.0} s × 4 levels): the rows chosen {:.2}× the time of the \
         unit-norm rows, mean |error| {:.2} % against {:.2} %",
        t_chosen / t_unit,
        error(&chosen),
        error(&unit)
    )
}

/// The identification's options, with `DYNID_BENCH_CHUNK` (samples per streamed chunk)
/// where it is set.
fn options() -> IdentifyOptions {
    let mut opts = IdentifyOptions::default();
    if let Some(c) = env_value("DYNID_BENCH_CHUNK") {
        opts.chunk_len = c.max(1);
    }
    opts
}

/// The first value of [`env_list`].
fn env_value(name: &str) -> Option<usize> {
    env_list(name)?.first().copied()
}

fn env_list(name: &str) -> Option<Vec<usize>> {
    std::env::var(name)
        .ok()
        .map(|s| s.split(',').filter_map(|v| v.trim().parse().ok()).collect())
}

fn main() {
    let lengths = env_list("DYNID_BENCH_SAMPLES").unwrap_or_else(|| vec![100_000, 1_000_000]);
    // A length of 0 skips the runs (e.g. to take only the thread-scaling table).
    let mut figures = Vec::new();
    for n in lengths.into_iter().filter(|&n| n > 0) {
        let r = run(n);
        figures.push(format!(
            "{n} samples per level: identification {:.1}× the reference, the pass {:.1}×; \
             from CSV {:.2}× the reference parse, parse alone {:.2}×",
            r.memory, r.pass, r.csv, r.parse
        ));
    }
    let n = env_value("DYNID_BENCH_SCALING_SAMPLES").unwrap_or(10_000_000);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = env_list("DYNID_BENCH_THREADS").unwrap_or_else(|| {
        std::iter::successors(Some(1), |k| Some(k * 2))
            .take_while(|&k| k <= cores)
            .collect()
    });
    if n > 0 {
        figures.push(scaling(n, &threads));
    }
    let accel_seconds = env_value("DYNID_BENCH_ACCEL_SECONDS").unwrap_or(200);
    if accel_seconds > 0 {
        figures.push(accelerations(accel_seconds as f64));
    }
    print_row(
        "identify",
        &figures.join("; "),
        "one pass that streams the same levels from memory and sums every value; \
         one pass that splits and parses every CSV field; the pass on one thread; the \
         unit-norm rows on the same accelerations",
        &format!(
            "{}cargo bench -p dynid-runtime --bench identify",
            bench_env()
        ),
    );
}
