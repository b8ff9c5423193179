//! The same records written as CSV, delimited text with comments and a units row, MATLAB
//! MAT v5 (uncompressed, compressed, one matrix with a `names` cell), MAT v7.3 (HDF5 with
//! MATLAB's layout: column vectors, and one matrix with a `names` char row), HDF5 (chunked
//! and deflated 1-D datasets, and one matrix with string names) and Parquet (two row groups,
//! Snappy pages): `dynid identify` gives the same JSON from each, every number equal to
//! 1e-12 relative (in practice the same bits: every reader hands on the same `f64`s in the
//! same chunks).
//!
//! The writers are in `tests/formats_common`.

mod common;
mod formats_common;

use common::{dynid, setup_linear_levels, stderr};
use formats_common::*;
use std::path::{Path, PathBuf};

// ---- the test ----------------------------------------------------------------------------

/// Every number of two JSON values equal to `tol` relative (strings: equal, except the
/// levels' `origin`, which names the file).
fn same_numbers(a: &serde_json::Value, b: &serde_json::Value, tol: f64, at: &str) {
    use serde_json::Value as V;
    match (a, b) {
        (V::Number(x), V::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= tol * x.abs().max(y.abs()),
                "{at}: {x} vs {y}"
            );
        }
        (V::Object(x), V::Object(y)) => {
            assert_eq!(x.len(), y.len(), "{at}: keys differ");
            for (k, v) in x {
                if k == "origin" {
                    continue;
                }
                same_numbers(v, &y[k], tol, &format!("{at}.{k}"));
            }
        }
        (V::Array(x), V::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}: lengths differ");
            for (i, (u, v)) in x.iter().zip(y).enumerate() {
                same_numbers(u, v, tol, &format!("{at}[{i}]"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

/// MATLAB variable names for the signals (a name cannot hold a dot: `m.x` becomes `m_x`).
fn matlab(names: &[String]) -> Vec<String> {
    names.iter().map(|n| n.replace('.', "_")).collect()
}

/// The renamings of [`matlab`]'s names back to the signals.
const MAP: &[&str] = &["--map", "m_x=m.x", "--map", "m_v=m.v"];

fn identify(model: &Path, files: &[PathBuf], extra: &[&str], out: &Path) -> serde_json::Value {
    let o = dynid()
        .arg("identify")
        .arg(model)
        .args(files)
        .args(extra)
        .arg("--json")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{files:?}: {}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap()
}

/// Writes one record (names, columns) to a file.
type Writer = dyn Fn(&[String], &[Vec<f64>], &Path);

#[test]
fn every_format_identifies_as_the_csv_of_the_same_data() {
    let dir = tempfile::tempdir().unwrap();
    let (model, csvs) = setup_linear_levels(dir.path());
    let reference = identify(&model, &csvs, &[], &dir.path().join("csv.json"));
    let write = |stem: &str, ext: &str, f: &Writer| {
        csvs.iter()
            .enumerate()
            .map(|(i, csv)| {
                let (names, cols) = read_csv(csv);
                let p = dir.path().join(format!("{stem}_{}.{ext}", i + 1));
                f(&names, &cols, &p);
                p
            })
            .collect::<Vec<_>>()
    };
    let bytes = |g: fn(&[String], &[Vec<f64>]) -> Vec<u8>| {
        move |n: &[String], c: &[Vec<f64>], p: &Path| std::fs::write(p, g(n, c)).unwrap()
    };
    let cases: Vec<(&str, Vec<PathBuf>, Vec<&str>)> = vec![
        (
            "text: `;`, comments, units row",
            write("semicolon", "txt", &|n, c, p| {
                let mut s = "# rig 3, run 7\n# exported by the logger\n".to_string();
                s += &n.join(";");
                s += "\n";
                s += &vec!["s"; n.len()].join(";");
                s += "\n";
                for i in 0..c[0].len() {
                    if i == 100 {
                        s += "# a comment between samples\n";
                    }
                    let row: Vec<String> = c.iter().map(|col| format!("{:?}", col[i])).collect();
                    s += &row.join(";");
                    s += "\n";
                }
                std::fs::write(p, s).unwrap();
            }),
            vec!["--delimiter", ";", "--comment", "#", "--units-row"],
        ),
        (
            "MAT v5, one vector per signal",
            write(
                "v5",
                "mat",
                &bytes(|n, c| mat5_vectors(&matlab(n), c, false)),
            ),
            MAP.to_vec(),
        ),
        (
            "MAT v5 compressed (v7)",
            write(
                "v7",
                "mat",
                &bytes(|n, c| mat5_vectors(&matlab(n), c, true)),
            ),
            MAP.to_vec(),
        ),
        (
            "MAT v5, matrix and names cell",
            write("v5m", "mat", &bytes(mat5_matrix)),
            vec![],
        ),
        (
            "MAT v7.3, column vectors",
            write("v73", "mat", &bytes(|n, c| mat73_vectors(&matlab(n), c))),
            MAP.to_vec(),
        ),
        (
            "MAT v7.3, matrix and names",
            write("v73m", "mat", &bytes(mat73_matrix)),
            vec![],
        ),
        (
            "HDF5, chunked deflated vectors",
            write("vec", "h5", &bytes(h5_vectors)),
            vec![],
        ),
        (
            "HDF5, matrix and names",
            write("mat", "h5", &bytes(h5_matrix)),
            vec![],
        ),
        (
            "Parquet, two row groups",
            write("pq", "parquet", &parquet_file),
            vec![],
        ),
    ];
    for (case, files, extra) in cases {
        let got = identify(&model, &files, &extra, &dir.path().join("out.json"));
        same_numbers(&reference, &got, 1e-12, case);
    }
}

#[test]
fn binary_files_are_told_by_content_not_name() {
    // A MAT v5 file named `.csv` and a Parquet file named `.dat` are read all the same.
    let dir = tempfile::tempdir().unwrap();
    let (model, csvs) = setup_linear_levels(dir.path());
    let reference = identify(&model, &csvs, &[], &dir.path().join("csv.json"));
    let files: Vec<PathBuf> = csvs
        .iter()
        .enumerate()
        .map(|(i, csv)| {
            let (names, cols) = read_csv(csv);
            if i == 0 {
                let p = dir.path().join("misnamed.csv");
                std::fs::write(&p, mat5_matrix(&names, &cols)).unwrap();
                p
            } else {
                let p = dir.path().join(format!("misnamed_{i}.dat"));
                parquet_file(&names, &cols, &p);
                p
            }
        })
        .collect();
    let got = identify(&model, &files, &[], &dir.path().join("out.json"));
    same_numbers(&reference, &got, 1e-12, "misnamed");
}
