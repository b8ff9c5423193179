//! An output path never overwrites an input or another output: `identify`, `detect` and
//! `diagnose` refuse such a path before any work, with a message that names both files,
//! and every input is byte-identical afterwards (symbolic links resolved).

mod common;

use common::{dynid, setup_linear_levels as setup, stderr};

use std::path::{Path, PathBuf};

fn contents(paths: &[&Path]) -> Vec<Vec<u8>> {
    paths.iter().map(|p| std::fs::read(p).unwrap()).collect()
}

/// Runs `dynid ARGS`, expects a refusal whose message contains every string of `says`,
/// and checks that the model and the levels are unchanged.
fn refused(model: &Path, levels: &[PathBuf], args: &[&std::ffi::OsStr], says: &[&str]) {
    let mut inputs: Vec<&Path> = vec![model];
    inputs.extend(levels.iter().map(PathBuf::as_path));
    let before = contents(&inputs);
    let out = dynid().args(args).output().unwrap();
    assert!(!out.status.success(), "accepted: {args:?}");
    assert_ne!(out.status.code(), Some(101), "panicked: {}", stderr(&out));
    let err = stderr(&out);
    for s in says {
        assert!(err.contains(s), "`{s}` missing in: {err}");
    }
    assert!(out.stdout.is_empty(), "work was done: {args:?}");
    assert_eq!(contents(&inputs), before, "an input changed: {args:?}");
}

#[test]
fn outputs_that_name_an_input_or_each_other_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (model, levels) = setup(dir.path());
    let os = |p: &Path| p.as_os_str().to_owned();
    let (m, l1, l2) = (os(&model), os(&levels[0]), os(&levels[1]));
    let l: Vec<_> = levels.iter().map(|p| os(p)).collect();
    let run = |cmd: &str, flags: &[(&str, &std::ffi::OsStr)], says: &[&str]| {
        let mut args: Vec<std::ffi::OsString> = vec![cmd.into(), m.clone()];
        args.extend(l.iter().cloned());
        for (f, p) in flags {
            args.push((*f).into());
            args.push((*p).to_owned());
        }
        if cmd == "diagnose" {
            args.push("--quiet".into());
        }
        let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        refused(&model, &levels, &refs, says);
    };
    // The JSON of `identify` over a measurement.
    run(
        "identify",
        &[("--json", &l1)],
        &["the JSON output", "is the input file", "level_1.csv"],
    );
    // A plot over a measurement.
    run(
        "detect",
        &[("--plot", &l2)],
        &["the plot", "is the input file"],
    );
    // The corrected model over the user's model.
    run(
        "diagnose",
        &[("--write-model", &m)],
        &["the corrected model", "is the input file"],
    );
    // Two outputs, one file.
    let x = dir.path().join("x.out");
    run(
        "diagnose",
        &[("--json", x.as_os_str()), ("--report", x.as_os_str())],
        &["the report", "the JSON output", "are the same file"],
    );
    assert!(!x.exists());
    // A relative spelling and a symbolic link resolve to the input too.
    let other = dir.path().join("sub");
    std::fs::create_dir(&other).unwrap();
    let dotted = other.join("..").join("level_3.csv");
    run(
        "identify",
        &[("--json", dotted.as_os_str())],
        &["is the input file"],
    );
    #[cfg(unix)]
    {
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink(&levels[0], &link).unwrap();
        run(
            "identify",
            &[("--json", link.as_os_str())],
            &["is the input file"],
        );
    }
}

/// A reader that stops early (`dynid compile M | head -1`) ends the output quietly: no
/// panic, no message.
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_the_output_quietly() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    // A chain of 400 bodies: its generated code (megabytes) overflows any pipe buffer.
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("chain.dyn");
    let mut src = String::from("model chain {\n    body m0 = 1\n    input u on m0\n");
    for i in 1..400 {
        src += &format!(
            "    body m{i} = 1\n    spring k{i} (m{}, m{i}) ~ 1\n    damper d{i} (m{}, m{i}) ~ 0.1\n",
            i - 1,
            i - 1
        );
    }
    src += "}\n";
    std::fs::write(&model, src).unwrap();
    let mut child = dynid()
        .arg("compile")
        .arg(&model)
        .args(["--emit", "rust"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(!first.is_empty());
    // The reader is gone (dropped above); the rest of the output goes nowhere.
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(out.status.code(), Some(101), "{err}");
}
