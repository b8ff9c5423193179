use super::*;
use crate::data::{LevelSource, RecordSource};
use crate::detect::{detect_from_data, DetectOptions};
use crate::sim::{self, SimConfig};
use crate::{identify, IdentifyOptions};
use dynid_ir::ir::ModelIr;

fn model(nl: &str) -> ModelIr {
    let src = format!(
        "model sdof {{
            body m1 = 1.0
            input u on m1
            damper d (ground, m1) ~ 0.4
            spring k (ground, m1) ~ 4.0
            {nl}
            excite u: lowpass(corner = 10) levels [6, 15, 40]
        }}"
    );
    dsl_parser::compile_str("sdof", &src).expect("valid model")
}

fn records(ir: &ModelIr) -> Vec<crate::record::Record> {
    let cfg = SimConfig {
        duration: 300.0,
        seed: 3,
        ..Default::default()
    };
    sim::simulate(ir, &cfg).expect("simulation").records
}

fn keys(v: &serde_json::Value) -> Vec<&str> {
    v.as_object().unwrap().keys().map(String::as_str).collect()
}

#[test]
fn identify_document_keys_parameters_by_name_in_the_models_order() {
    let ir = model("force nl (ground, m1) = k3 ~ 2.0 * s^3");
    let recs = records(&ir);
    let srcs: Vec<RecordSource> = recs
        .iter()
        .map(|r| RecordSource::new(r, &ir, "level").unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let id = identify(&ir, &levels, &IdentifyOptions::default()).unwrap();
    let v = serde_json::to_value(IdentifyDoc::new(&id)).unwrap();
    assert_eq!(
        keys(&v),
        [
            "condition",
            "covariance",
            "estimated",
            "filter",
            "fit_warnings",
            "levels",
            "parameters",
            "residual",
            "residual_noise",
            "rows",
            "schema_version",
            "shapes",
            "unidentifiable",
            "warnings"
        ]
    );
    assert_eq!(v["schema_version"], SCHEMA_VERSION);
    // The map's order is the model's (the text is written in struct order).
    let text = serde_json::to_string(&IdentifyDoc::new(&id)).unwrap();
    let at = |n: &str| text.find(&format!("\"{n}\":{{\"value\"")).unwrap();
    assert!(at("d") < at("k") && at("k") < at("k3"), "{text}");
    for p in &id.params {
        assert_eq!(v["parameters"][&p.name]["value"], p.value);
        assert_eq!(v["parameters"][&p.name]["stderr"], p.stderr);
        assert_eq!(v["parameters"][&p.name]["significant"], p.significant);
    }
    for r in &id.residual {
        assert_eq!(v["residual"][&r.equation], serde_json::json!(r.per_level));
    }
    // The covariance by name: symmetric, its diagonal the squared standard errors, and a
    // correlation inside [-1, 1].
    for (i, p) in id.params.iter().enumerate() {
        assert_eq!(v["covariance"][&p.name][&p.name], p.stderr * p.stderr);
        for (j, q) in id.params.iter().enumerate() {
            let c = v["covariance"][&p.name][&q.name].as_f64().unwrap();
            assert_eq!(c, id.covariance(i, j));
            assert_eq!(c, id.covariance(j, i));
            assert!(
                c.abs() <= p.stderr * q.stderr * (1.0 + 1e-12),
                "{p:?} {q:?} {c}"
            );
        }
    }
    // A refinement and a hint appear only where given.
    let with = IdentifyDoc::new(&id).with_refined(Some(&7));
    let v = serde_json::to_value(IdentifyDoc {
        closed_loop_hint: Some("hint"),
        ..with
    })
    .unwrap();
    assert_eq!(v["refined"], 7);
    assert_eq!(v["closed_loop_hint"], "hint");
}

#[test]
fn detect_document_carries_the_warnings_of_the_tests_degrees_of_freedom() {
    let ir = model("");
    let recs = records(&model("force nl (ground, m1) = k3 ~ 2.0 * s^3"));
    let srcs: Vec<RecordSource> = recs
        .iter()
        .map(|r| RecordSource::new(r, &ir, "level").unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let dopts = DetectOptions::default();
    let (det, fits) = detect_from_data(&ir, &levels, &Default::default(), &dopts, &[]).unwrap();
    let warnings = detection_warnings(&det, &fits, &dopts);
    let explicit = DetectOptions {
        se_dof: Some(fits.n_blocks as f64 - 1.0),
        ..dopts.clone()
    };
    assert_eq!(warnings, crate::detect::levels_too_alike(&det, &explicit));
    let v = serde_json::to_value(DetectDoc::new(&det, &fits, &warnings, None, &[])).unwrap();
    assert_eq!(
        keys(&v),
        [
            "batch_blocks",
            "cycles_note",
            "detection",
            "frf",
            "intensities",
            "jackknife_blocks",
            "schema_version",
            "segments",
            "sigma_v_source",
            "warnings"
        ]
    );
    assert_eq!(v["batch_blocks"], fits.n_blocks);
    // The name before schema version 2, kept for one version.
    assert_eq!(v["jackknife_blocks"], fits.n_blocks);
    assert_eq!(v["detection"], serde_json::to_value(&det).unwrap());
    assert!(v["segments"].is_null() && v["cycles_note"].is_null());
}
