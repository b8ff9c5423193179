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
use dynid_runtime::data::fuzz::FUZZ_MODEL;
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
            "MAT v7.3, matrix and names cell",
            write("v73c", "mat", &bytes(mat73_matrix_cell)),
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
        (
            "Parquet, ZSTD (polars' default)",
            write("pqz", "parquet", &|n, c, p| {
                let zstd = parquet::basic::ZstdLevel::try_new(3).unwrap();
                parquet_file_compressed(n, c, p, parquet::basic::Compression::ZSTD(zstd))
            }),
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

// ---- the readers under damaged files ------------------------------------------------------

/// Small files of every binary layout above, of one record (`t`, `m.x`, `u`; 128 samples):
/// the seeds of the `binary` fuzz target and of the miniature below.
fn small_seed_files(dir: &Path) -> Vec<PathBuf> {
    let n = 128;
    let names: Vec<String> = ["t", "m.x", "u"].iter().map(|s| s.to_string()).collect();
    let cols: Vec<Vec<f64>> = vec![
        (0..n).map(|i| i as f64 * 0.01).collect(),
        (0..n).map(|i| (i as f64 * 0.1).sin() * 1e-3).collect(),
        (0..n).map(|i| (i as f64 * 0.37).cos()).collect(),
    ];
    let m = matlab(&names);
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("v5.mat", mat5_vectors(&m, &cols, false)),
        ("v7.mat", mat5_vectors(&m, &cols, true)),
        ("v5m.mat", mat5_matrix(&names, &cols)),
        ("v73.mat", mat73_vectors(&m, &cols)),
        ("v73m.mat", mat73_matrix(&names, &cols)),
        ("vec.h5", h5_vectors(&names, &cols)),
        ("mat.h5", h5_matrix(&names, &cols)),
    ];
    let mut out: Vec<PathBuf> = files
        .into_iter()
        .map(|(name, bytes)| {
            let p = dir.join(name);
            std::fs::write(&p, bytes).unwrap();
            p
        })
        .collect();
    let p = dir.join("pq.parquet");
    parquet_file(&names, &cols, &p);
    out.push(p);
    out
}

#[test]
fn the_binary_readers_survive_damaged_files() {
    // A deterministic miniature of `fuzz/fuzz_targets/binary.rs`: every seed file intact
    // (read whole and streamed: the property holds and the data come back), then 60
    // damaged copies of each — bytes overwritten with 0x00, 0xff or a random byte, cut short,
    // a stretch repeated — through the same `check_data_file`, which panics if a reader
    // breaks its contract (a panic, a non-finite value, a ragged or short record).
    use dynid_runtime::data::{fuzz::check_data_file, read_record, CsvOptions};
    let dir = tempfile::tempdir().unwrap();
    let ir = dsl_parser::compile_str("fuzz.dyn", FUZZ_MODEL).unwrap();
    let seeds = small_seed_files(dir.path());
    let map = CsvOptions {
        map: vec![("m_x".into(), "m.x".into())],
        ..Default::default()
    };
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let damaged = dir.path().join("damaged");
    for seed in &seeds {
        // Vectors carry MATLAB's names (`m_x`); matrices, HDF5 and Parquet the signals'.
        let rec = read_record(seed, &CsvOptions::default())
            .or_else(|e| read_record(seed, &map).map_err(|f| format!("{e}; with --map: {f}")))
            .unwrap_or_else(|e| panic!("{}: {e}", seed.display()));
        assert_eq!(rec.len(), 128, "{}", seed.display());
        check_data_file(seed, &ir);
        let bytes = std::fs::read(seed).unwrap();
        for _ in 0..60 {
            let mut b = bytes.clone();
            let at = (next() as usize) % b.len();
            match next() % 4 {
                0 => {
                    let k = 1 + (next() as usize) % 8;
                    let v = [0x00, 0xff, next() as u8][(next() % 3) as usize];
                    let end = (at + k).min(b.len());
                    b[at..end].iter_mut().for_each(|x| *x = v);
                }
                1 => b.truncate(at),
                2 => {
                    let end = (at + 1 + (next() as usize) % 64).min(b.len());
                    let stretch = b[at..end].to_vec();
                    b.splice(at..at, stretch);
                }
                _ => b[at] ^= 1 << (next() % 8),
            }
            std::fs::write(&damaged, &b).unwrap();
            check_data_file(&damaged, &ir);
        }
    }
}

#[test]
fn inputs_the_fuzzers_found_are_refused_cleanly() {
    // Files the fuzz targets reported, kept as regression cases: a Parquet file whose
    // dictionary page the crate's decoder asserted on (a panic, now a format error that calls
    // the file damaged), an HDF5 file with a damaged chunk layout, and a text file of time
    // stamps alone (a record without columns).
    use dynid_runtime::data::{fuzz, CsvOptions, FileSource};
    let ir = dsl_parser::compile_str("fuzz.dyn", FUZZ_MODEL).unwrap();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let pq = dir.join("parquet_without_dictionary.parquet");
    fuzz::check_data_file(&pq, &ir);
    let opened = FileSource::open(&pq, &ir, &CsvOptions::default());
    let err = match opened {
        Ok(src) => {
            use dynid_runtime::data::LevelSource;
            src.stream(97, &mut |_, _| {})
                .expect_err("the damaged page is an error")
        }
        Err(e) => e,
    };
    let msg = err.to_string();
    assert!(msg.contains("damaged") && msg.contains("Parquet"), "{msg}");
    // An HDF5 file whose chunk layout would have `hdf5-pure` allocate petabytes (an
    // abort, not a panic): refused before reading.
    let h5 = dir.join("hdf5_chunk_grid.h5");
    fuzz::check_data_file(&h5, &ir);
    let msg = match FileSource::open(&h5, &ir, &CsvOptions::default()) {
        Ok(_) => panic!("the damaged chunk layout is read"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains("chunk layout"), "{msg}");
    let csv = dir.join("time_only.csv");
    fuzz::check_csv_bytes(&csv, &std::fs::read(&csv).unwrap(), &ir);
    fuzz::check_data_file(&csv, &ir);
}

#[test]
#[ignore = "writes the binary fuzz target's seed files into $DYNID_FUZZ_SEEDS"]
fn write_binary_fuzz_seeds() {
    let dir = PathBuf::from(std::env::var("DYNID_FUZZ_SEEDS").expect("DYNID_FUZZ_SEEDS=DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    for p in small_seed_files(&dir) {
        println!("{}", p.display());
    }
}
