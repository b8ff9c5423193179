//! Bad input against the release-like binary: each case must fail with its error code,
//! without a panic, without writing an output, and leave every input file as it was.
//! (Output paths that name an input are in `tests/output_paths.rs`.)

mod common;

use common::dynid;

use std::path::{Path, PathBuf};

fn model(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(name)
}

/// One case: the arguments (`{dir}` is replaced by the case's temporary directory) and
/// the error code the message must carry.
struct Case {
    name: &'static str,
    args: &'static [&'static str],
    code: &'static str,
}

/// Files written by `setup` into every case's directory.
fn setup(dir: &Path) {
    let st = dynid()
        .arg("simulate")
        .arg(model("sdof_linear.dyn"))
        .args(["--duration", "20", "--seed", "2", "--out"])
        .arg(dir.join("data"))
        .output()
        .unwrap();
    assert!(st.status.success());
    let level = std::fs::read_to_string(dir.join("data/level_1.csv")).unwrap();
    std::fs::write(dir.join("semicolon.csv"), level.replace(',', ";")).unwrap();
    std::fs::write(dir.join("tabs.csv"), level.replace(',', "\t")).unwrap();
    std::fs::write(dir.join("empty.csv"), "").unwrap();
    // Compiled models (JSON IR) with one defect each.
    let out = dynid()
        .arg("compile")
        .arg(model("sdof_linear.dyn"))
        .args(["--emit", "json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let ir: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let defect = |name: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = ir.clone();
        edit(&mut v);
        std::fs::write(dir.join(name), serde_json::to_string(&v).unwrap()).unwrap();
    };
    defect("param_index.json", &|v| {
        v["equations"][0]["terms"][1]["coef"]["param"] = 99.into();
    });
    defect("expr_index.json", &|v| {
        v["elements"][0]["terms"][0]["basis"] = 999.into();
    });
    defect("negative_mass.json", &|v| {
        v["bodies"][0]["mass"]["scale"] = (-1.0).into();
    });
    let mut lines: Vec<&str> = level.lines().collect();
    lines[7] = lines[6];
    std::fs::write(dir.join("repeated_time.csv"), lines.join("\n")).unwrap();
}

const CASES: &[Case] = &[
    Case {
        name: "a duration too long to hold in memory",
        args: &[
            "simulate",
            "{model}",
            "--duration",
            "1e9",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::config",
    },
    Case {
        name: "a duration that overflows the sample count",
        args: &[
            "simulate",
            "{model}",
            "--duration",
            "1e30",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::config",
    },
    Case {
        name: "a sample interval of 1e-300 s",
        args: &[
            "simulate",
            "{model}",
            "--sample",
            "1e-300",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::config",
    },
    Case {
        name: "an excitation level of 1e308 (the response overflows)",
        args: &[
            "simulate",
            "{model}",
            "--levels",
            "1e308",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::diverged",
    },
    Case {
        name: "a semicolon-separated level",
        args: &[
            "identify",
            "{model}",
            "{dir}/semicolon.csv",
            "{dir}/data/level_2.csv",
        ],
        code: "dynid::data::separator",
    },
    Case {
        name: "a tab-separated level",
        args: &[
            "identify",
            "{model}",
            "{dir}/tabs.csv",
            "{dir}/data/level_2.csv",
        ],
        code: "dynid::data::separator",
    },
    Case {
        name: "an empty level file",
        args: &["identify", "{model}", "{dir}/empty.csv"],
        code: "dynid::data::empty",
    },
    Case {
        name: "a repeated time stamp",
        args: &["identify", "{model}", "{dir}/repeated_time.csv"],
        code: "dynid::data::non_uniform_time",
    },
    Case {
        name: "a level file that does not exist",
        args: &["identify", "{model}", "{dir}/missing.csv"],
        code: "dynid::data::io",
    },
    Case {
        name: "filter corners above the Nyquist frequency (Ts = 0.01 s: 314 rad/s)",
        args: &[
            "identify",
            "{model}",
            "{dir}/data/level_1.csv",
            "--filter-corners",
            "50,200,400",
        ],
        code: "dynid::identify::option",
    },
    Case {
        name: "a plot named .jpg (only SVG and PNG are drawn)",
        args: &[
            "detect",
            "{model}",
            "{dir}/data/level_1.csv",
            "{dir}/data/level_2.csv",
            "{dir}/data/level_3.csv",
            "--plot",
            "{dir}/curves.jpg",
        ],
        code: "dynid::detect::plot_format",
    },
    Case {
        name: "a JSON model with a parameter index out of range",
        args: &["simulate", "{dir}/param_index.json", "--out", "{dir}/out"],
        code: "dynid::model::json",
    },
    Case {
        name: "a JSON model with an expression index out of range",
        args: &[
            "identify",
            "{dir}/expr_index.json",
            "{dir}/data/level_1.csv",
        ],
        code: "dynid::model::json",
    },
    Case {
        name: "a JSON model with a negative known mass",
        args: &["simulate", "{dir}/negative_mass.json", "--out", "{dir}/out"],
        code: "dynid::model::json",
    },
];

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
    let mut failures = Vec::new();
    for case in CASES {
        let before = snapshot(dir.path());
        let args: Vec<String> = case
            .args
            .iter()
            .map(|a| {
                a.replace("{dir}", &dir.path().display().to_string())
                    .replace("{model}", &model.display().to_string())
            })
            .collect();
        let out = dynid().args(&args).env("NO_COLOR", "1").output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        let problem = if out.status.success() {
            Some("accepted".to_string())
        } else if out.status.code() == Some(101) || err.contains("panicked") {
            Some(format!("panicked: {err}"))
        } else if !err.contains(case.code) {
            Some(format!("no `{}` in: {err}", case.code))
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
