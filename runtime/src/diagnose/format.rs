//! How the diagnosis writes its numbers: values, gaps and quantities with SI prefixes.

use dynid_ir::num;

/// Values in the diagnosis' text and report: five significant digits.
pub fn fmt_num(v: f64) -> String {
    num::sig(v, 5, false)
}

/// Gaps above this (in %) are printed as "> 1000 %": a prediction ten times the size of
/// the signal is simply wrong, and its digits say nothing more (the JSON keeps them).
pub const GAP_SHOWN_MAX: f64 = 1000.0;

/// A gap in % for the text and report: one decimal, "> 1000 %" beyond [`GAP_SHOWN_MAX`],
/// "diverged" for an infinite gap (a run that diverged), "unavailable" for one that cannot
/// be computed.
pub fn fmt_gap(v: f64) -> String {
    if v.is_finite() && v > GAP_SHOWN_MAX {
        format!("> {GAP_SHOWN_MAX:.0} %")
    } else if v.is_finite() {
        format!("{v:.1} %")
    } else if v == f64::INFINITY {
        "diverged".into()
    } else {
        "unavailable".into()
    }
}

/// A value in `unit` with the SI prefix that puts three significant digits before the
/// point or near it: `1.23e-5` m → "12.3 µm", `35.2` N → "35.2 N", `0.004` m/s → "4 mm/s";
/// "unavailable" when not finite.
pub fn fmt_si(v: f64, unit: &str) -> String {
    if !v.is_finite() {
        return "unavailable".into();
    }
    if v == 0.0 || unit.is_empty() {
        return format!("{} {unit}", num::sig(v, 3, false))
            .trim_end()
            .into();
    }
    const PREFIXES: [(f64, &str); 6] = [
        (1e6, "M"),
        (1e3, "k"),
        (1.0, ""),
        (1e-3, "m"),
        (1e-6, "µ"),
        (1e-9, "n"),
    ];
    let a = v.abs();
    let (scale, prefix) = PREFIXES
        .iter()
        .find(|(s, _)| a >= *s * 0.9995)
        .copied()
        .unwrap_or((1e-9, "n"));
    format!("{} {prefix}{unit}", num::sig(v / scale, 3, false))
}

/// [`fmt_gap`] of a gap that may be unavailable.
pub fn fmt_opt_gap(v: Option<f64>) -> String {
    v.map_or("unavailable".into(), fmt_gap)
}

/// `1 − after / before`; `None` when either gap is not finite or `before` is 0.
pub fn shrink(before: f64, after: f64) -> Option<f64> {
    (before.is_finite() && after.is_finite() && before > 0.0).then(|| 1.0 - after / before)
}
