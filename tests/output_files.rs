//! What outputs do to the paths they name: a device, FIFO, descriptor path or process
//! substitution is written through and never replaced; a symbolic link to a file writes
//! the file; new files follow the user's umask and replaced ones keep their mode; a
//! read-only file or directory is refused before the work; a run owns its `--out`
//! directory (an earlier run there is replaced whole) and never writes over an input; an
//! interrupted or out-of-space simulate leaves nothing behind.
#![cfg(unix)]

mod common;

use common::{dynid, setup_linear_levels as setup, stderr};

use std::os::unix::fs::{FileTypeExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_dynid")
}

/// `dynid identify MODEL LEVELS... EXTRA...`.
fn identify(model: &Path, levels: &[PathBuf], extra: &[&std::ffi::OsStr]) -> Command {
    let mut c = dynid();
    c.arg("identify").arg(model).args(levels).args(extra);
    c
}

fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    n.sort();
    n
}

fn mode(p: &Path) -> u32 {
    std::fs::metadata(p).unwrap().permissions().mode() & 0o7777
}

fn set_mode(p: &Path, m: u32) {
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(m)).unwrap();
}

fn mkfifo(p: &Path) {
    let st = Command::new("mkfifo").arg(p).status().unwrap();
    assert!(st.success());
}

/// A shell command line quoting `s` for `sh -c`.
fn quote(s: &Path) -> String {
    format!("'{}'", s.display().to_string().replace('\'', "'\\''"))
}

/// `dynid identify MODEL LEVELS…` as a shell command line.
fn identify_line(model: &Path, levels: &[PathBuf]) -> String {
    let levels: Vec<String> = levels.iter().map(|l| quote(l)).collect();
    format!(
        "{} identify {} {}",
        quote(Path::new(bin())),
        quote(model),
        levels.join(" ")
    )
}

fn refused(out: &Output, code: &str) -> String {
    let err = stderr(out);
    assert!(!out.status.success(), "accepted: {err}");
    assert_ne!(out.status.code(), Some(101), "panicked: {err}");
    assert!(err.contains(code), "`{code}` missing in: {err}");
    err
}

#[test]
fn devices_fifos_and_descriptors_are_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let (model, levels) = setup(dir.path());
    let before = names(dir.path());

    // A null device stays the device. A private one (`mknod`, root only), so that a
    // regression cannot replace the system's /dev/null; skipped where it cannot be made.
    let null = dir.path().join("null");
    let made = Command::new("mknod")
        .arg(&null)
        .args(["c", "1", "3"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if made {
        let out = identify(&model, &levels, &["--json".as_ref(), null.as_os_str()])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        let meta = std::fs::symlink_metadata(&null).unwrap();
        assert!(meta.file_type().is_char_device(), "the device was replaced");
        std::fs::remove_file(&null).unwrap();
    } else {
        eprintln!("device case skipped: `mknod` needs root");
    }

    // A FIFO is written through to its reader; no temporary beside it.
    let fifo = dir.path().join("result.json");
    mkfifo(&fifo);
    let (tx, rx) = std::sync::mpsc::channel();
    {
        let fifo = fifo.clone();
        // A reader that never gets a writer (the FIFO replaced) blocks for good: the test
        // stops waiting for it after a minute, and the process ends without it.
        std::thread::spawn(move || tx.send(std::fs::read_to_string(fifo).unwrap()));
    }
    let out = identify(&model, &levels, &["--json".as_ref(), fifo.as_os_str()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = rx
        .recv_timeout(std::time::Duration::from_secs(60))
        .expect("the FIFO's reader got nothing");
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(json.is_object(), "{json}");
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());

    // /dev/stdout into a pipe: the JSON arrives after the table.
    let out = identify(
        &model,
        &levels,
        &["--json".as_ref(), "/dev/stdout".as_ref()],
    )
    .output()
    .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let json_start = text.find("\n{").expect("the JSON on stdout");
    let _: serde_json::Value = serde_json::from_str(&text[json_start..]).unwrap();

    // /dev/stdout redirected to a file: the JSON follows the table, the table stays.
    let redirected = dir.path().join("stdout.txt");
    let script = format!(
        "{} --json /dev/stdout > {}",
        identify_line(&model, &levels),
        quote(&redirected)
    );
    let out = Command::new("sh").arg("-c").arg(&script).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&redirected).unwrap();
    let json_start = text.find("\n{").expect("the JSON after the table");
    assert!(json_start > 0 && !text[..json_start].trim().is_empty());
    let _: serde_json::Value = serde_json::from_str(&text[json_start..]).unwrap();
    std::fs::remove_file(&redirected).unwrap();

    // A process substitution `>(cat > FILE)` (a /dev/fd/N path), where bash is there.
    if Command::new("bash").arg("-c").arg("true").status().is_ok() {
        let got = dir.path().join("via_fd.json");
        let script = format!(
            "{} --json >(cat > {}); wait $!",
            identify_line(&model, &levels),
            quote(&got)
        );
        let out = Command::new("bash")
            .arg("-c")
            .arg(&script)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        // `wait $!` waits for the substitution's `cat`.
        let _: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&got).unwrap()).unwrap();
        std::fs::remove_file(&got).unwrap();
    }

    // A symbolic link to a file writes the file; the link stays a link.
    let real = dir.path().join("real.json");
    std::fs::write(&real, "old").unwrap();
    let link = dir.path().join("link.json");
    std::os::unix::fs::symlink("real.json", &link).unwrap();
    let out = identify(&model, &levels, &["--json".as_ref(), link.as_os_str()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let _: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&real).unwrap()).unwrap();

    let mut expected = before;
    expected.extend(["link.json", "real.json", "result.json"].map(String::from));
    expected.sort();
    assert_eq!(names(dir.path()), expected, "a temporary was left");
}

