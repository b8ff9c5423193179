//! Every `expect` left in the library and CLI code states the invariant that makes it
//! unreachable (`expect("invariant: …")`, or `expect("grammar: …")` where the parser's
//! grammar guarantees the shape), and no bare `unwrap()` remains: bad input must come back
//! as an error, never as a panic. Unit-test modules (`#[cfg(test)] mod tests { … }` at the
//! end of a file, `tests.rs`, a `tests/` folder its parent declares `#[cfg(test)] mod tests;`)
//! and test-only helpers are exempt. Arithmetic on a count
//! converted from a float (`x.ceil() as usize + 1`) is checked or saturating: the
//! conversion saturates, and the `+` after it overflows.
//!
//! Indexing panics are not `unwrap`s: in the files where matrix sizes come from the data
//! ([`DATA_SHAPED`]) every function that indexes a matrix states the check that keeps its
//! indices in bounds (`// shape: …`).

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
    name == "tests.rs"
        || name.ends_with("_tests.rs")
        || name == "test_models.rs"
        || p.ends_with("data/fuzz.rs")
}

/// A folder `tests/` of unit tests inside a source tree: its parent module (`mod.rs` or
/// `lib.rs` beside it) declares it `#[cfg(test)] mod tests;`, so none of it is built into
/// the library. A `tests/` folder declared otherwise is audited like any other code.
fn is_test_folder(dir: &Path) -> bool {
    if dir.file_name().is_none_or(|n| n != "tests") {
        return false;
    }
    let Some(parent) = dir.parent() else {
        return false;
    };
    ["mod.rs", "lib.rs"].iter().any(|m| {
        std::fs::read_to_string(parent.join(m)).is_ok_and(|text| {
            let lines: Vec<&str> = text.lines().map(str::trim).collect();
            lines
                .windows(2)
                .any(|w| w[0] == "#[cfg(test)]" && w[1] == "mod tests;")
        })
    })
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            if !is_test_folder(&p) {
                rust_files(&p, out);
            }
        } else if p.extension().is_some_and(|e| e == "rs") && !is_test_file(&p) {
            out.push(p);
        }
    }
}

/// The lines of `text` before its inline unit-test module (`#[cfg(test)] mod tests {`),
/// numbered from 1. A module declared in another file (`#[cfg(test)] mod tests;`) ends
/// nothing: the code after the declaration is audited too.
fn code_lines(text: &str) -> Vec<(usize, &str)> {
    let lines: Vec<&str> = text.lines().collect();
    let cut = lines
        .windows(2)
        .position(|w| {
            w[0].trim() == "#[cfg(test)]"
                && w[1].trim_start().starts_with("mod tests")
                && !w[1].trim_end().ends_with(';')
        })
        .unwrap_or(lines.len());
    lines[..cut]
        .iter()
        .enumerate()
        .map(|(i, l)| (i + 1, *l))
        .collect()
}

/// Arithmetic on a count converted from a float (`(t / ts).ceil() as usize + 1`): the
/// conversion saturates at `usize::MAX` for a huge or tiny value from a flag or the data
/// (a corner of 1e-300 rad/s), and the `+`, `-` or `*` after it then overflows — a panic in
/// a debug build, a wrong count in a release build. Such arithmetic is written saturating
/// or checked (`.saturating_add(1)`).
fn unchecked_count_arithmetic(line: &str) -> bool {
    [") as usize +", ") as usize -", ") as usize *"]
        .iter()
        .any(|p| line.contains(p))
}

/// Offending lines of one file's code.
fn offences(text: &str) -> Vec<(usize, String)> {
    code_lines(text)
        .into_iter()
        .filter(|(_, l)| !l.trim_start().starts_with("//"))
        .filter(|(_, l)| {
            unchecked_count_arithmetic(l)
                || l.contains(".unwrap()")
                || l.match_indices(".expect(\"").any(|(i, m)| {
                    let msg = &l[i + m.len()..];
                    !(msg.starts_with("invariant: ") || msg.starts_with("grammar: "))
                })
        })
        .map(|(i, l)| (i, l.trim().to_string()))
        .collect()
}

/// Files whose matrices and vectors take their sizes from the data (the number of levels,
/// of points on a curve, of unknowns left after rank loss): there an index out of bounds
/// is a panic that input can reach, and `tests/panic_audit.rs` cannot see it as it sees an
/// `unwrap`. The rule: every function of these files that indexes a matrix (`m[(i, j)]`)
/// states, in a comment `// shape: …`, the check that keeps its indices in bounds (a guard
/// at its top, or the invariant of its caller).
const DATA_SHAPED: &[&str] = &[
    "runtime/src/detect/fit.rs",
    "runtime/src/detect/fit/template.rs",
    "runtime/src/detect/fit/wls.rs",
    "runtime/src/ident/solve.rs",
    "runtime/src/ident/stats.rs",
    "runtime/src/refine/qr.rs",
    "runtime/src/refine/sens.rs",
    "runtime/src/diagnose/search.rs",
];

