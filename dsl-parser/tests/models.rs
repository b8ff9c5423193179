//! Every model in `models/` compiles; its `dynid compile` report is snapshot-tested, and
//! printing it back as source gives the same IR.

use dsl_parser::{compile_str, ir::ModelIr, print};
use std::path::{Path, PathBuf};

fn models() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("models/ exists")
        .map(|e| e.expect("readable entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "dyn"))
        .collect();
    files.sort();
    files
}

fn without_spans(mut ir: ModelIr) -> ModelIr {
    ir.spans = Default::default();
    ir
}

#[test]
fn every_model_compiles_and_matches_its_snapshot() {
    let files = models();
    assert!(files.len() >= 16, "models/ should hold the example models");
    for path in files {
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let src = std::fs::read_to_string(&path).unwrap();
        let ir = match compile_str(&format!("{stem}.dyn"), &src) {
            Ok(ir) => ir,
            Err(e) => panic!("{stem}.dyn does not compile:\n{}", e.render_plain(100)),
        };
        ir.check_invariants().unwrap();
        assert!(
            !ir.excitation.is_empty() || !ir.reference_excitation.is_empty(),
            "{stem}: every model can be simulated"
        );
        insta::assert_snapshot!(format!("report_{stem}"), print::render_report(&ir));
    }
}

#[test]
fn every_model_round_trips_through_source() {
    for path in models() {
        let src = std::fs::read_to_string(&path).unwrap();
        let ir = compile_str("m.dyn", &src).unwrap();
        let printed = print::to_source(&ir);
        let again = compile_str("printed.dyn", &printed)
            .unwrap_or_else(|e| panic!("{}\n{}", printed, e.render_plain(100)));
        assert_eq!(
            without_spans(again),
            without_spans(ir),
            "{}:\n{printed}",
            path.display()
        );
    }
}

#[test]
fn linear_counterparts_have_the_same_bodies_and_linear_elements() {
    for path in models() {
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let Some(base) = stem.strip_suffix("_linear") else {
            continue;
        };
        let lin = compile_str("l.dyn", &std::fs::read_to_string(&path).unwrap()).unwrap();
        for e in &lin.elements {
            assert_ne!(
                e.kind,
                dsl_parser::ir::ElementKind::Force,
                "{stem}: {}",
                e.name
            );
        }
        // Every nonlinear model named after this counterpart has the same bodies.
        for other in models() {
            let ostem = other.file_stem().unwrap().to_string_lossy().to_string();
            if ostem != stem && ostem.starts_with(base) && !ostem.ends_with("_linear") {
                let nl = compile_str("n.dyn", &std::fs::read_to_string(&other).unwrap()).unwrap();
                assert_eq!(nl.bodies, lin.bodies, "{ostem} vs {stem}");
            }
        }
    }
}
