//! Messages that must say what is wrong: each bad input is refused with its code and with
//! the words that name the real problem, never echoes a control or invisible character to
//! the terminal, and changes no file. (The catalogue of refusals is `tests/bad_inputs.rs`;
//! these are the cases whose message, not only whose refusal, is the point.)

mod common;

use common::dynid;

use std::path::{Path, PathBuf};

fn model(name: &str) -> PathBuf {
    common::model_path(name)
}

/// One case: arguments (`{dir}` is the case directory, `{model}` a copy of
/// `models/sdof_linear.dyn` in it), the code, text the message must contain and text it
/// must not.
struct Case {
    name: &'static str,
    args: &'static [&'static str],
    code: &'static str,
    also: &'static [&'static str],
    not: &'static [&'static str],
}

/// Characters that must never reach the terminal raw from a quoted file.
const RAW: &[char] = &['\0', '\x1b', '\u{feff}', '\u{200b}', '\u{202e}'];

fn utf16le(text: &str) -> Vec<u8> {
    std::iter::once(0xfeff_u16)
        .chain(text.encode_utf16())
        .flat_map(u16::to_le_bytes)
        .collect()
}

fn setup(dir: &Path) {
    let sdof = std::fs::read_to_string(model("sdof_linear.dyn")).unwrap();
    let servo = std::fs::read_to_string(model("servo_axis.dyn")).unwrap();
    for (out, sample, levels) in [("data", "0.01", "6,15,40"), ("fast", "0.0002", "15")] {
        let st = dynid()
            .arg("simulate")
            .arg(model("sdof_linear.dyn"))
            .args(["--duration", "20", "--seed", "2", "--sample", sample])
            .args(["--levels", levels, "--out"])
            .arg(dir.join(out))
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
    }
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    let with = |line: &str| sdof.replace("spring k (ground, m) ~ 4.0", line);
    let law = |law: &str| servo.replace("80000 * (xr - m.x) - 2680 * m.v", law);

    // Models.
    write("bom.dyn", format!("\u{feff}{sdof}").as_bytes());
    write(
        "zero_width.dyn",
        with("spring k\u{200b} (ground, m) ~ 4.0").as_bytes(),
    );
    write(
        "rtl.dyn",
        with("spring k\u{202e} (ground, m) ~ 4.0").as_bytes(),
    );
    write(
        "escape.dyn",
        with("spring k\x1b[31m (ground, m) ~ 4.0").as_bytes(),
    );
    write("nul.dyn", with("spring k\0 (ground, m) ~ 4.0").as_bytes());
    write("utf16.dyn", &utf16le(&sdof));
    write(
        "prime.dyn",
        with("spring k (ground, m) ~ 4.0\n    force f (ground, m) = c ~ 1.0 * sign(x')").as_bytes(),
    );
    write("law_by_zero.dyn", law("80000 * (xr - m.x) / 0").as_bytes());
    write(
        "law_sqrt.dyn",
        law("80000 * sqrt(xr - m.x) - 2680 * m.v").as_bytes(),
    );

    // Data.
    let level = std::fs::read_to_string(dir.join("data/level_1.csv")).unwrap();
    write("bom.csv", format!("\u{feff}{level}").as_bytes());
    write("utf16.csv", &utf16le(&level));
    write("old_mac.csv", level.replace('\n', "\r").as_bytes());
    write(
        "zero_width.csv",
        level.replacen("m.x", "m.x\u{200b}", 1).as_bytes(),
    );
    let mut lines: Vec<String> = level.lines().map(String::from).collect();
    lines[30] = lines[30].replacen(',', ",\x1b[31m", 1);
    write("escape.csv", (lines.join("\n") + "\n").as_bytes());
    let mut lines: Vec<String> = level.lines().map(String::from).collect();
    lines.drain(500..503);
    write("dropped.csv", (lines.join("\n") + "\n").as_bytes());
}

const DATA: &str = "{dir}/data/level_1.csv";