#[test]
fn new_files_follow_the_umask_and_replaced_files_keep_their_mode() {
    let dir = tempfile::tempdir().unwrap();
    let (model, levels) = setup(dir.path());
    let run = |umask: &str, json: &Path| {
        let script = format!(
            "umask {umask}; exec {} --json {}",
            identify_line(&model, &levels),
            quote(json)
        );
        let out = Command::new("sh").arg("-c").arg(&script).output().unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
    };
    let a = dir.path().join("a.json");
    run("022", &a);
    assert_eq!(mode(&a), 0o644);
    let b = dir.path().join("b.json");
    run("077", &b);
    assert_eq!(mode(&b), 0o600);
    let shared = dir.path().join("shared.json");
    std::fs::write(&shared, "old").unwrap();
    set_mode(&shared, 0o664);
    run("077", &shared);
    assert_eq!(mode(&shared), 0o664);
    assert_ne!(std::fs::read_to_string(&shared).unwrap(), "old");

    // Simulated levels too.
    let out_dir = dir.path().join("sim");
    let script = format!(
        "umask 022; exec {} simulate {} --duration 5 --out {}",
        quote(Path::new(bin())),
        quote(&model),
        quote(&out_dir)
    );
    let out = Command::new("sh").arg("-c").arg(&script).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    for n in names(&out_dir) {
        assert_eq!(mode(&out_dir.join(&n)), 0o644, "{n}");
    }
}

#[test]
fn read_only_files_and_directories_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let (model, levels) = setup(dir.path());
    // A 0444 file (refused even for root, who could write it).
    let ro = dir.path().join("ro.json");
    std::fs::write(&ro, "keep").unwrap();
    set_mode(&ro, 0o444);
    let out = identify(&model, &levels, &["--json".as_ref(), ro.as_os_str()])
        .output()
        .unwrap();
    let err = refused(&out, "dynid::output::read_only");
    assert!(err.contains("is read-only"), "{err}");
    assert!(out.stdout.is_empty(), "the analysis ran");
    assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
    assert_eq!(mode(&ro), 0o444);

    // A 0555 directory, for a file output and for `simulate --out`.
    let rodir = dir.path().join("rodir");
    std::fs::create_dir(&rodir).unwrap();
    set_mode(&rodir, 0o555);
    let out = identify(
        &model,
        &levels,
        &["--json".as_ref(), rodir.join("r.json").as_os_str()],
    )
    .output()
    .unwrap();
    let err = refused(&out, "dynid::output::read_only");
    assert!(err.contains("is not writable"), "{err}");
    assert!(out.stdout.is_empty(), "the analysis ran");
    let out = dynid()
        .arg("simulate")
        .arg(&model)
        .args(["--duration", "5", "--out"])
        .arg(rodir.join("sim"))
        .output()
        .unwrap();
    refused(&out, "dynid::output::read_only");
    set_mode(&rodir, 0o755);
    assert!(names(&rodir).is_empty());
}

