//! No input makes dynid loop forever, wait forever or take unbounded work or memory:
//! data scaled into the subnormal range are refused (identify, detect, diagnose), a FIFO
//! is read once, work and memory are estimated up front and refused above a limit with
//! the estimate and the flag that allows it, and a file that is not text or has no line
//! ends is refused after a bounded read. Every command here runs under a time limit: a
//! hang fails the test instead of stalling the suite.

mod common;

use common::{assert_refused, dynid};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn model(name: &str) -> PathBuf {
    common::model_path(name)
}

/// Run `cmd`, killing it and failing the test when it runs longer than `limit`.
fn run_within(mut cmd: Command, limit: Duration) -> Output {
    let what = format!("{cmd:?}");
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Drain the pipes on threads so a chatty child cannot block on a full pipe.
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let t_out = std::thread::spawn(move || {
        let mut b = Vec::new();
        std::io::Read::read_to_end(&mut out, &mut b).unwrap();
        b
    });
    let t_err = std::thread::spawn(move || {
        let mut b = Vec::new();
        std::io::Read::read_to_end(&mut err, &mut b).unwrap();
        b
    });
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > limit {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("still running after {limit:?} (a hang): {what}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: t_out.join().unwrap(),
        stderr: t_err.join().unwrap(),
    }
}

const LIMIT: Duration = Duration::from_secs(180);

/// Simulated levels of `name` in `dir/sub`.
fn simulate(dir: &Path, name: &str, sub: &str, duration: &str) -> PathBuf {
    let out = dir.join(sub);
    let st = dynid()
        .arg("simulate")
        .arg(model(name))
        .args(["--duration", duration, "--seed", "3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", common::stderr(&st));
    out
}

/// `src` with the columns named in `cols` multiplied by `scale` (printed with 17 digits,
/// as `awk '{printf "%.17g", $2 * 1e-155}'` does).
fn scaled(src: &Path, dst: &Path, cols: &[&str], scale: f64) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut out = header.join(",") + "\n";
    for l in lines {
        let row: Vec<String> = l
            .split(',')
            .zip(&header)
            .map(|(v, h)| {
                if cols.contains(h) {
                    format!("{:e}", v.parse::<f64>().unwrap() * scale)
                } else {
                    v.to_string()
                }
            })
            .collect();
        out += &(row.join(",") + "\n");
    }
    std::fs::write(dst, out).unwrap();
}

#[test]
fn data_scaled_into_the_subnormal_range_are_refused_not_looped_on() {
    // Before: identify, detect and diagnose spun at 100 % CPU forever (a row whose
    // largest entry is subnormal got an infinite weight, the solve failed, and the loop
    // emptied its columns and went round again).
    let dir = tempfile::tempdir().unwrap();
    let d = simulate(dir.path(), "sdof_linear.dyn", "d", "200");
    let all = dir.path().join("all_1e-155.csv");
    scaled(&d.join("level_1.csv"), &all, &["m.x", "m.v", "u"], 1e-155);
    let mut cases = vec![all.clone()];
    for s in [1e-308, 1e-315, 1e-320] {
        let p = dir.path().join(format!("x_{s:e}.csv"));
        scaled(&d.join("level_1.csv"), &p, &["m.x"], s);
        cases.push(p);
    }
    for data in &cases {
        let mut cmd = dynid();
        cmd.arg("identify")
            .arg(model("sdof_linear.dyn"))
            .arg(data)
            .arg(d.join("level_2.csv"));
        assert_refused(
            &run_within(cmd, LIMIT),
            "dynid::identify::underflow",
            &["m.x", "rescale"],
        );
    }
    for command in ["detect", "diagnose"] {
        let mut cmd = dynid();
        cmd.arg(command)
            .arg(model("sdof_linear.dyn"))
            .arg(&all)
            .arg(d.join("level_2.csv"))
            .arg(d.join("level_3.csv"));
        assert_refused(
            &run_within(cmd, LIMIT),
            "dynid::identify::underflow",
            &["all_1e-155.csv"],
        );
    }
}

/// A FIFO at `path` fed with `bytes` by a thread (which waits for a reader, as a
/// producing process would).
fn fifo(path: &Path, bytes: Vec<u8>) -> std::thread::JoinHandle<()> {
    let st = Command::new("mkfifo").arg(path).status().unwrap();
    assert!(st.success());
    let p = path.to_path_buf();
    std::thread::spawn(move || {
        use std::io::Write;
        if let Ok(mut f) = std::fs::OpenOptions::new().write(true).open(&p) {
            let _ = f.write_all(&bytes);
        }
    })
}

#[test]
fn a_fifo_is_read_once_as_data_and_as_a_simulation_input() {
    // Before: the file was opened twice (header, then body); the second open of a FIFO
    // waits for a writer that has gone, forever.
    let dir = tempfile::tempdir().unwrap();
    let d = simulate(dir.path(), "sdof_linear.dyn", "d", "200");
    let level_1 = std::fs::read(d.join("level_1.csv")).unwrap();

    let f = dir.path().join("level_1.fifo");
    let writer = fifo(&f, level_1.clone());
    let mut cmd = dynid();
    cmd.arg("identify")
        .arg(model("sdof_linear.dyn"))
        .arg(&f)
        .arg(d.join("level_2.csv"))
        .arg(d.join("level_3.csv"));
    let o = run_within(cmd, LIMIT);
    assert!(o.status.success(), "{}", common::stderr(&o));
    writer.join().unwrap();
    // The same numbers as from the regular file.
    let mut cmd = dynid();
    cmd.arg("identify")
        .arg(model("sdof_linear.dyn"))
        .arg(d.join("level_1.csv"))
        .arg(d.join("level_2.csv"))
        .arg(d.join("level_3.csv"));
    let regular = run_within(cmd, LIMIT);
    assert_eq!(o.stdout, regular.stdout);

    let g = dir.path().join("input.fifo");
    let writer = fifo(&g, level_1);
    let mut cmd = dynid();
    cmd.arg("simulate")
        .arg(model("sdof_linear.dyn"))
        .arg("--input")
        .arg(&g)
        .arg("--out")
        .arg(dir.path().join("driven"));
    let o = run_within(cmd, LIMIT);
    assert!(o.status.success(), "{}", common::stderr(&o));
    writer.join().unwrap();
    assert!(dir.path().join("driven/driven.csv").is_file());
}

#[test]
fn detection_on_two_levels_says_they_are_too_few_instead_of_panicking() {
    // Before: `panicked at runtime/src/detect/fit.rs:146:19: Matrix index out of bounds`
    // (a template with a shape parameter fitted to the four points of two levels).
    let dir = tempfile::tempdir().unwrap();
    let d = simulate(dir.path(), "sdof_cubic_coulomb.dyn", "d1", "500");
    let mut cmd = dynid();
    cmd.arg("detect")
        .arg(model("sdof_linear.dyn"))
        .arg(d.join("level_1.csv"))
        .arg(d.join("level_2.csv"));
    let o = run_within(cmd, LIMIT);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", common::stderr(&o));
    assert!(
        out.contains("2 levels are too few to rank any template: give at least 3 levels"),
        "{out}"
    );
}

#[test]
fn simulation_work_is_estimated_and_refused_above_the_limit_with_the_flag_to_allow_it() {
    // Before: `--substeps 1000000` and `--input-oversample 1000000000` ran for hours.
    let dir = tempfile::tempdir().unwrap();
    let d = simulate(dir.path(), "sdof_linear.dyn", "d", "50");
    let cases: [(&[&str], &str); 3] = [
        (&["--substeps", "1000000"], "hours"),
        (&["--input-oversample", "1000000000"], "days"),
        (&["--substeps", "100000000", "--input"], "hours"),
    ];
    for (args, unit) in cases {
        let out = dir.path().join("out");
        let mut cmd = dynid();
        cmd.arg("simulate").arg(model("sdof_linear.dyn")).args(args);
        if args.contains(&"--input") {
            cmd.arg(d.join("level_1.csv"));
        }
        cmd.arg("--out").arg(&out);
        let o = run_within(cmd, Duration::from_secs(60));
        assert_refused(
            &o,
            "dynid::sim::too_long",
            &[unit, "of simulation", "RK4 steps", "--allow-long"],
        );
        assert!(!out.exists(), "{args:?} created the output directory");
    }
}

#[test]
fn files_that_are_not_text_or_have_no_line_ends_are_refused_after_a_bounded_read() {
    // Before: `compile /dev/zero` reached 6.3 GB in 10 s, `identify M /dev/zero` 8.3 GB,
    // and a 1 GB file without a newline used 6.1 GB and echoed its 10.9 MB "header" into
    // the error.
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = dynid();
    cmd.args(["compile", "/dev/zero"]);
    let o = run_within(cmd, Duration::from_secs(60));
    assert_refused(&o, "holds more than 8 MiB", &["not a model source"]);

    let mut cmd = dynid();
    cmd.arg("identify")
        .arg(model("sdof_linear.dyn"))
        .arg("/dev/zero");
    let o = run_within(cmd, Duration::from_secs(60));
    assert_refused(&o, "dynid::data::binary", &["/dev/zero", "NUL byte"]);

    // 3 MiB of digits and commas without a line end.
    let long = dir.path().join("one_line.csv");
    std::fs::write(&long, "1,".repeat(3 << 19)).unwrap();
    let mut cmd = dynid();
    cmd.arg("identify").arg(model("sdof_linear.dyn")).arg(&long);
    let o = run_within(cmd, Duration::from_secs(60));
    assert_refused(
        &o,
        "dynid::data::line_too_long",
        &["line 1 is longer than 1 MiB"],
    );
    assert!(o.stderr.len() < 4096, "{} bytes of error", o.stderr.len());
}

#[test]
fn silverbox_upsampling_is_refused_above_the_memory_limit() {
    // Before: `silverbox --upsample 1000000` asked for 69 GB and aborted (SIGABRT).
    let dir = std::env::var_os("DYNID_SILVERBOX_DATA").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/silverbox"),
        PathBuf::from,
    );
    if !dir.join("SNLS80mV.csv").is_file() {
        println!("SKIPPED: no Silverbox data (set DYNID_SILVERBOX_DATA=DIR)");
        return;
    }
    let mut cmd = dynid();
    cmd.args(["silverbox", "--upsample", "1000000", "--data"])
        .arg(&dir);
    let o = run_within(cmd, Duration::from_secs(120));
    assert_refused(
        &o,
        "dynid::silverbox::too_large",
        &["TB of memory", "--allow-large"],
    );
}

