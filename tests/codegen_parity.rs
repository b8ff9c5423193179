//! Generated evaluator against the interpreter, on every model in `models/`: the assembled
//! least-squares system `C p = c` must be bit-identical whichever evaluator computes the
//! basis, and so must the identification.
//!
//! The list of models is written by the root package's `build.rs` (one `include_model!` per
//! `models/*.dyn`), so a new model is covered without touching this file.

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::ident::{self, Identification, IdentifyError, IdentifyOptions};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{SimConfig, SimError, SimOutput};
use dynid::runtime::tape::Tape;
use dynid::runtime::BasisEval;

/// One included model: its generated evaluator and conveniences.
pub struct Case {
    file: &'static str,
    eval: &'static (dyn BasisEval + 'static),
    ir: fn() -> &'static ModelIr,
    simulate: fn(&SimConfig) -> Result<SimOutput, SimError>,
    identify: fn(&[Record], &IdentifyOptions) -> Result<Identification, IdentifyError>,
    typed: fn(&Identification) -> Option<Vec<f64>>,
}

mod models {
    use super::*;
    include!(concat!(env!("OUT_DIR"), "/models.rs"));
}

/// Short records: a few hundred seconds at most, fewer for fast models (the sample
/// interval shrinks until the simulator accepts the resolution).
fn short_records(case: &Case) -> Vec<Record> {
    let mut cfg = SimConfig {
        duration: 200.0,
        sample: 0.01,
        burn_in: 20.0,
        seed: 7,
        ..SimConfig::default()
    };
    for _ in 0..4 {
        match (case.simulate)(&cfg) {
            Ok(out) => return out.records,
            Err(SimError::UnderResolved { .. }) => {
                cfg.duration /= 10.0;
                cfg.sample /= 10.0;
                cfg.burn_in /= 10.0;
            }
            Err(e) => panic!("{}: cannot simulate: {e}", case.file),
        }
    }
    panic!("{}: no sample interval resolves the motion", case.file)
}

fn sources<'r>(ir: &ModelIr, records: &'r [Record]) -> Vec<RecordSource<'r>> {
    records
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect()
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn every_model_in_the_directory_is_covered() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut on_disk: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".dyn"))
        .map(|n| format!("models/{n}"))
        .collect();
    on_disk.sort();
    let covered: Vec<&str> = models::CASES.iter().map(|c| c.file).collect();
    assert_eq!(covered, on_disk);
}

#[test]
fn generated_and_interpreted_evaluators_assemble_the_same_system() {
    for case in models::CASES {
        let ir = (case.ir)();
        let direct = dynid::dsl_parser::compile_file(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(case.file),
        )
        .unwrap();
        assert_eq!(
            ir, &direct,
            "{}: embedded IR differs from the file",
            case.file
        );

        let records = short_records(case);
        let srcs = sources(ir, &records);
        let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
        let tape = Tape::compile(ir, &ir.eval_roots());
        let mut opts = IdentifyOptions::default();
        // A model's own filter order may be too low for displacement-only data; parity
        // only needs some valid bank.
        if let Err(IdentifyError::BadOption { .. }) = ident::assemble(ir, &tape, &levels, &opts) {
            opts.order = Some(4);
        }

        let generated = ident::assemble(ir, case.eval, &levels, &opts);
        let interpreted = ident::assemble(ir, &tape, &levels, &opts);
        let (g, t) = match (generated, interpreted) {
            (Ok(g), Ok(t)) => (g, t),
            (g, t) => panic!("{}: assemble failed: {g:?} / {t:?}", case.file),
        };
        assert_eq!((g.rows, g.cols), (t.rows, t.cols), "{}", case.file);
        assert!(g.rows > 0, "{}", case.file);
        assert!(
            same_bits(&g.c_matrix, &t.c_matrix),
            "{}: C differs",
            case.file
        );
        assert!(same_bits(&g.rhs, &t.rhs), "{}: c differs", case.file);

        // The generated `identify` (generated basis) against the runtime's (tape). A model
        // with a shape parameter is profiled only by the interpreter (the generated code has
        // the starting gap compiled in), so its systems are compared above, not its fits.
        if !ir.shapes.is_empty() {
            continue;
        }
        let by_macro = (case.identify)(&records, &opts);
        let by_tape = ident::identify(ir, &levels, &opts);
        match (by_macro, by_tape) {
            (Ok(a), Ok(b)) => {
                assert_eq!(a.params, b.params, "{}", case.file);
                assert_eq!(a.unidentifiable, b.unidentifiable, "{}", case.file);
                assert_eq!(
                    a.condition.to_bits(),
                    b.condition.to_bits(),
                    "{}",
                    case.file
                );
                // The model's own parameters: `identify` may have chosen rows that add
                // an input's delay (`u.delay`, a dotted name no model parameter has).
                let values: Vec<f64> = a
                    .params
                    .iter()
                    .filter(|p| !p.name.contains('.'))
                    .map(|p| p.value)
                    .collect();
                match (case.typed)(&a) {
                    Some(typed) => assert!(same_bits(&typed, &values), "{}", case.file),
                    None => assert!(!a.unidentifiable.is_empty(), "{}", case.file),
                }
                eprintln!(
                    "{}: {} rows, bit-identical; condition {:.3e}",
                    case.file, g.rows, a.condition
                );
            }
            (a, b) => panic!("{}: identification failed: {a:?} / {b:?}", case.file),
        }
    }
}