const CASES: &[Case] = &[
    // ---- Invisible and control characters ----
    Case {
        name: "a zero-width space in a model",
        args: &["compile", "{dir}/zero_width.dyn"],
        code: "dyn::syntax",
        also: &["`\\u{200b}`", "a zero-width space", "zero_width.dyn:5:13"],
        not: &[],
    },
    Case {
        name: "a right-to-left override in a model",
        args: &["compile", "{dir}/rtl.dyn"],
        code: "dyn::syntax",
        also: &["`\\u{202e}`", "bidirectional"],
        not: &[],
    },
    Case {
        name: "an escape sequence in a model",
        args: &["compile", "{dir}/escape.dyn"],
        code: "dyn::syntax",
        also: &["`\\x1b`", "an escape character"],
        not: &[],
    },
    Case {
        name: "a NUL byte in a model",
        args: &["compile", "{dir}/nul.dyn"],
        code: "dyn::syntax",
        also: &["`\\x00`", "a NUL byte"],
        not: &[],
    },
    Case {
        name: "a UTF-16 model",
        args: &["compile", "{dir}/utf16.dyn"],
        code: "dyn::io",
        also: &["UTF-16"],
        not: &[],
    },
    Case {
        name: "a UTF-16 level file",
        args: &["identify", "{model}", "{dir}/utf16.csv"],
        code: "dynid::data::encoding",
        also: &["UTF-16", "utf16.csv"],
        not: &[],
    },
    Case {
        name: "a zero-width space in a column name",
        args: &["identify", "{model}", "{dir}/zero_width.csv"],
        code: "dynid::data::missing_column",
        also: &["m.x\\u{200b}", "a zero-width space"],
        not: &[],
    },
    Case {
        name: "an escape sequence in a number",
        args: &["identify", "{model}", "{dir}/escape.csv"],
        code: "dynid::data::not_a_number",
        also: &["\\x1b[31m", "an escape character", "line 31"],
        not: &[],
    },
    // ---- Line ends ----
    Case {
        name: "old Mac line ends (CR only)",
        args: &["identify", "{model}", "{dir}/old_mac.csv"],
        code: "dynid::data::line_ends",
        also: &["carriage return"],
        not: &["no samples"],
    },
    // ---- The language ----
    Case {
        name: "`sign(x')`",
        args: &["compile", "{dir}/prime.dyn"],
        code: "dyn::syntax",
        also: &["`'` is not part of the language", "`m.v`"],
        not: &["expected `(`"],
    },
    Case {
        name: "a control law divided by 0",
        args: &["compile", "{dir}/law_by_zero.dyn"],
        code: "dyn::invalid_value",
        also: &["control law"],
        not: &[],
    },
    Case {
        name: "a control law undefined on the state (`sqrt` of the error)",
        args: &[
            "simulate",
            "{dir}/law_sqrt.dyn",
            "--duration",
            "5",
            "--out",
            "{dir}/out",
        ],
        code: "dynid::sim::control_law",
        also: &["u = 80000 * sqrt(xr - m.x)", "NaN", "s after the start"],
        not: &["t = -", "unstable"],
    },
    // ---- Sampling ----
    Case {
        name: "levels at different sample intervals",
        args: &["identify", "{model}", DATA, "{dir}/fast/level_1.csv"],
        code: "dynid::identify::sample_intervals",
        also: &[
            // (miette may wrap the paths at a `/`.)
            "level_1.csv has Ts = 0.01 s",
            "level_1.csv has Ts = 2e-4 s",
            "fast/",
            "resample",
        ],
        not: &["invalid option"],
    },
    Case {
        name: "`--sample` against the file's own `t` column",
        args: &["identify", "{model}", DATA, "--sample", "0.02"],
        code: "dynid::data::sample_conflict",
        also: &["`--sample 0.02`", "`t` column", "0.01 s"],
        not: &[],
    },
    Case {
        name: "dropped samples",
        args: &["identify", "{model}", "{dir}/dropped.csv"],
        code: "dynid::data::non_uniform_time",
        also: &[
            "3 samples are missing",
            "t = 4.98 s",
            "t = 5.02 s",
            "cut the file",
        ],
        not: &["--sample"],
    },
    // ---- --map ----
    Case {
        name: "`--map =m.x` (no column name)",
        args: &["identify", "{model}", DATA, "--map", "=m.x"],
        code: "dynid::data::bad_map",
        also: &["column name before `=` is empty"],
        not: &["is not a signal"],
    },
    Case {
        name: "`--map m.x=t` on a file with `t`",
        args: &["identify", "{model}", DATA, "--map", "m.x=t"],
        code: "dynid::data::bad_map",
        also: &["`t` is the time column"],
        not: &["appears twice"],
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
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn unclear_inputs_get_messages_that_name_the_problem() {
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
        let raw = String::from_utf8_lossy(&out.stderr);
        // The message as one line: miette wraps it at 80 columns behind `│` rails.
        let err = raw
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
        } else if let Some(t) = case.not.iter().find(|t| err.contains(**t)) {
            Some(format!("`{t}` in: {err}"))
        } else if let Some(c) = RAW.iter().find(|c| raw.contains(**c)) {
            Some(format!("raw {c:?} on the terminal: {raw:?}"))
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

/// A byte-order mark at the start of a model or a level file (as Windows editors and
/// spreadsheet exports write) is accepted: the file reads as without it.
#[test]
fn a_leading_byte_order_mark_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let run = |args: &[&Path]| {
        let out = dynid().args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{:?}: {}",
            args,
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    };
    let d = dir.path();
    let plain = run(&[
        Path::new("identify"),
        &model("sdof_linear.dyn"),
        &d.join("data/level_1.csv"),
    ]);
    let with_bom = run(&[
        Path::new("identify"),
        &d.join("bom.dyn"),
        &d.join("bom.csv"),
    ]);
    let body = |s: &[u8]| {
        // The first line names the files; the estimates follow.
        String::from_utf8_lossy(s)
            .lines()
            .filter(|l| !l.contains(".csv") && !l.contains(".dyn"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(body(&plain), body(&with_bom));
}