#[test]
fn a_missing_column_in_a_huge_header_is_named_without_echoing_the_header() {
    // Before: the whole 10.9 MB "header" of a file without line ends was echoed.
    let dir = tempfile::tempdir().unwrap();
    let wide = dir.path().join("wide.csv");
    let header: Vec<String> = (0..20_000).map(|k| format!("col{k}")).collect();
    let row = vec!["0"; header.len()].join(",");
    std::fs::write(&wide, header.join(",") + "\n" + &row + "\n" + &row + "\n").unwrap();
    let mut cmd = dynid();
    cmd.arg("identify").arg(model("sdof_linear.dyn")).arg(&wide);
    let o = run_within(cmd, Duration::from_secs(60));
    assert_refused(&o, "dynid::data::missing_column", &["(20000 columns)"]);
    assert!(o.stderr.len() < 4096, "{} bytes of error", o.stderr.len());
}

/// Three short level files of the chain's columns (different values, so that no level is
/// a copy of another).
fn chain_levels(dir: &Path, n: usize) -> Vec<PathBuf> {
    let header: Vec<String> = std::iter::once("t".to_string())
        .chain((1..=n).map(|i| format!("m{i}.x")))
        .chain(["u".to_string()])
        .collect();
    (1..=3)
        .map(|level| {
            let mut text = header.join(",") + "\n";
            for k in 0..3 {
                let v = format!(",{}", 0.1 * (level * (k + 1)) as f64);
                text += &format!("{}{}\n", 0.01 * k as f64, v.repeat(n + 1));
            }
            let p = dir.join(format!("level_{level}.csv"));
            std::fs::write(&p, text).unwrap();
            p
        })
        .collect()
}

