//! Bad input against the release-like binary: each case must fail with its error code,
//! without a panic, without writing an output, and leave every input file as it was.
//! (Output paths that name an input are in `tests/output_paths.rs`.)

mod common;
mod formats_common;

use common::dynid;
use formats_common::{
    doubles, element, h5_vectors, mat5_file, mat5_matrix, mat5_vectors, mat73_matrix, matrix,
    parquet_with_null,
};

use std::path::{Path, PathBuf};

fn model(name: &str) -> PathBuf {
    common::model_path(name)
}

/// One case: the arguments (`{dir}` is replaced by the case's temporary directory and
/// `{model}` by a copy of `models/sdof_linear.dyn` in it), the error code the message must
/// carry, further text it must contain, and the bad file it reads, if it brings one.
struct Case {
    name: &'static str,
    args: &'static [&'static str],
    code: &'static str,
    also: &'static [&'static str],
    file: Option<File>,
}

/// A case's bad file: its path under `{dir}`, and its bytes made from the shared inputs.
struct File {
    name: &'static str,
    make: fn(&Inputs) -> Vec<u8>,
}

/// The fields a case leaves at their defaults (`..CASE`).
const CASE: Case = case("", &[], "");

const fn case(name: &'static str, args: &'static [&'static str], code: &'static str) -> Case {
    Case {
        name,
        args,
        code,
        also: &[],
        file: None,
    }
}

impl Case {
    /// The case with its bad file `name` (a path under `{dir}`), made by `make`.
    const fn with_file(self, name: &'static str, make: fn(&Inputs) -> Vec<u8>) -> Case {
        Case {
            file: Some(File { name, make }),
            ..self
        }
    }
}

/// The linear SDOF model with one line changed (`{line}` replaces the damper).
fn sdof_with(line: &str) -> String {
    let base = std::fs::read_to_string(model("sdof_linear.dyn")).unwrap();
    base.replace("damper d (ground, m) ~ 0.4", line)
}

fn text(s: &str) -> Vec<u8> {
    s.as_bytes().to_vec()
}

/// What the bad files are made from: level 1 of the simulated data (its text and its
/// columns) and the model compiled to JSON.
struct Inputs {
    level: String,
    names: Vec<String>,
    cols: Vec<Vec<f64>>,
    ir: serde_json::Value,
}

impl Inputs {
    /// Level 1 with its lines (0 = header) edited.
    fn edited(&self, edit: impl Fn(&mut Vec<String>)) -> Vec<u8> {
        let mut l: Vec<String> = self.level.lines().map(String::from).collect();
        edit(&mut l);
        (l.join("\n") + "\n").into_bytes()
    }

    /// The compiled model (JSON IR) with one defect.
    fn defect(&self, edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
        let mut v = self.ir.clone();
        edit(&mut v);
        serde_json::to_vec(&v).unwrap()
    }

    /// The columns with a NaN at sample 50 of `m.x`.
    fn with_nan(&self) -> Vec<Vec<f64>> {
        let mut cols = self.cols.clone();
        let x = self.names.iter().position(|n| n == "m.x").unwrap();
        cols[x][49] = f64::NAN;
        cols
    }

    /// Level 1 as a Parquet file.
    fn parquet(&self) -> Vec<u8> {
        written(|p| formats_common::parquet_file(&self.names, &self.cols, p))
    }
}

/// The bytes `write` puts into a file (for writers that take a path).
fn written(write: impl Fn(&Path)) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("f");
    write(&p);
    std::fs::read(p).unwrap()
}

/// Replace field `f` of line `i` (0 = header).
fn set(l: &mut [String], i: usize, f: usize, v: &str) {
    let mut fields: Vec<String> = l[i].split(',').map(String::from).collect();
    fields[f] = v.to_string();
    l[i] = fields.join(",");
}

