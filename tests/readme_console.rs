//! The README's console blocks run as written: every command of a ```console block is run
//! (in a scratch directory holding a link to `models/`, `/tmp/` mapped into it), and every
//! output line the README shows must appear, in order, in what the commands print. A line
//! `...` or `…` stands for lines left out; a shown line ending in `…` is a prefix. Stale
//! output fails here instead of misleading a reader.
//!
//! Files a block uses without making them: a `NAME.dyn` outside `models/` is the nearest
//! model source shown before the block (whatever its file name); `bad.csv` is the first
//! level of `/tmp/d1` with the NaN the README describes.

use std::path::{Path, PathBuf};
use std::process::Command;

const README: &str = include_str!("../README.md");

/// One ```console block: its commands (continuation lines joined) and the lines shown.
struct Block {
    line: usize,
    commands: Vec<String>,
    shown: Vec<String>,
    /// The nearest plain code block before it that holds a model (`model NAME {`).
    model_before: Option<String>,
}

fn blocks() -> Vec<Block> {
    let lines: Vec<&str> = README.lines().collect();
    let mut out = Vec::new();
    let mut last_model: Option<String> = None;
    let mut i = 0;
    while i < lines.len() {
        let fence = lines[i].trim_start();
        if !fence.starts_with("```") {
            i += 1;
            continue;
        }
        let kind = fence.trim_start_matches('`').trim().to_string();
        let start = i + 1;
        let mut end = start;
        while end < lines.len() && !lines[end].trim_start().starts_with("```") {
            end += 1;
        }
        let body = &lines[start..end.min(lines.len())];
        if kind == "console" {
            let mut commands = Vec::new();
            let mut shown = Vec::new();
            let mut k = 0;
            while k < body.len() {
                if let Some(cmd) = body[k].strip_prefix("$ ") {
                    let mut cmd = cmd.trim_end().to_string();
                    while cmd.ends_with('\\') && k + 1 < body.len() {
                        cmd.pop();
                        k += 1;
                        cmd.push(' ');
                        cmd.push_str(body[k].trim());
                    }
                    commands.push(cmd);
                } else {
                    shown.push(body[k].trim_end().to_string());
                }
                k += 1;
            }
            out.push(Block {
                line: start,
                commands,
                shown,
                model_before: last_model.clone(),
            });
        } else if body.iter().any(|l| l.trim().starts_with("model ")) {
            last_model = Some(body.join("\n"));
        }
        i = end + 1;
    }
    out
}

/// The scratch directory: `models` links to the repository's models.
fn scratch() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    std::os::unix::fs::symlink(models, dir.path().join("models")).unwrap();
    dir
}

fn bin_dir() -> PathBuf {
    Path::new(env!("CARGO_BIN_EXE_dynid"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// Run the commands of `b` in `dir` and return what they printed (stdout and stderr, in
/// order per command), with `dir` mapped back to the README's `/tmp`.
fn run_block(b: &Block, dir: &Path) -> String {
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    let mut printed = String::new();
    for cmd in &b.commands {
        let cmd = cmd.replace("/tmp/", &format!("{}/", tmp.display()));
        // A model the README shows as text before the block.
        if let Some(src) = &b.model_before {
            for file in cmd
                .split_whitespace()
                .filter(|w| w.ends_with(".dyn") && !w.starts_with("models/"))
            {
                std::fs::write(dir.join(file), src).unwrap();
            }
        }
        if cmd.contains("bad.csv") && !dir.join("bad.csv").exists() {
            // The first level of `/tmp/d1` with NaN where the README's message says.
            let src = std::fs::read_to_string(tmp.join("d1/level_1.csv"))
                .expect("the block with bad.csv follows the one that simulates /tmp/d1");
            let mut lines: Vec<String> = src.lines().map(str::to_string).collect();
            let header: Vec<&str> = lines[0].split(',').collect();
            let col = header.iter().position(|h| *h == "m.x").unwrap();
            let mut fields: Vec<String> = lines[10].split(',').map(str::to_string).collect();
            fields[col] = "NaN".into();
            lines[10] = fields.join(",");
            std::fs::write(dir.join("bad.csv"), lines.join("\n") + "\n").unwrap();
        }
        let path = format!(
            "{}:{}",
            bin_dir().display(),
            std::env::var("PATH").unwrap_or_default()
        );
        // Both streams through one pipe, in the order they are written; the newline ends a
        // trailing `# comment` of the command.
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!("{{ {cmd}\n}} 2>&1"))
            .current_dir(dir)
            .env("PATH", path)
            .env("NO_COLOR", "1")
            .env("COLUMNS", "80")
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        printed.push_str(&text.replace(&format!("{}/", tmp.display()), "/tmp/"));
    }
    printed
}

/// Every shown line, in order, among the printed ones; the first that is not, with context.
fn check(b: &Block, printed: &str) -> Result<(), String> {
    let got: Vec<&str> = printed.lines().map(str::trim_end).collect();
    let mut at = 0;
    for want in &b.shown {
        let want = want.as_str();
        if want.trim().is_empty() || want.trim() == "..." || want.trim() == "…" {
            continue;
        }
        let matches = |g: &str| match want.strip_suffix('…') {
            Some(prefix) => g.starts_with(prefix.trim_end()),
            None => g == want,
        };
        match got[at..].iter().position(|g| matches(g)) {
            Some(k) => at += k + 1,
            None => {
                return Err(format!(
                    "README.md line {}: the block's commands\n  {}\ndo not print\n  {want}\n\
                     (after the lines matched so far); they printed:\n{printed}",
                    b.line,
                    b.commands.join("\n  ")
                ))
            }
        }
    }
    Ok(())
}

#[test]
fn every_console_block_of_the_readme_prints_what_it_shows() {
    let blocks = blocks();
    assert!(blocks.len() >= 8, "{} console blocks", blocks.len());
    let dir = scratch();
    let mut failures = Vec::new();
    for b in &blocks {
        assert!(
            !b.commands.is_empty(),
            "README.md line {}: no command",
            b.line
        );
        let printed = run_block(b, dir.path());
        if let Err(e) = check(b, &printed) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn a_shown_line_that_is_not_printed_or_out_of_order_fails() {
    let block = |shown: &[&str]| Block {
        line: 1,
        commands: vec!["true".into()],
        shown: shown.iter().map(|s| s.to_string()).collect(),
        model_before: None,
    };
    let printed = "first line\nsecond 1.23\nthird\n";
    assert!(check(&block(&["first line", "...", "third"]), printed).is_ok());
    assert!(check(&block(&["second 1.2…"]), printed).is_ok());
    assert!(check(&block(&["second 1.24"]), printed).is_err());
    assert!(check(&block(&["third", "first line"]), printed).is_err());
}