#[test]
fn identification_memory_is_estimated_before_reading_and_refused_with_the_flag_to_allow_it() {
    // Before: a chain of 500 bodies with every position measured passed every screen and
    // then took memory until the system killed it (the moments alone are 12525 × 1002
    // numbers per block and level, the rows 3·10⁶ per level for 1000 unknowns). Now the
    // estimate (terabytes) is refused before a sample is read, so the files here are three
    // samples long.
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("chain500.dyn");
    std::fs::write(&model, dynid::runtime::sim::test_models::chain_source(500)).unwrap();
    let data = chain_levels(dir.path(), 500);
    for command in ["identify", "detect", "diagnose"] {
        let mut cmd = dynid();
        cmd.arg(command).arg(&model).args(&data);
        let o = run_within(cmd, Duration::from_secs(120));
        assert_refused(
            &o,
            "dynid::identify::too_large",
            &[
                "TB of memory",
                "above the limit of about 8 GB",
                "500 bodies, 501 measured signals",
                "501 drivers × 6 corners × 4 sections",
                "1000 unknowns",
                "filter corners [...]` line with fewer corners",
                "--allow-large",
            ],
        );
        // The flag lets it past the estimate (to the data, three samples too few here).
        let mut cmd = dynid();
        cmd.arg(command)
            .arg(&model)
            .args(&data)
            .arg("--allow-large");
        let o = run_within(cmd, Duration::from_secs(120));
        assert_refused(&o, "dynid::data::too_few_samples", &["level_1.csv"]);
    }
    for command in ["identify", "detect", "diagnose", "simulate"] {
        let out = dynid().args([command, "--help"]).output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("--allow-large"), "`{command} --help`: {text}");
    }
}

