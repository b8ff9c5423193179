//! Moment statistics as a value (`MomentStats`): measured per record with a design fixed
//! before, encoded and decoded exactly, merged in any grouping and order, and solved, they
//! give the identification of the same records given together — and every refusal of a
//! merge, a model or a file.
//!
//! The figures of docs/distributed.md come from here:
//! `cargo test --test moments -- --nocapture` prints the largest relative difference of the
//! merge from the whole (estimates and standard errors) and the bytes of a piece.

mod common;
mod figures;
mod servo_common;

use common::{simulate, sources};
use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::data::LevelSource;
use dynid::runtime::ident::{Identification, MomentDesign, MomentStats, MomentsError};
use dynid::runtime::record::Record;
use dynid::runtime::{identify, IdentifyOptions};

/// Relative tolerance of merged against whole: both solve the same rows; a merge in
/// another order sums the levels' terms in another order (rounding, measured at most
/// 4.4e-13 by this test with `--nocapture`).
const TOL: f64 = 1e-10;

/// Where the sizes of a piece are written.
const DOC: &str = "docs/distributed.md";

fn model(name: &str) -> ModelIr {
    let src = std::fs::read_to_string(common::model_path(name)).unwrap();
    dynid::dsl_parser::compile_str(name, &src).unwrap()
}

/// Every record's statistics with `design`, each through its bytes and back.
fn pieces(ir: &ModelIr, recs: &[Record], design: &MomentDesign) -> Vec<MomentStats> {
    let srcs = sources(ir, recs);
    srcs.iter()
        .map(|s| {
            let one: Vec<&dyn LevelSource> = vec![s];
            let st = MomentStats::measure(ir, &one, design, false).unwrap();
            let bytes = st.to_bytes();
            let back = MomentStats::from_bytes(&bytes, "piece").unwrap();
            assert_eq!(back, st, "the encoding round-trips exactly");
            back
        })
        .collect()
}

/// The largest relative difference of the estimates and standard errors of `b` from `a`
/// (the same parameters identified).
fn max_rel(a: &Identification, b: &Identification) -> f64 {
    assert_eq!(a.params.len(), b.params.len());
    let rel = |x: f64, y: f64| (x - y).abs() / x.abs().max(f64::MIN_POSITIVE);
    a.params
        .iter()
        .zip(&b.params)
        .map(|(p, q)| {
            assert_eq!(p.name, q.name);
            rel(p.value, q.value).max(rel(p.stderr, q.stderr))
        })
        .fold(0.0, f64::max)
}

