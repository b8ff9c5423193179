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