/// A file of `size` bytes that starts with `head` and continues sparse (no disk space, NUL
/// bytes if it were read, refused as binary): only its size says how large the record
/// would be.
fn sparse_csv(path: &Path, head: &str, size: u64) {
    std::fs::write(path, head).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .unwrap()
        .set_len(size)
        .unwrap();
}

#[test]
fn records_read_whole_are_estimated_from_the_file_size_and_refused_above_the_limit() {
    // Before: `simulate --input`, a record split into levels, `diagnose` and
    // `identify --refine` read the whole file into memory, whatever its size (here the
    // sparse tail would have been read as binary data after gigabytes).
    let dir = tempfile::tempdir().unwrap();
    let mut head = "t,m.x,m.v,u\n".to_string();
    // 3 MB of rows: the reader's first buffer (1 MiB) holds text only.
    for k in 0..100_000 {
        let t = 0.01 * k as f64;
        head += &format!(
            "{t:.2},{:.6},{:.6},{:.6}\n",
            t.sin(),
            t.cos(),
            (3.0 * t).sin()
        );
    }
    // About 36 bytes a row: 40 GiB are 1.2·10⁹ rows, 29 GB of three columns.
    let big = dir.path().join("big.csv");
    sparse_csv(&big, &head, 40 << 30);
    let big2 = dir.path().join("big2.csv");
    sparse_csv(&big2, &head.replace("0.00,", "0.00,1"), 40 << 30);
    let sdof = model("sdof_linear.dyn");
    let out = dir.path().join("out");
    let cases: [(Vec<&std::ffi::OsStr>, &str, &[&str]); 4] = [
        (
            vec![
                "simulate".as_ref(),
                sdof.as_os_str(),
                "--input".as_ref(),
                big.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
            ],
            "dynid::data::too_large",
            &[
                "big.csv",
                "GB of memory",
                "rows × 3 columns",
                "--allow-large",
            ],
        ),
        (
            vec!["detect".as_ref(), sdof.as_os_str(), big.as_os_str()],
            "dynid::data::too_large",
            &["big.csv", "GB of memory", "--allow-large"],
        ),
        (
            vec![
                "diagnose".as_ref(),
                sdof.as_os_str(),
                big.as_os_str(),
                big2.as_os_str(),
            ],
            "dynid::identify::too_large",
            &[
                "diagnosis would take",
                "for the records read whole",
                "--allow-large",
            ],
        ),
        (
            vec![
                "identify".as_ref(),
                sdof.as_os_str(),
                big.as_os_str(),
                "--refine".as_ref(),
            ],
            "dynid::data::too_large",
            &["big.csv", "GB of memory", "--allow-large"],
        ),
    ];
    for (args, code, also) in cases {
        let mut cmd = dynid();
        cmd.args(&args);
        let o = run_within(cmd, Duration::from_secs(60));
        assert_refused(&o, code, also);
        assert!(!out.exists(), "{args:?} created the output directory");
    }
}