/// The files every case may read (the simulated levels, a directory, a file to keep),
/// then each case's own bad file.
fn setup(dir: &Path) {
    let st = dynid()
        .arg("simulate")
        .arg(model("sdof_linear.dyn"))
        .args(["--duration", "20", "--seed", "2", "--out"])
        .arg(dir.join("data"))
        .output()
        .unwrap();
    assert!(st.status.success());
    std::fs::create_dir(dir.join("a_directory")).unwrap();
    std::fs::write(dir.join("existing_file"), "keep me\n").unwrap();
    let out = dynid()
        .arg("compile")
        .arg(model("sdof_linear.dyn"))
        .args(["--emit", "json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let (names, cols) = formats_common::read_csv(&dir.join("data/level_1.csv"));
    let inputs = Inputs {
        level: std::fs::read_to_string(dir.join("data/level_1.csv")).unwrap(),
        names,
        cols,
        ir: serde_json::from_slice(&out.stdout).unwrap(),
    };
    std::fs::create_dir(dir.join("bin")).unwrap();
    for f in CASES.iter().filter_map(|c| c.file.as_ref()) {
        std::fs::write(dir.join(f.name), (f.make)(&inputs)).unwrap();
    }
    moment_files(dir);
}

const DATA: &str = "{dir}/data/level_1.csv";

const CASES: &[Case] = &[
    // ---- Models ----
    case(
        "a syntax error",
        &["compile", "{dir}/syntax.dyn"],
        "dyn::syntax",
    )
    .with_file("syntax.dyn", |_| {
        text("model m {\n    body m = 1.0\n    spring k (ground, m) ~\n}\n")
    }),
    case(
        "an empty model file",
        &["compile", "{dir}/empty.dyn"],
        "dyn::syntax",
    )
    .with_file("empty.dyn", |_| Vec::new()),
    case(
        "a model file that does not exist",
        &["compile", "{dir}/missing.dyn"],
        "dyn::io",
    ),
    case(
        "a directory as the model",
        &["compile", "{dir}/a_directory"],
        "dyn::io",
    ),
    Case {
        name: "a model that is not UTF-8 (Latin-1 `é`)",
        args: &["compile", "{dir}/latin1.dyn"],
        code: "dyn::io",
        also: &["line 1, column 5"],
        ..CASE
    }
    .with_file("latin1.dyn", |_| {
        [
            &b"// d\xe9placement\n"[..],
            sdof_with("damper d (ground, m) ~ 0.4").as_bytes(),
        ]
        .concat()
    }),
    case(
        "an element on an undeclared body",
        &["compile", "{dir}/undefined.dyn"],
        "dyn::undefined_name",
    )
    .with_file("undefined.dyn", |_| {
        sdof_with("damper d (ground, q) ~ 0.4").into()
    }),
    case(
        "a name declared twice",
        &["compile", "{dir}/duplicate.dyn"],
        "dyn::duplicate_name",
    )
    .with_file("duplicate.dyn", |_| {
        sdof_with("damper k (ground, m) ~ 0.4").into()
    }),
    case(
        "an unknown function",
        &["compile", "{dir}/bad_call.dyn"],
        "dyn::invalid_call",
    )
    .with_file("bad_call.dyn", |_| {
        sdof_with("force f (ground, m) = c ~ 1.0 * frob(s)").into()
    }),
    case(
        "a reserved word as a name",
        &["compile", "{dir}/reserved.dyn"],
        "dyn::reserved_name",
    )
    .with_file("reserved.dyn", |_| {
        sdof_with("damper ground (ground, m) ~ 0.4").into()
    }),
    case(
        "a model with nothing to identify",
        &["identify", "{dir}/nothing_unknown.dyn", DATA],
        "dyn::nothing_to_identify",
    )
    .with_file("nothing_unknown.dyn", |_| {
        text("model m {\n    body m = 1.0\n    input u on m\n    spring k (ground, m) = 4.0\n}\n")
    }),
    case(
        "a model whose signals are not in the data",
        &["identify", "{two_mass}", DATA],
        "dynid::data::missing_column",
    ),
    Case {
        name: "a term `((s^64)^64)^64` that overflows on the data (level 3: |s| > 1)",
        args: &[
            "identify",
            "{dir}/power_tower.dyn",
            "{dir}/data/level_3.csv",
        ],
        code: "dynid::identify::non_finite_term",
        also: &["((m.x^64)^64)^64", "sample"],
        ..CASE
    }
    .with_file("power_tower.dyn", |_| {
        sdof_with("damper d (ground, m) ~ 0.4\n    force p (ground, m) = c ~ 0.0 * ((s^64)^64)^64")
            .into()
    }),
    Case {
        name: "`sqrt(s)` on data where s < 0",
        args: &["identify", "{dir}/sqrt_negative.dyn", DATA],
        code: "dynid::identify::non_finite_term",
        also: &["sqrt(m.x)", "NaN", "sample 2"],
        ..CASE
    }
    .with_file("sqrt_negative.dyn", |_| {
        sdof_with("damper d (ground, m) ~ 0.4\n    force p (ground, m) = c ~ 0.0 * sqrt(s)").into()
    }),
    Case {
        name: "`exp(1000 s)` overflowing on the data",
        args: &[
            "identify",
            "{dir}/exp_overflow.dyn",
            "{dir}/data/level_3.csv",
        ],
        code: "dynid::identify::non_finite_term",
        also: &["inf"],
        ..CASE
    }
    .with_file("exp_overflow.dyn", |_| {
        sdof_with("damper d (ground, m) ~ 0.4\n    force p (ground, m) = c ~ 0.0 * exp(1000 * s)")
            .into()
    }),
    case(
        "a JSON model that is not JSON",
        &["identify", "{dir}/garbage.json", DATA],
        "dynid::model::json",
    )
    .with_file("garbage.json", |_| text("{\"bodies\": [")),
    case(
        "a JSON model with a parameter index out of range",
        &["simulate", "{dir}/param_index.json", "--out", "{dir}/out"],
        "dynid::model::json",
    )
    .with_file("param_index.json", |i| {
        i.defect(|v| v["equations"][0]["terms"][1]["coef"]["param"] = 99.into())
    }),
    case(
        "a JSON model with an expression index out of range",
        &["identify", "{dir}/expr_index.json", DATA],
        "dynid::model::json",
    )
    .with_file("expr_index.json", |i| {
        i.defect(|v| v["elements"][0]["terms"][0]["basis"] = 999.into())
    }),
    case(
        "a JSON model with a negative known mass",
        &["simulate", "{dir}/negative_mass.json", "--out", "{dir}/out"],
        "dynid::model::json",
    )
    .with_file("negative_mass.json", |i| {
        i.defect(|v| v["bodies"][0]["mass"]["scale"] = (-1.0).into())
    }),
    // ---- Data ----
    case(
        "a level file that does not exist",
        &["identify", "{model}", "{dir}/missing.csv"],
        "dynid::data::io",
    ),
    case(
        "a directory as a level file",
        &["identify", "{model}", "{dir}/a_directory"],
        "dynid::data::io",
    ),
    case(
        "an empty level file",
        &["identify", "{model}", "{dir}/empty.csv"],
        "dynid::data::empty",
    )
    .with_file("empty.csv", |_| Vec::new()),
    case(
        "a header without samples",
        &["identify", "{model}", "{dir}/header_only.csv"],
        "dynid::data::header_only",
    )
    .with_file("header_only.csv", |i| i.edited(|l| l.truncate(1))),
    case(
        "a binary file as a level",
        &["identify", "{model}", "{dir}/binary.csv"],
        "dynid::data::binary",
    )
    .with_file("binary.csv", |_| {
        let mut b: Vec<u8> = (0..4000u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect();
        b[0] = 0xff;
        b
    }),
    // ---- Binary data files ----
    Case {
        name: "a truncated MAT v5 file",
        args: &["identify", "{model}", "{dir}/bin/truncated.mat"],
        code: "dynid::data::format",
        also: &["truncated.mat", "MAT v5", "truncated"],
        ..CASE
    }
    .with_file("bin/truncated.mat", |i| {
        let v5 = mat5_vectors(&i.names, &i.cols, false);
        v5[..v5.len() / 2].to_vec()
    }),
    Case {
        name: "a truncated compressed MAT v7 file",
        args: &["identify", "{model}", "{dir}/bin/truncated_v7.mat"],
        code: "dynid::data::format",
        also: &["truncated"],
        ..CASE
    }
    .with_file("bin/truncated_v7.mat", |i| {
        let v7 = mat5_vectors(&i.names, &i.cols, true);
        v7[..v7.len() - 100].to_vec()
    }),
    Case {
        name: "a MAT file cut inside its header",
        args: &["identify", "{model}", "{dir}/bin/header_cut.mat"],
        code: "dynid::data::format",
        also: &["128-byte header"],
        ..CASE
    }
    .with_file("bin/header_cut.mat", |i| {
        mat5_vectors(&i.names, &i.cols, false)[..60].to_vec()
    }),
    Case {
        name: "a MAT file with no variables",
        args: &["identify", "{model}", "{dir}/bin/header_only.mat"],
        code: "dynid::data::missing_column",
        also: &["no variables"],
        ..CASE
    }
    .with_file("bin/header_only.mat", |i| {
        mat5_vectors(&i.names, &i.cols, false)[..128].to_vec()
    }),
    Case {
        name: "a MAT file whose signal is text",
        args: &["identify", "{model}", "{dir}/bin/wrong_type.mat"],
        code: "dynid::data::missing_column",
        also: &["`m.x`", "m.x (char 1×5)"],
        ..CASE
    }
    .with_file("bin/wrong_type.mat", |i| {
        // `m.x` as text.
        let els: Vec<Vec<u8>> = i
            .names
            .iter()
            .zip(&i.cols)
            .map(|(n, c)| match n.as_str() {
                "m.x" => matrix(
                    4,
                    &[1, 5],
                    "m.x",
                    &element(4, &[b'h', 0, b'e', 0, b'l', 0, b'l', 0, b'o', 0]),
                ),
                _ => matrix(6, &[c.len(), 1], n, &doubles(c)),
            })
            .collect();
        mat5_file(&els, true)
    }),
    Case {
        name: "a MAT file without a signal",
        args: &["identify", "{model}", "{dir}/bin/missing_u.mat"],
        code: "dynid::data::missing_column",
        also: &["`u`", "the file holds: t (double", "--map NAME=u"],
        ..CASE
    }
    .with_file("bin/missing_u.mat", |i| {
        let (n, c): (Vec<String>, Vec<Vec<f64>>) = i
            .names
            .iter()
            .cloned()
            .zip(i.cols.iter().cloned())
            .filter(|(n, _)| n != "u")
            .unzip();
        mat5_vectors(&n, &c, true)
    }),
    Case {
        name: "a NaN in a MAT v5 file",
        args: &["identify", "{model}", "{dir}/bin/nan.mat"],
        code: "dynid::data::non_finite",
        also: &["sample 50", "`m.x`", "NaN"],
        ..CASE
    }
    .with_file("bin/nan.mat", |i| {
        mat5_vectors(&i.names, &i.with_nan(), false)
    }),
    Case {
        name: "a NaN in a MAT v7.3 file",
        args: &["identify", "{model}", "{dir}/bin/nan_v73.mat"],
        code: "dynid::data::non_finite",
        also: &["sample 50"],
        ..CASE
    }
    .with_file("bin/nan_v73.mat", |i| mat73_matrix(&i.names, &i.with_nan())),
    Case {
        name: "a NaN in an HDF5 file",
        args: &["identify", "{model}", "{dir}/bin/nan.h5"],
        code: "dynid::data::non_finite",
        also: &["sample 50"],
        ..CASE
    }
    .with_file("bin/nan.h5", |i| h5_vectors(&i.names, &i.with_nan())),
    Case {
        name: "a names variable that does not fit the matrix",
        args: &["identify", "{model}", "{dir}/bin/names_short.mat"],
        code: "dynid::data::format",
        also: &["`names` holds 3 names"],
        ..CASE
    }
    .with_file("bin/names_short.mat", |i| {
        // A `names` cell with one name fewer than the matrix has columns.
        mat5_matrix(&i.names[..i.names.len() - 1], &i.cols)
    }),
    Case {
        name: "a MAT v7.3 names cell holding a number",
        args: &["identify", "{model}", "{dir}/bin/names_cell_number_v73.mat"],
        code: "dynid::data::format",
        also: &["of `names` holds double, not a char vector"],
        ..CASE
    }
    .with_file("bin/names_cell_number_v73.mat", |i| {
        // A v7.3 `names` cell whose last cell is a number, not a char vector.
        let (names, cols) = (&i.names, &i.cols);
        let mut b = hdf5_pure::mat::MatBuilder::new(Default::default());
        let flat: Vec<f64> = cols.iter().flatten().copied().collect();
        b.write_f64("data", &[cols[0].len(), cols.len()], &flat)
            .unwrap();
        b.cell("names", &[1, names.len()], |c| {
            for n in &names[..names.len() - 1] {
                c.push_char(n)?;
            }
            c.push_scalar_f64(3.0)?;
            Ok(())
        })
        .unwrap();
        b.finish().unwrap()
    }),
    case(
        "a truncated HDF5 file",
        &["identify", "{model}", "{dir}/bin/truncated.h5"],
        "dynid::data::format",
    )
    .with_file("bin/truncated.h5", |i| {
        let h5 = h5_vectors(&i.names, &i.cols);
        h5[..h5.len() / 2].to_vec()
    }),
    case(
        "a truncated MAT v7.3 file",
        &["identify", "{model}", "{dir}/bin/truncated_v73.mat"],
        "dynid::data::format",
    )
    .with_file("bin/truncated_v73.mat", |i| {
        let m = mat73_matrix(&i.names, &i.cols);
        m[..m.len() * 2 / 3].to_vec()
    }),
    case(
        "a truncated Parquet file",
        &["identify", "{model}", "{dir}/bin/truncated.parquet"],
        "dynid::data::format",
    )
    .with_file("bin/truncated.parquet", |i| {
        let pq = i.parquet();
        pq[..pq.len() - 40].to_vec()
    }),
    case(
        "a Parquet file with damaged metadata",
        &["identify", "{model}", "{dir}/bin/corrupt.parquet"],
        "dynid::data::format",
    )
    .with_file("bin/corrupt.parquet", |i| {
        // The footer's metadata damaged (its length and the closing `PAR1` kept).
        let mut pq = i.parquet();
        let end = pq.len() - 8;
        pq[end - 40..end].iter_mut().for_each(|b| *b ^= 0x5a);
        pq
    }),
    Case {
        name: "a null in a Parquet column",
        args: &["identify", "{model}", "{dir}/bin/null.parquet"],
        code: "dynid::data::format",
        also: &["`m.x`", "sample 78"],
        ..CASE
    }
    .with_file("bin/null.parquet", |i| {
        written(|p| {
            let x = i.names.iter().position(|n| n == "m.x").unwrap();
            parquet_with_null(&i.names, &i.cols, x, 77, p)
        })
    }),
    Case {
        name: "text named .mat",
        args: &["identify", "{model}", "{dir}/bin/text.mat"],
        code: "dynid::data::format",
        also: &["the name says MAT-file"],
        ..CASE
    }
    .with_file("bin/text.mat", |_| b"t,m.x\n0,1\n".to_vec()),
    Case {
        name: "an empty .h5 file",
        args: &["identify", "{model}", "{dir}/bin/empty.h5"],
        code: "dynid::data::format",
        also: &["is empty"],
        ..CASE
    }
    .with_file("bin/empty.h5", |_| Vec::new()),
    Case {
        name: "a TDMS file",
        args: &["identify", "{model}", "{dir}/bin/run.tdms"],
        code: "dynid::data::unknown_format",
        also: &["NI TDMS", "MATLAB .mat", "HDF5", "Parquet"],
        ..CASE
    }
    .with_file("bin/run.tdms", |_| {
        b"TDSm\x00\x00\x00\x00 some acquisition".to_vec()
    }),
    case(
        "a semicolon-separated level",
        &[
            "identify",
            "{model}",
            "{dir}/semicolon.csv",
            "{dir}/data/level_2.csv",
        ],
        "dynid::data::separator",
    )
    .with_file("semicolon.csv", |i| i.level.replace(',', ";").into()),
    case(
        "a tab-separated level",
        &[
            "identify",
            "{model}",
            "{dir}/tabs.csv",
            "{dir}/data/level_2.csv",
        ],
        "dynid::data::separator",
    )
    .with_file("tabs.csv", |i| i.level.replace(',', "\t").into()),
    Case {
        name: "numbers with a decimal comma",
        args: &["identify", "{model}", "{dir}/decimal_comma.csv"],
        code: "dynid::data::ragged",
        also: &["decimal comma"],
        ..CASE
    }
    .with_file("decimal_comma.csv", |i| {
        i.edited(|l| {
            for row in l.iter_mut().skip(1) {
                *row = row.replace('.', ",");
            }
        })
    }),
    Case {
        name: "a quoted number with a decimal comma",
        args: &["identify", "{model}", "{dir}/quoted_comma.csv"],
        code: "dynid::data::not_a_number",
        also: &["decimal comma", "line 13"],
        ..CASE
    }
    .with_file("quoted_comma.csv", |i| {
        i.edited(|l| set(l, 12, 1, "\"0,25\""))
    }),
    Case {
        name: "a row with a field missing",
        args: &["identify", "{model}", "{dir}/short_row.csv"],
        code: "dynid::data::ragged",
        also: &["line 41"],
        ..CASE
    }
    .with_file("short_row.csv", |i| {
        i.edited(|l| {
            let cut = l[40].rfind(',').unwrap();
            l[40].truncate(cut);
        })
    }),
    Case {
        name: "a NaN sample",
        args: &["identify", "{model}", "{dir}/nan.csv"],
        code: "dynid::data::non_finite",
        also: &["line 34", "`m.x`"],
        ..CASE
    }
    .with_file("nan.csv", |i| i.edited(|l| set(l, 33, 1, "NaN"))),
    Case {
        name: "an infinite input sample",
        args: &["identify", "{model}", "{dir}/inf.csv"],
        code: "dynid::data::non_finite",
        also: &["line 35", "`u`"],
        ..CASE
    }
    .with_file("inf.csv", |i| i.edited(|l| set(l, 34, 3, "inf"))),
    Case {
        name: "a word where a number belongs",
        args: &["identify", "{model}", "{dir}/word.csv"],
        code: "dynid::data::not_a_number",
        also: &["line 36", "`abc`"],
        ..CASE
    }
    .with_file("word.csv", |i| i.edited(|l| set(l, 35, 2, "abc"))),
    case(
        "an empty field",
        &["identify", "{model}", "{dir}/blank_field.csv"],
        "dynid::data::not_a_number",
    )
    .with_file("blank_field.csv", |i| i.edited(|l| set(l, 36, 2, ""))),
    case(
        "a measured input column missing",
        &["identify", "{model}", "{dir}/no_u.csv"],
        "dynid::data::missing_column",
    )
    .with_file("no_u.csv", |i| {
        i.edited(|l| {
            for row in l.iter_mut() {
                let cut = row.rfind(',').unwrap();
                row.truncate(cut);
            }
        })
    }),
    case(
        "a column named twice",
        &["identify", "{model}", "{dir}/duplicate_column.csv"],
        "dynid::data::duplicate_column",
    )
    .with_file("duplicate_column.csv", |i| {
        i.edited(|l| set(l, 0, 2, "m.x"))
    }),
    case(
        "no time column and no --sample",
        &["identify", "{model}", "{dir}/no_time.csv"],
        "dynid::data::no_sample_interval",
    )
    .with_file("no_time.csv", |i| {
        i.edited(|l| {
            for row in l.iter_mut() {
                *row = row.split_once(',').unwrap().1.to_string();
            }
        })
    }),
    case(
        "no time column and --sample 0",
        &["identify", "{model}", "{dir}/no_time.csv", "--sample", "0"],
        "dynid::data::bad_sample_interval",
    ),
    Case {
        name: "a repeated time stamp",
        args: &["identify", "{model}", "{dir}/repeated_time.csv"],
        code: "dynid::data::non_uniform_time",
        also: &["does not increase", "line 8"],
        ..CASE
    }
    .with_file("repeated_time.csv", |i| i.edited(|l| l[7] = l[6].clone())),
    Case {
        name: "time stamps out of order",
        args: &["identify", "{model}", "{dir}/backwards_time.csv"],
        code: "dynid::data::non_uniform_time",
        also: &["line 21", "time step"],
        ..CASE
    }
    .with_file("backwards_time.csv", |i| i.edited(|l| l.swap(20, 21))),
    Case {
        name: "a missing sample (a gap in time)",
        args: &["identify", "{model}", "{dir}/gap_in_time.csv"],
        code: "dynid::data::non_uniform_time",
        also: &["line 51"],
        ..CASE
    }
    .with_file("gap_in_time.csv", |i| i.edited(|l| drop(l.remove(50)))),
    case(
        "too few samples",
        &["identify", "{model}", "{dir}/too_few.csv"],
        "dynid::data::too_few_samples",
    )
    .with_file("too_few.csv", |i| i.edited(|l| l.truncate(40))),
    case(
        "a record too short for the slowest filter",
        &["identify", "{model}", "{dir}/too_short.csv"],
        "dynid::identify::too_short",
    )
    .with_file("too_short.csv", |i| i.edited(|l| l.truncate(130))),
    Case {
        name: "one sample of 1e20 (a recording glitch)",
        args: &[
            "identify",
            "{model}",
            "{dir}/outlier.csv",
            "{dir}/data/level_2.csv",
        ],
        code: "dynid::data::outlier",
        also: &["`m.x`", "sample 500"],
        ..CASE
    }
    .with_file("outlier.csv", |i| i.edited(|l| set(l, 500, 1, "1e20"))),
    Case {
        name: "values of 1e300 (moments overflow)",
        args: &["identify", "{model}", "{dir}/huge.csv"],
        code: "dynid::identify::overflow",
        also: &["rescale"],
        ..CASE
    }
    .with_file("huge.csv", |i| {
        i.edited(|l| {
            for row in l.iter_mut().skip(1) {
                let f: Vec<String> = row.split(',').map(String::from).collect();
                let scaled: Vec<String> = f[1..]
                    .iter()
                    .map(|v| format!("{:e}", v.parse::<f64>().unwrap() * 1e300))
                    .collect();
                *row = format!("{},{}", f[0], scaled.join(","));
            }
        })
    }),
    case(
        "a level at rest (every signal zero)",
        &[
            "identify",
            "{model}",
            "{dir}/at_rest.csv",
            "{dir}/data/level_2.csv",
        ],
        "dynid::data::no_excitation",
    )
    .with_file("at_rest.csv", |i| {
        i.edited(|l| {
            for row in l.iter_mut().skip(1) {
                let t = row.split(',').next().unwrap().to_string();
                *row = format!("{t},0,0,0");
            }
        })
    }),
    case(
        "a level at rest in a diagnosis with a report",
        &[
            "diagnose",
            "{model}",
            DATA,
            "{dir}/at_rest.csv",
            "{dir}/data/level_3.csv",
            "--report",
            "{dir}/report.html",
        ],
        "dynid::data::no_excitation",
    ),
    case(
        "a bad --map",
        &["identify", "{model}", DATA, "--map", "x"],
        "dynid::data::bad_map",
    ),
    // ---- Flags ----
    case(
        "a duration of 1e9 s (10¹¹ samples: far beyond the size cap)",
        &[
            "simulate",
            "{model}",
            "--duration",
            "1e9",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "a duration that overflows the sample count",
        &[
            "simulate",
            "{model}",
            "--duration",
            "1e30",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    Case {
        name: "a negative duration",
        args: &[
            "simulate",
            "{model}",
            "--duration",
            "-5",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::config",
        also: &["duration -5"],
        ..CASE
    },
    case(
        "a duration of NaN",
        &[
            "simulate",
            "{model}",
            "--duration",
            "nan",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "a sample interval of 1e-300 s",
        &[
            "simulate",
            "{model}",
            "--sample",
            "1e-300",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "a sample interval of 0",
        &["simulate", "{model}", "--sample", "0", "--out", "{dir}/out"],
        "dynid::sim::config",
    ),
    case(
        "input oversampling 0",
        &[
            "simulate",
            "{model}",
            "--input-oversample",
            "0",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "0 RK4 sub-steps",
        &[
            "simulate",
            "{model}",
            "--substeps",
            "0",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "a negative noise fraction",
        &["simulate", "{model}", "--noise", "-1", "--out", "{dir}/out"],
        "dynid::sim::config",
    ),
    case(
        "a negative level in a list",
        &[
            "simulate",
            "{model}",
            "--levels",
            "-3,2",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "a quantisation step of 0",
        &[
            "simulate",
            "{model}",
            "--quantise",
            "0",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::config",
    ),
    case(
        "--pd with one gain",
        &["simulate", "{model}", "--pd", "3", "--out", "{dir}/out"],
        "dynid::simulate::option",
    ),
    case(
        "an excitation level of 1e308 (the response overflows)",
        &[
            "simulate",
            "{model}",
            "--levels",
            "1e308",
            "--out",
            "{dir}/out",
        ],
        "dynid::sim::diverged",
    ),
    Case {
        name: "a model that diverges at its second level only",
        args: &[
            "simulate",
            "{dir}/softening.dyn",
            "--duration",
            "20",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::diverged",
        also: &["level 2"],
        ..CASE
    }
    .with_file("softening.dyn", |_| {
        sdof_with("damper d (ground, m) ~ 0.4\n    force nl (ground, m) = k3 ~ -2.0 * s^3")
            .replace("levels [6, 15, 40]", "levels [0.5, 500]")
            .into()
    }),
    case(
        "--out naming an existing file",
        &["simulate", "{model}", "--out", "{dir}/existing_file"],
        "dynid::output::not_a_directory",
    ),
    case(
        "demo --keep-data naming an existing file",
        &[
            "demo",
            "--duration",
            "100",
            "--quiet",
            "--keep-data",
            "{dir}/existing_file",
            "--report",
            "{dir}/r.html",
        ],
        "dynid::output::not_a_directory",
    ),
    case(
        "simulate --input a level of the --out directory (the run replaces it)",
        &[
            "simulate",
            "{model}",
            "--input",
            "{dir}/data/level_1.csv",
            "--out",
            "{dir}/data",
        ],
        "dynid::output::is_input",
    ),
    case(
        "filter corners above the Nyquist frequency (Ts = 0.01 s: 314 rad/s)",
        &[
            "identify",
            "{model}",
            DATA,
            "--filter-corners",
            "50,200,400",
        ],
        "dynid::identify::option",
    ),
    case(
        "negative filter corners",
        &["identify", "{model}", DATA, "--filter-corners", "-3,2"],
        "dynid::identify::option",
    ),
    case(
        "detection from one file too short to split into levels",
        &["detect", "{model}", DATA],
        "dynid::split::too_short",
    ),
    case(
        "a diagnosis from one file too short to split into levels",
        &["diagnose", "{model}", DATA, "--segments", "2"],
        "dynid::split::too_short",
    ),
    case(
        "--split-by naming no column",
        &["detect", "{model}", DATA, "--split-by", "m.y"],
        "dynid::split::unknown_signal",
    ),
    case(
        "--segments with several files",
        &[
            "detect",
            "{model}",
            DATA,
            "{dir}/data/level_2.csv",
            "--segments",
            "3",
        ],
        "dynid::split::several_files",
    ),
    case(
        "--segments 1",
        &["detect", "{model}", DATA, "--segments", "1"],
        "must be at least 2",
    ),
    case(
        "a detection --alpha outside (0, 1)",
        &[
            "detect",
            "{model}",
            DATA,
            "{dir}/data/level_2.csv",
            "--alpha",
            "2",
        ],
        "dynid::detect::option",
    ),
    case(
        "an unknown flag",
        &["identify", "{model}", DATA, "--frobnicate"],
        "unexpected argument '--frobnicate'",
    ),
    case(
        "an unknown command",
        &["frobnicate"],
        "unrecognized subcommand 'frobnicate'",
    ),
    case(
        "an unknown --emit",
        &["compile", "{model}", "--emit", "pdf"],
        "invalid value 'pdf'",
    ),
    case("identify without data", &["identify", "{model}"], "<DATA>"),
    // ---- Counts from flags beyond what a machine word holds ----
    Case {
        name: "a filter corner of 1e-300 rad/s (a record length beyond any count)",
        args: &["identify", "{model}", DATA, "--filter-corners", "1e-300"],
        code: "dynid::identify::too_short",
        also: &[
            "time constant 3e300 s",
            "more samples than any record holds",
        ],
        ..CASE
    },
    Case {
        name: "--segments 18446744073709551615",
        args: &[
            "detect",
            "{model}",
            DATA,
            "--segments",
            "18446744073709551615",
        ],
        code: "dynid::split::too_short",
        also: &["too short for 18446744073709551615 segments"],
        ..CASE
    },
    Case {
        name: "--refine --substeps 18446744073709551615",
        args: &[
            "identify",
            "{model}",
            DATA,
            "--refine",
            "--substeps",
            "18446744073709551615",
        ],
        code: "dynid::sim::too_long",
        also: &["RK4 sub-steps", "--allow-long"],
        ..CASE
    },
    Case {
        name: "--duration 1e300 at --sample 1e-300",
        args: &[
            "simulate",
            "{model}",
            "--duration",
            "1e300",
            "--sample",
            "1e-300",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::config",
        also: &["inf samples per level"],
        ..CASE
    },
    Case {
        name: "simulate --substeps 18446744073709551615",
        args: &[
            "simulate",
            "{model}",
            "--substeps",
            "18446744073709551615",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::too_long",
        also: &["--allow-long"],
        ..CASE
    },
    // ---- Moment statistics ----
    case(
        "identify --from a CSV file",
        &["identify", "{model}", "--from", DATA],
        "dynid::moments::not_moments",
    ),
    case(
        "identify --from a .dynm cut short",
        &["identify", "{model}", "--from", "{dir}/truncated.dynm"],
        "dynid::moments::truncated",
    ),
    case(
        "identify --from a .dynm of another format version",
        &["identify", "{model}", "--from", "{dir}/version.dynm"],
        "dynid::moments::version",
    ),
    case(
        "identify --from the statistics of another model",
        &[
            "identify",
            "{dir}/other_model.dyn",
            "--from",
            "{dir}/part1.dynm",
        ],
        "dynid::moments::other_model",
    ),
    Case {
        name: "identify --from pieces of two designs",
        args: &[
            "identify",
            "{model}",
            "--from",
            "{dir}/part1.dynm",
            "{dir}/corners.dynm",
        ],
        code: "dynid::moments::other_design",
        also: &["corners.dynm against the files before it"],
        ..CASE
    },
    case(
        "moments --out onto its data file",
        &["moments", "{model}", DATA, "--out", DATA],
        "dynid::output::is_input",
    ),
    case(
        "moments --design that is not a design",
        &[
            "moments",
            "{model}",
            DATA,
            "--design",
            "{dir}/not_a_design.json",
            "--out",
            "{dir}/p.dynm",
        ],
        "dynid::moments::design",
    )
    .with_file("not_a_design.json", |_| text("{\"corners\": [")),
    // ---- Outputs ----
    case(
        "a plot named .jpg (only SVG and PNG are drawn)",
        &[
            "detect",
            "{model}",
            DATA,
            "{dir}/data/level_2.csv",
            "{dir}/data/level_3.csv",
            "--plot",
            "{dir}/curves.jpg",
        ],
        "dynid::detect::plot_format",
    ),
    case(
        "--json onto a level file",
        &["identify", "{model}", DATA, "--json", DATA],
        "dynid::output::is_input",
    ),
    case(
        "--json onto a directory",
        &["identify", "{model}", DATA, "--json", "{dir}/a_directory"],
        "dynid::output::is_directory",
    ),
    case(
        "--json into a directory that does not exist",
        &[
            "identify",
            "{model}",
            DATA,
            "--json",
            "{dir}/nowhere/id.json",
        ],
        "dynid::output::no_directory",
    ),
];

/// Moment statistics of level 1 and 2 (`part1.dynm`, `part2.dynm`), of level 2 with other
/// corners, cut short, of another format version; a model that differs in one nominal.
fn moment_files(dir: &Path) {
    let part = |level: &str, out: &str, extra: &[&str]| {
        let st = dynid()
            .arg("moments")
            .arg(model("sdof_linear.dyn"))
            .arg(dir.join("data").join(level))
            .args(extra)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap();
        assert!(st.status.success(), "{}", common::stderr(&st));
    };
    part("level_1.csv", "part1.dynm", &[]);
    part("level_2.csv", "part2.dynm", &[]);
    part(
        "level_2.csv",
        "corners.dynm",
        &["--filter-corners", "2,4,8"],
    );
    let bytes = std::fs::read(dir.join("part1.dynm")).unwrap();
    std::fs::write(dir.join("truncated.dynm"), &bytes[..bytes.len() / 2]).unwrap();
    let mut version = bytes.clone();
    version[8] = 9;
    std::fs::write(dir.join("version.dynm"), version).unwrap();
    std::fs::write(
        dir.join("other_model.dyn"),
        sdof_with("damper d (ground, m) ~ 0.5"),
    )
    .unwrap();
}

/// Every file below `dir` with its content.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let bytes = std::fs::read(&p).unwrap();
                out.push((p, bytes));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_bad_input_is_refused_with_its_code_and_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let model = dir.path().join("sdof_linear.dyn");
    std::fs::copy(self::model("sdof_linear.dyn"), &model).unwrap();
    assert!(CASES.len() >= 60, "the catalogue has {} cases", CASES.len());
    let mut failures = Vec::new();
    for case in CASES {
        let before = snapshot(dir.path());
        let args: Vec<String> = case
            .args
            .iter()
            .map(|a| {
                a.replace("{dir}", &dir.path().display().to_string())
                    .replace("{model}", &model.display().to_string())
                    .replace(
                        "{two_mass}",
                        &self::model("two_mass.dyn").display().to_string(),
                    )
            })
            .collect();
        let out = dynid().args(&args).env("NO_COLOR", "1").output().unwrap();
        // The message as one line: miette wraps it at 80 columns behind `│` rails.
        let err = String::from_utf8_lossy(&out.stderr)
            .split_whitespace()
            .filter(|w| !matches!(*w, "│" | "×" | "help:"))
            .collect::<Vec<_>>()
            .join(" ");
        let problem = if out.status.success() {
            Some("accepted".to_string())
        } else if out.status.code() == Some(101) || err.contains("panicked") {
            Some(format!("panicked: {err}"))
        } else if !err.contains(case.code) {
            Some(format!("no `{}` in: {err}", case.code))
        } else if let Some(t) = case.also.iter().find(|t| !err.contains(**t)) {
            Some(format!("no `{t}` in: {err}"))
        } else if snapshot(dir.path()) != before {
            Some("files changed".into())
        } else {
            None
        };
        if let Some(p) = problem {
            failures.push(format!("{}: {p}", case.name));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