#[test]
fn simulate_and_demo_never_write_over_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = d.join("sdof_linear.dyn");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_linear.dyn"),
        &model,
    )
    .unwrap();
    // `dynid compile M.dyn --emit json > truth.json; dynid simulate truth.json --out .`
    let out = dynid()
        .arg("compile")
        .arg(&model)
        .args(["--emit", "json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    std::fs::write(d.join("truth.json"), &out.stdout).unwrap();
    let out = dynid()
        .current_dir(d)
        .args(["simulate", "truth.json", "--duration", "5", "--out", "."])
        .output()
        .unwrap();
    let err = refused(&out, "dynid::output::is_input");
    assert!(err.contains("the model `truth.json`"), "{err}");
    assert!(out.stdout.is_empty());
    assert_eq!(
        std::fs::read(d.join("truth.json")).unwrap(),
        out_json(&model)
    );

    // `dynid simulate M.dyn --input d/driven.csv --out d`
    let sub = d.join("d");
    let st = dynid()
        .arg("simulate")
        .arg(&model)
        .args(["--duration", "5", "--levels", "1", "--out"])
        .arg(&sub)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", stderr(&st));
    std::fs::rename(sub.join("level_1.csv"), sub.join("driven.csv")).unwrap();
    let driven = std::fs::read(sub.join("driven.csv")).unwrap();
    let out = dynid()
        .arg("simulate")
        .arg(&model)
        .arg("--input")
        .arg(sub.join("driven.csv"))
        .arg("--out")
        .arg(&sub)
        .output()
        .unwrap();
    let err = refused(&out, "dynid::output::is_input");
    assert!(err.contains("which is the input file"), "{err}");
    assert_eq!(std::fs::read(sub.join("driven.csv")).unwrap(), driven);
    // A level of an earlier run in DIR, which the new run would remove, is an input too.
    std::fs::rename(sub.join("driven.csv"), sub.join("level_1.csv")).unwrap();
    let out = dynid()
        .arg("simulate")
        .arg(&model)
        .arg("--input")
        .arg(sub.join("level_1.csv"))
        .arg("--out")
        .arg(&sub)
        .output()
        .unwrap();
    refused(&out, "dynid::output::is_input");
    assert_eq!(std::fs::read(sub.join("level_1.csv")).unwrap(), driven);

    // `dynid demo --duration 100 --keep-data k --report k/level_1.csv`: before the work.
    let k = d.join("k");
    std::fs::create_dir(&k).unwrap();
    let out = dynid()
        .args(["demo", "--duration", "100", "--quiet", "--keep-data"])
        .arg(&k)
        .arg("--report")
        .arg(k.join("level_1.csv"))
        .output()
        .unwrap();
    let err = refused(&out, "dynid::output::same_file");
    assert!(err.contains("which is the report"), "{err}");
    assert!(out.stdout.is_empty(), "the demo ran");
    assert!(names(&k).is_empty());

    // `dynid demo --keep-data EXISTING_FILE`: a code and a help, before the work.
    let file = d.join("existing_file");
    std::fs::write(&file, "x").unwrap();
    let out = dynid()
        .args(["demo", "--duration", "100", "--quiet", "--keep-data"])
        .arg(&file)
        .arg("--report")
        .arg(d.join("r.html"))
        .output()
        .unwrap();
    let err = refused(&out, "dynid::output::not_a_directory");
    assert!(err.contains("give a new or an existing directory"), "{err}");
    assert!(out.stdout.is_empty(), "the demo ran");
}

/// The compiled JSON of `model` (what `compile --emit json` prints).
fn out_json(model: &Path) -> Vec<u8> {
    dynid()
        .arg("compile")
        .arg(model)
        .args(["--emit", "json"])
        .output()
        .unwrap()
        .stdout
}

#[test]
fn a_run_replaces_the_earlier_run_in_its_out_directory() {
    let dir = tempfile::tempdir().unwrap();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_linear.dyn");
    let out_dir = dir.path().join("d");
    let sim = |extra: &[&str]| {
        let st = dynid()
            .arg("simulate")
            .arg(&model)
            .args(["--duration", "5", "--out"])
            .arg(&out_dir)
            .args(extra)
            .output()
            .unwrap();
        assert!(st.status.success(), "{}", stderr(&st));
    };
    sim(&["--levels", "1,2,3,4", "--seed", "1"]);
    std::fs::write(out_dir.join("notes.txt"), "mine").unwrap();
    sim(&["--levels", "1,2,3", "--seed", "2"]);
    assert_eq!(
        names(&out_dir),
        [
            "level_1.csv",
            "level_2.csv",
            "level_3.csv",
            "notes.txt",
            "truth.json"
        ]
    );
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("truth.json")).unwrap())
            .unwrap();
    assert_eq!(truth["seed"], 2);
    // A driven run replaces the levels too.
    let input = dir.path().join("input.csv");
    std::fs::copy(out_dir.join("level_1.csv"), &input).unwrap();
    let st = dynid()
        .arg("simulate")
        .arg(&model)
        .arg("--input")
        .arg(&input)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", stderr(&st));
    assert_eq!(names(&out_dir), ["driven.csv", "notes.txt", "truth.json"]);
}

