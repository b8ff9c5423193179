//! The figures the docs attribute to tests are marked (`<!-- figure: NAME -->`, see
//! `tests/figures/mod.rs`) and read back by the test that measures them: here, that the
//! reader finds what it should, and that every marker in the docs is read by some test (a
//! marker no test reads would be a figure nothing checks).

mod figures;

use figures::{figure_in, markers_in, Figure};

#[test]
fn the_reader_takes_the_number_before_the_marker() {
    let text = "| cubic | **0.488**<!-- figure: a --> | 14 %<!-- figure: b --> | \
                r −0.13 %<!-- figure: c --> from clean positions, 12.0 mV<!-- figure: d -->, \
                4.6 standard errors<!-- figure: e -->";
    let f = |n| figure_in("text", text, n);
    assert_eq!(
        f("a"),
        Figure {
            value: 0.488,
            decimals: 3
        }
    );
    assert_eq!(
        f("b"),
        Figure {
            value: 14.0,
            decimals: 0
        }
    );
    assert_eq!(
        f("c"),
        Figure {
            value: -0.13,
            decimals: 2
        }
    );
    assert_eq!(
        f("d"),
        Figure {
            value: 12.0,
            decimals: 1
        }
    );
    assert_eq!(markers_in(text), ["a", "b", "c", "d", "e"]);
    assert_eq!(f("a").rounding(), 5e-4);
}

#[test]
fn the_reader_takes_scientific_notation() {
    let text = "| `m` | 5.383e-6<!-- figure: m --> | 8.7e-14<!-- figure: r --> (a), \
                −2.5e−3<!-- figure: n -->, 4e2<!-- figure: k --> and 1e<!-- figure: x -->";
    let f = |n| figure_in("text", text, n);
    let m = f("m");
    assert!(
        (m.value - 5.383e-6).abs() < 1e-18 && m.decimals == 9,
        "{m:?}"
    );
    let r = f("r");
    assert!(
        (r.value - 8.7e-14).abs() < 1e-26 && r.decimals == 15,
        "{r:?}"
    );
    let n = f("n");
    assert!((n.value + 2.5e-3).abs() < 1e-15 && n.decimals == 4, "{n:?}");
    assert_eq!(f("k").value, 400.0);
    assert_eq!(f("k").rounding(), 50.0);
    // `1e` has no exponent: the number is the 1.
    assert_eq!(f("x").value, 1.0);
    // Rounded as written: 5.3834e-6 is 5.383e-6, 5.3836e-6 is not.
    figures::check_text("x.md", text, "m", 5.3834e-6, None);
}

#[test]
#[should_panic(expected = "x.md says")]
fn a_stale_figure_in_scientific_notation_fails() {
    figures::check_text("x.md", "5.383e-6<!-- figure: m -->", "m", 5.3836e-6, None);
}

#[test]
#[should_panic(expected = "no marker")]
fn a_removed_figure_fails() {
    figure_in("text", "0.488 mV", "a");
}

#[test]
#[should_panic(expected = "says 0.488")]
fn a_stale_figure_fails() {
    // 0.4886 rounds to 0.489, not to the written 0.488.
    figures::check_text("x.md", "0.488<!-- figure: a -->", "a", 0.4886, None);
}

#[test]
fn a_figure_that_rounds_to_the_measured_value_passes() {
    figures::check_text("x.md", "0.488<!-- figure: a -->", "a", 0.48849, None);
    figures::check_text("x.md", "−0.14 %<!-- figure: a -->", "a", -0.136, None);
}

/// Every marker of README.md, ARCHITECTURE.md and docs/*.md is unique, has a number before
/// it, and its name is read by a test (it appears as `"NAME"` in tests/ or in a unit test).
#[test]
fn every_marked_figure_is_read_by_a_test() {
    let root = figures::root();
    let mut docs = vec!["README.md".to_string(), "ARCHITECTURE.md".to_string()];
    for e in std::fs::read_dir(root.join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            docs.push(format!("docs/{}", p.file_name().unwrap().to_str().unwrap()));
        }
    }
    let mut code = String::new();
    let mut stack = vec![root.join("tests"), root.join("runtime/src")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs")
                && !p.ends_with("tests/doc_figures.rs")
            {
                code.push_str(&std::fs::read_to_string(&p).unwrap());
            }
        }
    }
    let mut unread = Vec::new();
    let mut count = 0;
    for doc in &docs {
        let text = std::fs::read_to_string(root.join(doc)).unwrap();
        for name in markers_in(&text) {
            count += 1;
            figure_in(doc, &text, name);
            if !code.contains(&format!("\"{name}\"")) {
                unread.push(format!("{doc}: {name}"));
            }
        }
    }
    eprintln!("{count} marked figures in {} docs", docs.len());
    assert!(
        unread.is_empty(),
        "marked figures no test reads:\n{}",
        unread.join("\n")
    );
}