/// The identification of `recs` in process and from their pieces merged in order, in
/// another grouping, and in reverse order: `(largest difference, bytes per piece)`.
fn merge_equals_whole(ir: &ModelIr, recs: &[Record], opts: &IdentifyOptions) -> (f64, usize) {
    let srcs = sources(ir, recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    // Moments hold the instrument rows (no choice of rows: `IdentifyOptions::auto_rows`).
    let opts = &IdentifyOptions {
        auto_rows: false,
        ..opts.clone()
    };
    let whole = identify(ir, &levels, opts).unwrap();
    let design = MomentDesign::from_data(ir, &levels, opts).unwrap();
    let parts = pieces(ir, recs, &design);
    let bytes = parts[0].to_bytes().len();

    let in_order = MomentStats::merge_all(parts.clone()).unwrap();
    let id = in_order.identify(ir).unwrap();
    // In order the merged problem is the whole one, row for row: the same report.
    assert_eq!(id.levels, whole.levels);
    assert_eq!(id.noise, whole.noise);
    assert_eq!(id.filter, whole.filter);
    assert_eq!(id.estimated, whole.estimated);
    let mut worst = max_rel(&whole, &id);

    // Another grouping: the last two first, then the first in front.
    let n = parts.len();
    let tail = MomentStats::merge_all(parts[1..].iter().cloned()).unwrap();
    let grouped = parts[0].clone().merge(tail).unwrap();
    assert_eq!(grouped, in_order, "the merge is associative");
    // Reverse order: the levels are permuted, the pooled problem is the same.
    let reversed = MomentStats::merge_all(parts.iter().rev().cloned()).unwrap();
    let rid = reversed.identify(ir).unwrap();
    assert_eq!(rid.levels.len(), n);
    worst = worst.max(max_rel(&whole, &rid));
    (worst, bytes)
}

#[test]
fn two_mass_pieces_merged_equal_the_whole() {
    let ir = model("two_mass.dyn");
    let recs = simulate(&ir, 60.0, 0.01, 3);
    let (worst, bytes) = merge_equals_whole(&ir, &recs, &IdentifyOptions::default());
    println!("two_mass: merged vs whole max rel. diff {worst:.2e}; {bytes} bytes per piece");
    figures::check(DOC, "moments.kb.two_mass_60s", bytes as f64 / 1000.0);
    figures::check_order(DOC, "moments.rounding.two_mass", worst);
    assert!(worst <= TOL, "merged differs from whole by {worst:e}");
}

#[test]
fn servo_pieces_merged_equal_the_whole() {
    // Rests left out, an estimated velocity, a constant force: everything a piece carries.
    let (ir, a) = servo_common::planned_record(1);
    let (_, b) = servo_common::planned_record(2);
    let (worst, bytes) = merge_equals_whole(&ir, &[a, b], &IdentifyOptions::default());
    println!("servo_axis: merged vs whole max rel. diff {worst:.2e}; {bytes} bytes per piece");
    figures::check(DOC, "moments.kb.servo", bytes as f64 / 1000.0);
    figures::check_order(DOC, "moments.rounding.servo", worst);
    assert!(worst <= TOL, "merged differs from whole by {worst:e}");
}

#[test]
fn a_design_from_a_sample_measures_the_rest() {
    // The design pass on the first record only: the other records are measured with its
    // corners and blocks, and the merge solves like the in-process identification with
    // those corners and blocks given.
    let ir = model("sdof_duffing.dyn");
    let recs = simulate(&ir, 60.0, 0.01, 4);
    let srcs = sources(&ir, &recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let design = MomentDesign::from_data(&ir, &levels[..1], &IdentifyOptions::default()).unwrap();
    let merged = MomentStats::merge_all(pieces(&ir, &recs, &design)).unwrap();
    let id = merged.identify(&ir).unwrap();
    let whole = identify(&ir, &levels, &design.identify_options()).unwrap();
    let worst = max_rel(&whole, &id);
    assert!(worst <= TOL, "merged differs from whole by {worst:e}");
}

#[test]
fn merges_of_other_designs_or_models_are_refused() {
    let ir = model("two_mass.dyn");
    let recs = simulate(&ir, 60.0, 0.01, 6);
    let srcs = sources(&ir, &recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = IdentifyOptions::default();
    let design = MomentDesign::from_data(&ir, &levels, &opts).unwrap();
    let a = pieces(&ir, &recs[..1], &design).remove(0);

    let mut other = design.clone();
    other.n_blocks += 2;
    let b = pieces(&ir, &recs[1..2], &other).remove(0);
    let err = a.clone().merge(b).unwrap_err();
    assert!(
        matches!(&err, MomentsError::OtherDesign { detail } if detail.contains("time blocks")),
        "{err}"
    );

    let corners = IdentifyOptions {
        corners: Some(vec![0.5, 1.0, 2.0, 4.0, 8.0, 12.0]),
        ..opts.clone()
    };
    let other = MomentDesign::from_data(&ir, &levels, &corners).unwrap();
    let c = pieces(&ir, &recs[1..2], &other).remove(0);
    let err = a.clone().merge(c).unwrap_err();
    assert!(
        matches!(&err, MomentsError::OtherDesign { detail } if detail.contains("corners")),
        "{err}"
    );

    // Another model: refused when measuring with the design, merging or solving.
    let lin = model("sdof_duffing.dyn");
    let err = a.identify(&lin).unwrap_err();
    assert!(matches!(err, MomentsError::OtherModel { .. }), "{err}");
    let lin_recs = simulate(&lin, 60.0, 0.01, 6);
    let lin_srcs = sources(&lin, &lin_recs);
    let lin_levels: Vec<&dyn LevelSource> = vec![&lin_srcs[0]];
    let err = MomentStats::measure(&lin, &lin_levels, &design, false).unwrap_err();
    assert!(matches!(err, MomentsError::OtherModel { .. }), "{err}");
    let lin_design = MomentDesign::from_data(&lin, &lin_levels, &opts).unwrap();
    let d = MomentStats::measure(&lin, &lin_levels, &lin_design, false).unwrap();
    let err = a.clone().merge(d).unwrap_err();
    assert!(
        matches!(&err, MomentsError::OtherDesign { detail } if detail.starts_with("model")),
        "{err}"
    );
    assert!(matches!(
        MomentStats::merge_all(Vec::new()),
        Err(MomentsError::Empty)
    ));
}

#[test]
fn damaged_files_are_refused_with_their_reason() {
    let ir = model("two_mass.dyn");
    let recs = simulate(&ir, 60.0, 0.01, 7);
    let srcs = sources(&ir, &recs[..1]);
    let levels: Vec<&dyn LevelSource> = vec![&srcs[0]];
    let design = MomentDesign::from_data(&ir, &levels, &IdentifyOptions::default()).unwrap();
    let bytes = MomentStats::measure(&ir, &levels, &design, false)
        .unwrap()
        .to_bytes();
    let read = |b: &[u8]| MomentStats::from_bytes(b, "part.dynm").unwrap_err();

    assert!(matches!(
        read(b"t,m1.x\n0,1\n"),
        MomentsError::NotMoments { .. }
    ));
    assert!(matches!(read(&bytes[..5]), MomentsError::NotMoments { .. }));
    for cut in [12, 30, bytes.len() / 2, bytes.len() - 1] {
        let err = read(&bytes[..cut]);
        assert!(
            matches!(err, MomentsError::Truncated { .. }),
            "cut at {cut}: {err}"
        );
    }
    let mut version = bytes.clone();
    version[8] = 2;
    assert!(matches!(
        read(&version),
        MomentsError::Version { found: 2, .. }
    ));
    let mut flipped = bytes.clone();
    let mid = bytes.len() / 2;
    flipped[mid] ^= 0x10;
    assert!(matches!(read(&flipped), MomentsError::Corrupt { .. }));
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(read(&longer), MomentsError::Corrupt { .. }));
    // Every prefix is refused, none panics.
    for cut in 0..bytes.len().min(400) {
        assert!(MomentStats::from_bytes(&bytes[..cut], "p").is_err());
    }
}

/// `dynid moments` per file with the design of all files, then `identify --from`: the same
/// text and JSON as `identify` of the files (without the corner check, which re-reads the
/// data); the size of a piece for docs/distributed.md.
#[test]
fn cli_identify_from_pieces_prints_what_identify_of_the_files_prints() {
    let dir = tempfile::tempdir().unwrap();
    let files = common::two_mass_levels(dir.path());
    let model = common::model_path("two_mass.dyn");
    let run = |args: &[&std::ffi::OsStr]| {
        let out = common::dynid().args(args).output().unwrap();
        assert!(out.status.success(), "{}", common::stderr(&out));
        out
    };
    let os = |p: &std::path::Path| p.as_os_str().to_owned();
    let design = dir.path().join("design.json");
    let mut args = vec![os("moments".as_ref()), os(&model)];
    args.extend(files.iter().map(|f| os(f)));
    args.extend([
        os("--design-only".as_ref()),
        os("--out".as_ref()),
        os(&design),
    ]);
    run(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());

    let mut parts = Vec::new();
    for (i, f) in files.iter().enumerate() {
        let part = dir.path().join(format!("p{i}.dynm"));
        let args = [
            os("moments".as_ref()),
            os(&model),
            os(f),
            os("--design".as_ref()),
            os(&design),
            os("--out".as_ref()),
            os(&part),
        ];
        run(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
        parts.push(part);
    }
    let size = std::fs::metadata(&parts[0]).unwrap().len();
    println!("two_mass, 200 s at 100 Hz: {size} bytes per .dynm piece");
    figures::check(DOC, "moments.kb.two_mass_200s", size as f64 / 1000.0);

    let whole_json = dir.path().join("whole.json");
    let mut args = vec![os("identify".as_ref()), os(&model)];
    args.extend(files.iter().map(|f| os(f)));
    args.extend([
        os("--no-corner-check".as_ref()),
        os("--json".as_ref()),
        os(&whole_json),
    ]);
    let whole = run(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());

    let from_json = dir.path().join("from.json");
    let mut args = vec![os("identify".as_ref()), os(&model), os("--from".as_ref())];
    args.extend(parts.iter().map(|p| os(p)));
    args.extend([os("--json".as_ref()), os(&from_json)]);
    let from = run(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());

    assert_eq!(
        String::from_utf8_lossy(&from.stdout),
        String::from_utf8_lossy(&whole.stdout)
    );
    assert_eq!(
        String::from_utf8_lossy(&from.stderr),
        String::from_utf8_lossy(&whole.stderr)
    );
    let read = |p: &std::path::Path| {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        // Where the time went differs from run to run.
        v.as_object_mut().unwrap().remove("times");
        v
    };
    assert_eq!(read(&from_json), read(&whole_json));
}
