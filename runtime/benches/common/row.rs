//! The row a bench adds to the table of `docs/performance.md`: the bench, its figure (a
//! ratio against a reference measured in the same run), that reference, the date, the
//! commit, the processor and the command. Every bench prints its row last, so a run's
//! figures are copied into the table as printed; `tests/doc_figures.rs` checks that each
//! bench of `runtime/benches/` and `benches/` has a row there, in this format.
// Included by `runtime/benches/common/mod.rs`, `benches/codegen.rs` and `tests/doc_figures.rs`.
#![allow(dead_code)]

/// The columns of the table, in order.
pub const COLUMNS: [&str; 7] = [
    "bench",
    "figure",
    "reference (same run)",
    "date",
    "commit",
    "CPU",
    "command",
];

/// One row of the table, in Markdown: `bench` as code, the command as code.
pub fn format_row(
    bench: &str,
    figure: &str,
    reference: &str,
    date: &str,
    commit: &str,
    cpu: &str,
    command: &str,
) -> String {
    let cell = |s: &str| s.replace('|', "\\|");
    format!(
        "| `{bench}` | {} | {} | {date} | {commit} | {} | `{}` |",
        cell(figure),
        cell(reference),
        cell(cpu),
        cell(command)
    )
}

/// Print this run's row (date, commit and processor taken from the machine).
pub fn print_row(bench: &str, figure: &str, reference: &str, command: &str) {
    println!("\nrow for docs/performance.md:");
    println!(
        "{}",
        format_row(
            bench,
            figure,
            reference,
            &today(),
            &commit(),
            &cpu(),
            command
        )
    );
}

/// The `DYNID_BENCH_*` variables of this run (but the one a bench sets for its own child
/// processes), as they would be typed before the command.
pub fn bench_env() -> String {
    let mut vars: Vec<(String, String)> = std::env::vars()
        .filter(|(k, _)| k.starts_with("DYNID_BENCH_") && k != "DYNID_BENCH_CHILD")
        .collect();
    vars.sort();
    vars.iter().map(|(k, v)| format!("{k}={v} ")).collect()
}

fn output(cmd: &str, args: &[&str]) -> Option<String> {
    let out = std::process::Command::new(cmd).args(args).output().ok()?;
    let s = String::from_utf8(out.stdout).ok()?.trim().to_string();
    (out.status.success() && !s.is_empty()).then_some(s)
}

/// The date in UTC, `YYYY-MM-DD`.
fn today() -> String {
    output("date", &["-u", "+%F"]).unwrap_or_else(|| "????-??-??".into())
}

/// The checked-out commit (short hash, `+` when the tree has changes).
fn commit() -> String {
    let hash = output("git", &["rev-parse", "--short", "HEAD"]).unwrap_or_else(|| "?".into());
    let dirty = output("git", &["status", "--porcelain", "--untracked-files=no"]).is_some();
    if dirty {
        format!("{hash}+")
    } else {
        hash
    }
}

/// The processor's model name and the number of threads available (Linux; `?` elsewhere).
fn cpu() -> String {
    let name = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.split_whitespace().collect::<Vec<_>>().join(" "))
        })
        .unwrap_or_else(|| "?".into());
    let n = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{name}, {n} threads")
}