#[path = "../runtime/benches/common/row.rs"]
mod row;

/// The cells of the Markdown table row `line` (`None` when it is not a row).
fn cells(line: &str) -> Option<Vec<String>> {
    let inner = line.trim().strip_prefix('|')?.strip_suffix('|')?;
    // `\|` inside a cell is a literal bar.
    let mut out = vec![String::new()];
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                out.last_mut().unwrap().push('|');
                chars.next();
            }
            '|' => out.push(String::new()),
            c => out.last_mut().unwrap().push(c),
        }
    }
    Some(out.into_iter().map(|c| c.trim().to_string()).collect())
}

/// What is wrong with one row of the table of docs/performance.md (`None`: nothing).
fn row_fault(cells: &[String]) -> Option<String> {
    if cells.len() != row::COLUMNS.len() {
        return Some(format!(
            "{} cells, the table has {}",
            cells.len(),
            row::COLUMNS.len()
        ));
    }
    let bench = cells[0].trim_matches('`');
    let (date, commit, cpu) = (&cells[3], &cells[4], &cells[5]);
    let unmeasured = [date, commit, cpu].iter().all(|c| c.as_str() == "—");
    let dated = date.len() == 10
        && date.chars().enumerate().all(|(i, c)| {
            if i == 4 || i == 7 {
                c == '-'
            } else {
                c.is_ascii_digit()
            }
        });
    let hash = commit.trim_end_matches('+');
    let committed = hash.len() >= 7 && hash.chars().all(|c| c.is_ascii_hexdigit());
    let complete = dated && committed && !cpu.is_empty();
    if !(unmeasured || complete) {
        return Some(format!(
            "date `{date}`, commit `{commit}`, CPU `{cpu}`: a run gives all three (or `—` \
             in each before the first run)"
        ));
    }
    if cells[1].is_empty() || cells[2].is_empty() {
        return Some("no figure or no reference".into());
    }
    if !cells[6].contains(&format!("--bench {bench}")) {
        return Some(format!("the command does not run `--bench {bench}`"));
    }
    None
}

/// The row a bench prints is a row of the table (same columns, and it passes the checks).
#[test]
fn the_row_a_bench_prints_fits_the_table() {
    let line = row::format_row(
        "identify",
        "identification 12× the reference | pass 9.6×",
        "one pass that sums every value",
        "2026-11-24",
        "2af4f42+",
        "Intel Xeon, 2 threads",
        "cargo bench -p dynid-runtime --bench identify",
    );
    let c = cells(&line).expect("a table row");
    assert_eq!(c[1], "identification 12× the reference | pass 9.6×");
    assert_eq!(row_fault(&c), None, "{line}");
    let mut stale = c.clone();
    stale[4] = "?".into();
    assert!(row_fault(&stale).is_some());
}

/// docs/performance.md has a well-formed row for every bench of `runtime/benches/` and
/// `benches/`, and every bench prints its row (`row::print_row`).
#[test]
fn every_bench_has_a_row_in_the_performance_table() {
    let root = figures::root();
    let doc = std::fs::read_to_string(root.join("docs/performance.md")).unwrap();
    let header = format!("| {} |", row::COLUMNS.join(" | "));
    let start = doc
        .find(&header)
        .expect("docs/performance.md holds the table with the columns of row::COLUMNS");
    let rows: Vec<Vec<String>> = doc[start..]
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| cells(l).expect("a table row"))
        .collect();
    let mut faults = Vec::new();
    for r in &rows {
        if let Some(f) = row_fault(r) {
            faults.push(format!("row `{}`: {f}", r[0]));
        }
    }
    let mut benches = Vec::new();
    for dir in ["runtime/benches", "benches"] {
        for e in std::fs::read_dir(root.join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "rs") {
                let name = p.file_stem().unwrap().to_str().unwrap().to_string();
                let src = std::fs::read_to_string(&p).unwrap();
                if !src.contains("print_row(") {
                    faults.push(format!("{dir}/{name}.rs does not print its row"));
                }
                benches.push(name);
            }
        }
    }
    assert!(benches.len() >= 5, "benches found: {benches:?}");
    for b in &benches {
        if !rows.iter().any(|r| r[0] == format!("`{b}`")) {
            faults.push(format!("no row for the bench `{b}`"));
        }
    }
    for r in &rows {
        if !benches.iter().any(|b| r[0] == format!("`{b}`")) {
            faults.push(format!("row `{}` names no bench", r[0]));
        }
    }
    assert!(
        faults.is_empty(),
        "docs/performance.md:\n{}",
        faults.join("\n")
    );
}
