use super::driven::read_input_csv;
use super::*;
use dynid_runtime::data::DataError;

/// The diagnostic code of a failed run (empty without one).
fn code(e: &miette::Report) -> String {
    e.code().map(|c| c.to_string()).unwrap_or_default()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn input_csv_errors_name_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    // The error's code, and its text (which must name the line and column).
    let err = |text: &str| {
        let e = read_input_csv(&write(dir.path(), "a.csv", text), false).unwrap_err();
        (code(&e), format!("{e:?}"))
    };
    let is = |(code, e): (String, String), want: &str, line: &str| {
        assert_eq!(code, want, "{e}");
        assert!(e.contains(line), "{e}");
    };
    is(
        err("u\n1\n2\n"),
        "dynid::data::no_sample_interval",
        "no `t` column",
    );
    is(err("t,u\n0,1\n0.1\n"), "dynid::data::ragged", "line 3");
    let nan = err("t,u\n0,1\n0.1,NaN\n");
    assert!(nan.1.contains("`u`"), "{}", nan.1);
    is(nan, "dynid::data::non_finite", "line 3");
    is(
        err("t,u\n0,1\n0.1,x\n"),
        "dynid::data::not_a_number",
        "line 3",
    );
    // A step of two intervals: a dropped sample, named as such (the same code as an
    // uneven step, told apart by the variant).
    let variant = |text: &str| {
        let e = read_input_csv(&write(dir.path(), "a.csv", text), false).unwrap_err();
        assert_eq!(code(&e), "dynid::data::non_uniform_time", "{e:?}");
        e.downcast::<DataError>().expect("a data error")
    };
    let e = variant("t,u\n0,1\n0.1,2\n0.3,2\n0.35,1\n");
    assert!(
        matches!(
            e,
            DataError::MissingSamples {
                line: 4,
                missing: 1,
                ..
            }
        ),
        "{e:?}"
    );
    let e = variant("t,u\n0,1\n0.1,2\n0.25,2\n0.35,1\n");
    assert!(
        matches!(e, DataError::NonUniformTime { line: 4, .. }),
        "{e:?}"
    );
    let r = read_input_csv(
        &write(dir.path(), "b.csv", "t,u\n1,1\n1.5,2\n2,3\n\n"),
        false,
    )
    .unwrap();
    assert_eq!(
        (r.t0, r.ts, r.names.clone()),
        (1.0, 0.5, vec!["u".to_string()])
    );
    assert_eq!(r.columns, vec![vec![1.0, 2.0, 3.0]]);
}

fn args(model: PathBuf, out: PathBuf) -> Args {
    Args {
        model,
        levels: Some(vec![6.0, 15.0]),
        duration: 20.0,
        sample: 0.01,
        seed: 3,
        noise: 0.0,
        clean_inputs: false,
        substeps: DEFAULT_SUBSTEPS,
        burn_in: 5.0,
        input_oversample: 1,
        quantise: None,
        pd: None,
        reference_rms: 0.03,
        reference_corner: 5.0,
        smooth_reference: false,
        tachometer: false,
        out,
        excitation: Default::default(),
        input: None,
        format: Format::Json,
        allow_long: false,
        allow_large: false,
    }
}

#[test]
fn writes_levels_and_truth_then_drives_with_a_level() {
    use dynid_runtime::sim::test_models::{sdof, SdofParams};
    let dir = tempfile::tempdir().unwrap();
    let ir = sdof(
        &SdofParams::benchmark(),
        dsl_parser::ir::FormFilter::Lowpass { corner: 10.0 },
        vec![1.0],
    );
    let model = write(
        dir.path(),
        "sdof.json",
        &serde_json::to_string(&ir).unwrap(),
    );
    let out = dir.path().join("out");
    run(args(model.clone(), out.clone())).unwrap();
    let mut files: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    assert_eq!(files, ["level_1.csv", "level_2.csv", "truth.json"]);
    let truth: sim::Truth =
        serde_json::from_str(&std::fs::read_to_string(out.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth.levels, [6.0, 15.0]);
    assert_eq!(truth.files, ["level_1.csv", "level_2.csv"]);
    let level = read_input_csv(&out.join("level_2.csv"), false).unwrap();
    assert_eq!(level.names, ["m1.x", "m1.v", "u"]);
    assert_eq!(level.len(), 2000);

    let driven_out = dir.path().join("driven");
    let mut a = args(model, driven_out.clone());
    a.input = Some(out.join("level_2.csv"));
    run(a).unwrap();
    let driven = read_input_csv(&driven_out.join("driven.csv"), false).unwrap();
    assert_eq!(driven.len(), level.len());
    assert_eq!(driven.column("u"), level.column("u"));
}

#[test]
fn closed_loop_quantised_oversampled_run_writes_the_reference() {
    use dynid_runtime::sim::test_models::ServoAxis;
    let dir = tempfile::tempdir().unwrap();
    let model = write(
        dir.path(),
        "servo.json",
        &serde_json::to_string(&ServoAxis::standard().model()).unwrap(),
    );
    let out = dir.path().join("out");
    let mut a = args(model, out.clone());
    a.levels = None;
    a.duration = 2.0;
    a.burn_in = 1.0;
    a.sample = 1e-3;
    a.input_oversample = 4;
    a.quantise = Some(1e-6);
    a.pd = Some(vec![80000.0, 2680.0]);
    run(a).unwrap();
    let level = read_input_csv(&out.join("level_1.csv"), false).unwrap();
    assert_eq!(level.names, ["m.x", "u", "m.x_ref"]);
    assert_eq!(level.len(), 2000);
    let truth: sim::Truth =
        serde_json::from_str(&std::fs::read_to_string(out.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth.input_oversample, 4);
    assert_eq!(truth.control.unwrap().kd, 2680.0);
    let mut bad = args(dir.path().join("servo.json"), dir.path().join("bad"));
    bad.pd = Some(vec![1.0]);
    let e = run(bad).unwrap_err();
    assert_eq!(code(&e), "dynid::simulate::option", "{e:?}");
}

#[test]
fn failures_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let e = run(args(dir.path().join("missing.json"), out.clone())).unwrap_err();
    assert_eq!(code(&e), "dynid::model::io", "{e:?}");
    assert!(
        format!("{e:?}").contains("missing.json"),
        "the error names the file: {e:?}"
    );
    let e = run(args(write(dir.path(), "m.dyn", "model m {}"), out.clone())).unwrap_err();
    assert_eq!(code(&e), "dyn::compile", "{e:?}");
    assert!(
        format!("{e:?}").contains("m.dyn"),
        "the error names the file: {e:?}"
    );
    assert!(!out.exists());
}
