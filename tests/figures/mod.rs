//! Figures quoted in the docs, read where they stand and checked against what a test
//! measures, so that a stale figure fails the suite.
//!
//! In a Markdown file (README.md, ARCHITECTURE.md, docs/*.md) a figure that a test produces
//! is followed by a marker, an HTML comment that renders as nothing:
//!
//! ```text
//! | **silverbox_cubic** | 4 | **0.488**<!-- figure: silverbox.cubic.arrow --> | … |
//! f0 comes out within 0.03 %<!-- figure: constant_force.f0 -->
//! ```
//!
//! The figure is the number just before the marker (a `%`, `**` or a unit word between the
//! two is skipped; `−` is read as a minus sign; `5.383e-6` is read in scientific notation). The test that measures it calls
//! [`check`] with the measured value: the value must round to the figure as written (to
//! its last printed digit), or lie within the tolerance given to [`check_within`].
//! `tests/doc_figures.rs` checks that every marker in the docs is read by some test.
#![allow(dead_code)] // each test binary uses a subset

use std::path::Path;

/// A figure as the doc writes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figure {
    pub value: f64,
    /// Decimal places of the last digit as written (`0.488`: 3, `14`: 0, `5.383e-6`: 9).
    pub decimals: i32,
}

impl Figure {
    /// Half a unit of the last printed digit: the rounding the written figure allows.
    pub fn rounding(&self) -> f64 {
        0.5 * 10f64.powi(-self.decimals)
    }
}

/// The marker text for `name`.
pub fn marker(name: &str) -> String {
    format!("<!-- figure: {name} -->")
}

/// The repository root: the first directory up from the package's manifest that holds
/// `Cargo.lock` (this file is also included by the unit tests of `runtime/`).
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|p| p.join("Cargo.lock").exists())
        .expect("the workspace root holds Cargo.lock")
}

/// The figure marked `name` in `text`; panics (naming `doc`) when the marker is missing,
/// appears twice, or has no number before it.
pub fn figure_in(doc: &str, text: &str, name: &str) -> Figure {
    let m = marker(name);
    let mut at = text.match_indices(&m).map(|(i, _)| i);
    let i = at
        .next()
        .unwrap_or_else(|| panic!("{doc}: no marker `{m}`: the figure was moved or removed"));
    assert!(at.next().is_none(), "{doc}: marker `{m}` appears twice");
    number_before(&text[..i]).unwrap_or_else(|| {
        let start = text[..i].char_indices().rev().nth(30).map_or(0, |(k, _)| k);
        panic!("{doc}: no number before `{m}`: …{}", &text[start..i])
    })
}

/// The figure marked `name` in the file `doc` (relative to the repository root).
pub fn figure(doc: &str, name: &str) -> Figure {
    let text = std::fs::read_to_string(root().join(doc))
        .unwrap_or_else(|e| panic!("{doc} cannot be read: {e}"));
    figure_in(doc, &text, name)
}

/// Assert that `measured` rounds to the figure marked `name` in `doc` as written.
pub fn check(doc: &str, name: &str, measured: f64) {
    let f = figure(doc, name);
    check_within(doc, name, measured, f.rounding());
}

/// Assert that `measured` lies within `tol` of the figure marked `name` in `doc` (for a
/// figure that rounds a value which differs a little between machines).
pub fn check_within(doc: &str, name: &str, measured: f64, tol: f64) {
    let text = std::fs::read_to_string(root().join(doc))
        .unwrap_or_else(|e| panic!("{doc} cannot be read: {e}"));
    check_text(doc, &text, name, measured, Some(tol));
}

/// Assert that `measured` is of the order of the figure marked `name` in `doc`: within a
/// factor 10 either way. For a rounding error (`8.7e-14`), whose digits depend on the
/// processor's vector path and the order of its sums; the doc says so beside it.
pub fn check_order(doc: &str, name: &str, measured: f64) {
    let f = figure(doc, name);
    eprintln!(
        "figure {name} ({doc}): written {}, measured {}",
        shown(f.value),
        shown(measured)
    );
    assert!(
        measured.is_finite() && f.value > 0.0 && (measured / f.value).log10().abs() <= 1.0,
        "{doc} says {} for `{name}`, the test measures {} (allowed: a factor 10): \
         update the doc or find what changed",
        shown(f.value),
        shown(measured)
    );
}