/// Start a simulate long enough to interrupt, wait until its temporaries hold data, send
/// `signal`, and check that it ends with 128 + signal and leaves nothing.
fn interrupt(signal: libc::c_int) {
    let dir = tempfile::tempdir().unwrap();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_linear.dyn");
    let out_dir = dir.path().join("out");
    let mut cmd = dynid();
    cmd.arg("simulate")
        .arg(&model)
        .args(["--duration", "20000", "--burn-in", "1", "--out"])
        .arg(&out_dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    // dynid keeps a signal ignored that its parent ignored (`nohup`, a background job):
    // give the child the default actions whatever this test runs under.
    // SAFETY: `signal` is async-signal-safe, as `pre_exec` requires.
    unsafe {
        std::os::unix::process::CommandExt::pre_exec(&mut cmd, || {
            for s in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                libc::signal(s, libc::SIG_DFL);
            }
            Ok(())
        });
    }
    let mut child = cmd.spawn().unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    loop {
        let written = std::fs::read_dir(&out_dir)
            .into_iter()
            .flatten()
            .flatten()
            .any(|e| e.metadata().is_ok_and(|m| m.len() > 0));
        if written {
            break;
        }
        if let Some(st) = child.try_wait().unwrap() {
            panic!("simulate ended first: {st}");
        }
        assert!(
            std::time::Instant::now() < deadline,
            "no temporaries appeared"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // SAFETY: sending a signal to our own child.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(128 + signal), "{}", stderr(&out));
    assert!(!out_dir.exists(), "left behind: {:?}", names(&out_dir));
    assert!(names(dir.path()).is_empty());
}

#[test]
fn an_interrupted_simulate_leaves_no_temporaries() {
    interrupt(libc::SIGINT);
    interrupt(libc::SIGTERM);
    interrupt(libc::SIGHUP);
}

/// `unshare -rm` (a private mount namespace, mapped to root) runs `script` with a small
/// tmpfs at `$1`; `None` where the system does not allow it.
fn in_small_tmpfs(script: &str, mount: &Path, size: &str) -> Option<Output> {
    let probe = Command::new("unshare")
        .args(["-rm", "true"])
        .stderr(Stdio::null())
        .status();
    if !probe.is_ok_and(|s| s.success()) {
        eprintln!("skipped: `unshare -rm` is not available");
        return None;
    }
    let full = format!("mount -t tmpfs -o size={size} tmpfs \"$1\" && {script}");
    Some(
        Command::new("unshare")
            .args(["-rm", "sh", "-c", &full, "sh"])
            .arg(mount)
            .output()
            .unwrap(),
    )
}

#[test]
fn a_full_disk_is_refused_up_front_or_said_so() {
    let dir = tempfile::tempdir().unwrap();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_linear.dyn");
    let mnt = dir.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let sim = format!("{} simulate {}", quote(Path::new(bin())), quote(&model));

    // Estimated above the free space: refused with the estimate, nothing written.
    let script = format!("{sim} --duration 1000 --out \"$1/d\"; r=$?; ls -A \"$1\"; exit $r");
    let Some(out) = in_small_tmpfs(&script, &mnt, "1m") else {
        return;
    };
    let err = refused(&out, "dynid::output::no_space");
    // 3 levels × 100001 rows × 4 columns × 17 bytes.
    assert!(err.contains("need about 20 MB"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );

    // The disk fills during the run (another writer takes the space while the level files
    // are being written; the run is stopped meanwhile, so it cannot finish first): the
    // disk is named, and nothing is left but the other writer's file. The estimate, 41 MB,
    // fits in the 64 MB.
    let script = format!(
        "{sim} --duration 2000 --burn-in 1 --out \"$1/d\" & pid=$!
         while ! find \"$1/d\" -name '.*tmp.csv' -size +1k 2>/dev/null | grep -q .; do
             sleep 0.01; done
         kill -STOP $pid
         dd if=/dev/zero of=\"$1/fill\" bs=64k 2>/dev/null
         kill -CONT $pid
         wait $pid; r=$?; ls -A \"$1\"; exit $r"
    );
    let out = in_small_tmpfs(&script, &mnt, "64m").expect("as above");
    let err = refused(&out, "dynid::output::write");
    assert!(err.contains("the disk is full"), "{err}");
    assert!(!err.contains("invalid simulation setting"), "{err}");
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "fill");
}