/// Whether `line` indexes by a parenthesised expression (`m[(i, j)]`, `v[(a + b)..]`):
/// `[(` after a name or a closing bracket, not a slice of tuples (`&[(usize, f64)]`).
fn indexes_by_tuple(line: &str) -> bool {
    line.match_indices("[(").any(|(i, _)| {
        line[..i]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ')' || c == ']')
    })
}

/// Functions of `text` that index a matrix and state no `// shape:` check: `(line of the
/// fn, its first line)`. A function runs from its `fn` line to the closing brace at the
/// same indentation.
fn unchecked_indexing(text: &str) -> Vec<(usize, String)> {
    let lines = code_lines(text);
    let mut out = Vec::new();
    for (k, &(line, l)) in lines.iter().enumerate() {
        let body = l.trim_start();
        let is_fn = ["fn ", "pub fn ", "pub(crate) fn ", "pub(super) fn "]
            .iter()
            .any(|p| body.starts_with(p));
        if !is_fn {
            continue;
        }
        let indent = l.len() - body.len();
        let end = format!("{}}}", " ".repeat(indent));
        let span: Vec<&str> = lines[k..]
            .iter()
            .map(|&(_, l)| l)
            .take_while(|l| *l != end)
            .collect();
        let indexes = span
            .iter()
            .any(|l| !l.trim_start().starts_with("//") && indexes_by_tuple(l));
        let checked = span.iter().any(|l| l.trim_start().starts_with("// shape:"));
        if indexes && !checked {
            out.push((line, body.to_string()));
        }
    }
    out
}

#[test]
fn the_shape_audit_finds_unchecked_matrix_indexing() {
    let text = "fn a(m: &M) -> f64 {\n    m[(0, 1)]\n}\nfn b(m: &M) -> f64 {\n    // shape: m is 2 × 2 (checked by the caller)\n    m[(0, 1)]\n}\nfn c(h: &[(usize, f64)]) {}\n";
    let found: Vec<usize> = unchecked_indexing(text).iter().map(|o| o.0).collect();
    assert_eq!(found, [1]);
}

#[test]
fn the_audit_reads_past_a_test_module_declared_elsewhere() {
    let text = "#[cfg(test)]\nmod tests;\nfn a() {\n    x.unwrap();\n}\n";
    let found: Vec<usize> = offences(text).iter().map(|o| o.0).collect();
    assert_eq!(found, [4]);
}

#[test]
fn only_a_tests_folder_declared_cfg_test_is_left_out() {
    let dir = tempfile::tempdir().unwrap();
    for (module, decl) in [("a", "#[cfg(test)]\nmod tests;\n"), ("b", "mod tests;\n")] {
        std::fs::create_dir_all(dir.path().join(module).join("tests")).unwrap();
        std::fs::write(dir.path().join(module).join("mod.rs"), decl).unwrap();
    }
    assert!(is_test_folder(&dir.path().join("a").join("tests")));
    assert!(!is_test_folder(&dir.path().join("b").join("tests")));
    assert!(!is_test_folder(&dir.path().join("a")));
}

#[test]
fn matrix_indexing_on_data_dependent_shapes_states_its_bounds() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut bad = Vec::new();
    for f in DATA_SHAPED {
        let text = std::fs::read_to_string(root.join(f)).unwrap();
        for (line, code) in unchecked_indexing(&text) {
            bad.push(format!("{f}:{line}: {code}"));
        }
    }
    assert!(
        bad.is_empty(),
        "these functions index matrices whose sizes come from the data: check the shape \
         (fewer points than coefficients, an empty curve) and say how in a `// shape:` \
         comment:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_audit_finds_what_it_looks_for() {
    let text = "fn a() {\n    x.unwrap();\n    y.expect(\"oops\");\n    z.expect(\"invariant: fine\");\n    let n = (t / ts).ceil() as usize + 1;\n    let m = ((t / ts).ceil() as usize).saturating_add(1);\n    let k = r as usize * len;\n}\n#[cfg(test)]\nmod tests {\n    fn t() { w.unwrap(); }\n}\n";
    let found: Vec<usize> = offences(text).iter().map(|o| o.0).collect();
    assert_eq!(found, [2, 3, 5]);
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
         `expect(\"invariant: why\")`; arithmetic on a count converted from a float is \
         saturating or checked:\n{}",
        bad.join("\n")
    );
}
