//! Every `expect` left in the library and CLI code states the invariant that makes it
//! unreachable (`expect("invariant: …")`, or `expect("grammar: …")` where the parser's
//! grammar guarantees the shape), and no bare `unwrap()` remains: bad input must come back
//! as an error, never as a panic. Unit-test modules (`#[cfg(test)] mod tests` at the end of
//! a file, `tests.rs`) and test-only helpers are exempt.

use std::path::{Path, PathBuf};

const ROOTS: &[&str] = &[
    "src",
    "runtime/src",
    "dsl-parser/src",
    "dsl-parser/ir/src",
    "codegen-macros/src",
    "python/src",
];

/// Files of test code inside the source trees.
fn is_test_file(p: &Path) -> bool {
    let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
    name == "tests.rs" || name == "test_models.rs" || p.ends_with("data/fuzz.rs")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") && !is_test_file(&p) {
            out.push(p);
        }
    }
}

/// The lines of `text` before its unit-test module.
fn code_lines(text: &str) -> Vec<&str> {
    let lines: Vec<&str> = text.lines().collect();
    let cut = lines
        .windows(2)
        .position(|w| w[0].trim() == "#[cfg(test)]" && w[1].trim_start().starts_with("mod tests"))
        .unwrap_or(lines.len());
    lines[..cut].to_vec()
}

/// Offending lines of one file's code.
fn offences(text: &str) -> Vec<(usize, String)> {
    code_lines(text)
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with("//"))
        .filter(|(_, l)| {
            l.contains(".unwrap()")
                || l.match_indices(".expect(\"").any(|(i, m)| {
                    let msg = &l[i + m.len()..];
                    !(msg.starts_with("invariant: ") || msg.starts_with("grammar: "))
                })
        })
        .map(|(i, l)| (i + 1, l.trim().to_string()))
        .collect()
}

#[test]
fn the_audit_finds_what_it_looks_for() {
    let text = "fn a() {\n    x.unwrap();\n    y.expect(\"oops\");\n    z.expect(\"invariant: fine\");\n}\n#[cfg(test)]\nmod tests {\n    fn t() { w.unwrap(); }\n}\n";
    let found: Vec<usize> = offences(text).iter().map(|o| o.0).collect();
    assert_eq!(found, [2, 3]);
}

#[test]
fn library_and_cli_code_has_no_unexplained_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for r in ROOTS {
        rust_files(&root.join(r), &mut files);
    }
    assert!(files.len() > 50, "only {} files found", files.len());
    let mut bad = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        for (line, code) in offences(&text) {
            bad.push(format!("{}:{line}: {code}", f.display()));
        }
    }
    assert!(
        bad.is_empty(),
        "a panic reachable from input must be an error; an impossible one says \
         `expect(\"invariant: why\")`:\n{}",
        bad.join("\n")
    );
}