/// [`check_within`] on the text of `doc` (`tol`: `None` for the figure's rounding).
pub fn check_text(doc: &str, text: &str, name: &str, measured: f64, tol: Option<f64>) {
    let f = figure_in(doc, text, name);
    let tol = tol.unwrap_or(f.rounding());
    eprintln!(
        "figure {name} ({doc}): written {}, measured {}",
        shown(f.value),
        shown(measured)
    );
    assert!(
        measured.is_finite()
            && (measured - f.value).abs() <= tol * (1.0 + 1e-9) + 1e-12 * f.value.abs(),
        "{doc} says {} for `{name}`, the test measures {} (allowed ± {}): \
         update the doc or find what changed",
        shown(f.value),
        shown(measured),
        shown(tol)
    );
}

/// A value as a message shows it: in scientific notation when very small or large.
fn shown(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Every marker name in `text`, in order.
pub fn markers_in(text: &str) -> Vec<&str> {
    text.match_indices("<!-- figure: ")
        .filter_map(|(i, m)| {
            let rest = &text[i + m.len()..];
            rest.find(" -->").map(|e| &rest[..e])
        })
        .collect()
}

/// The number that ends `before` (skipping blanks, `%`, `*`, `` ` `` and a unit word).
fn number_before(before: &str) -> Option<Figure> {
    let t = before.trim_end_matches([' ', '%', '*', '`']);
    // A unit or word right after the number (`0.488 mV`, `68 %`): skip one word.
    let t = match t.char_indices().next_back() {
        Some((_, c)) if c.is_alphabetic() => {
            let w = t.trim_end_matches(|c: char| c.is_alphabetic() || c == '/');
            w.trim_end_matches([' ', '%', '*'])
        }
        _ => t,
    };
    // Scientific notation (`5.383e-6`, `8.7e-14`): the mantissa's last digit is worth
    // 10^exponent of what it is worth alone.
    if let Some((e_at, exponent)) = exponent_suffix(t) {
        let m = plain_number_before(&t[..e_at])?;
        return Some(Figure {
            // One rounding: a division by an exact power of ten for a negative exponent.
            value: if exponent < 0 {
                m.value / 10f64.powi(-exponent)
            } else {
                m.value * 10f64.powi(exponent)
            },
            decimals: m.decimals - exponent,
        });
    }
    plain_number_before(t)
}

/// Where `t` ends in an exponent `e-6` (`e−6`, `e+6`, `e6`) right after a digit: the byte
/// index of the `e` and the exponent.
fn exponent_suffix(t: &str) -> Option<(usize, i32)> {
    let digits_at = t
        .char_indices()
        .rev()
        .take_while(|(_, c)| c.is_ascii_digit())
        .last()
        .map(|(k, _)| k)?;
    let magnitude: i32 = t[digits_at..].parse().ok()?;
    let head = &t[..digits_at];
    let (sign, rest) = if let Some(r) = head.strip_suffix(['-', '−']) {
        (-1, r)
    } else {
        (1, head.strip_suffix('+').unwrap_or(head))
    };
    let mantissa = rest.strip_suffix('e')?;
    mantissa.chars().next_back().filter(char::is_ascii_digit)?;
    Some((mantissa.len(), sign * magnitude))
}

/// The plain decimal number (`0.488`, `−3.2`, `14`) that ends `t`.
fn plain_number_before(t: &str) -> Option<Figure> {
    let start = t
        .char_indices()
        .rev()
        .take_while(|(_, c)| c.is_ascii_digit() || *c == '.')
        .last()
        .map(|(k, _)| k)?;
    let digits = &t[start..];
    let sign = match t[..start].chars().next_back() {
        Some('−' | '-') => -1.0,
        _ => 1.0,
    };
    let value: f64 = digits.parse().ok()?;
    let decimals = digits
        .find('.')
        .map_or(0, |p| (digits.len() - p - 1) as i32);
    Some(Figure {
        value: sign * value,
        decimals,
    })
}
