//! The diagnosis as text: verdict, location, effect, gaps and the evidence behind them.

use super::effects::Effect;
use super::format::{fmt_gap, fmt_num, fmt_opt_gap, fmt_si, shrink};
use super::types::{
    CandidateScore, Diagnosis, FoundEffect, ModelGap, MovedParam, SignalGap, Verdict,
};

/// A shrink as "N % `word`" (e.g. "N % smaller"), "N % larger" when the gap grew, "N×
/// larger" when it more than doubled (a percentage of a gap near zero says nothing), or
/// "change unavailable" when a gap diverged.
pub fn fmt_shrink(shrink: Option<f64>, word: &str) -> String {
    match shrink {
        Some(x) if x >= 0.0 => format!("{:.0} % {word}", 100.0 * x),
        Some(x) if x < -1.0 => format!("{:.1}× larger", 1.0 - x),
        Some(x) => format!("{:.0} % larger", -100.0 * x),
        None => "change unavailable".into(),
    }
}

/// The gap table: a label column and two right-aligned columns, each as wide as its widest
/// cell plus a blank (at least 12), so that cells never run together.
fn gap_table(rows: &[(&str, &ModelGap)]) -> String {
    use std::fmt::Write;
    let cells: Vec<(String, String)> = rows
        .iter()
        .map(|(_, g)| (fmt_gap(g.gap), fmt_gap(g.pathwise)))
        .collect();
    let width = |head: &str, col: &dyn Fn(&(String, String)) -> usize| {
        cells
            .iter()
            .map(col)
            .chain([head.chars().count()])
            .max()
            .unwrap_or(0)
            .saturating_add(1)
            .max(12)
    };
    let w1 = width("statistical", &|c| c.0.chars().count());
    let w2 = width("pathwise", &|c| c.1.chars().count());
    let label = rows
        .iter()
        .map(|(l, _)| l.chars().count())
        .max()
        .unwrap_or(0)
        .max(36);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<w$}{:>w1$}{:>w2$}",
        "",
        "statistical",
        "pathwise",
        w = label + 2
    );
    for ((l, _), (a, b)) in rows.iter().zip(&cells) {
        let _ = writeln!(s, "  {l:<label$}{a:>w1$}{b:>w2$}");
    }
    s
}

/// One signal's mean gaps over the levels: (statistical %, free-run RMS error in the
/// unit, unit).
pub type SignalMeans = (f64, f64, String);

/// Means over the levels of one signal's gaps in a model's gap; `None` when no level has
/// the signal.
pub fn signal_means(g: &ModelGap, signal: &str) -> Option<SignalMeans> {
    let v: Vec<&SignalGap> = g
        .levels
        .iter()
        .filter_map(|l| l.signals.iter().find(|s| s.signal == signal))
        .collect();
    let n = v.len() as f64;
    let first = v.first()?;
    Some((
        v.iter().map(|s| s.statistical).sum::<f64>() / n,
        v.iter().map(|s| s.rms_error).sum::<f64>() / n,
        first.unit.clone(),
    ))
}

/// Per response signal and model: the statistical gap with the free-run RMS error in the
/// signal's unit beside it (a position gap of 0.0 % may be micrometres that matter; the
/// force of a closed loop often carries the information).
fn signal_table(signals: &[String], rows: &[(&str, &ModelGap)]) -> String {
    use std::fmt::Write;
    let mut s = String::from(
        "Per signal (mean over levels; statistical gap, free-run RMS error in the signal's unit):\n",
    );
    let width = signals.iter().map(|n| n.chars().count()).max().unwrap_or(0);
    for name in signals {
        let cells: Vec<String> = rows
            .iter()
            .filter_map(|(label, g)| {
                let (gap, rms, unit) = signal_means(g, name)?;
                let label = label.split(' ').next().unwrap_or(label);
                Some(format!("{label} {} ({})", fmt_gap(gap), fmt_si(rms, &unit)))
            })
            .collect();
        if !cells.is_empty() {
            let _ = writeln!(s, "  {name:<width$}  {}", cells.join(" → "));
        }
    }
    s
}

impl Diagnosis {
    /// The force channel of each recorded force (open-loop models): the equation residual
    /// in N with its share of the force's spread, per model; empty without one.
    pub fn force_table(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        for f in &self.force_gaps {
            let cells: Vec<String> = [
                ("nominal", f.nominal),
                ("re-identified", f.reidentified),
                ("corrected", f.corrected),
            ]
            .iter()
            .filter_map(|(label, v)| {
                v.map(|v| {
                    format!(
                        "{label} {} ({})",
                        fmt_gap(v.percent),
                        fmt_si(v.rms, &f.unit)
                    )
                })
            })
            .collect();
            if cells.is_empty() {
                continue;
            }
            let _ = writeln!(s, "  {} (force channel)  {}", f.input, cells.join(" → "));
        }
        if let Some(f) = self.force_gaps.first() {
            let _ = writeln!(
                s,
                "  (force channel: the force the model needs for the measured motion minus the \
                 recorded one, RMS below {} Hz on the motion, rests left out; % of the recorded \
                 force's std)",
                fmt_num(f.band_hz)
            );
        }
        s
    }

    /// A short human summary: verdict, location, effect, shrink, evidence.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        self.write_gaps(&mut s);
        self.write_where(&mut s);
        match self.verdict {
            Verdict::MissingEffect => {
                for (k, f) in self.found.iter().enumerate() {
                    self.write_found(&mut s, k, f);
                }
                self.write_missing_effect(&mut s);
            }
            Verdict::MistunedParameters => self.write_mistuned(&mut s),
            Verdict::Consistent => {
                let _ = writeln!(
                    s,
                    "No significant unmodelled effect: the model matches the data within {} (statistical gap, {}).",
                    fmt_gap(self.reidentified.gap.min(self.nominal.gap)),
                    if self.reidentified.gap < self.nominal.gap {
                        "re-identified"
                    } else {
                        "nominal"
                    }
                );
            }
            Verdict::Unexplained => {
                let _ = writeln!(
                    s,
                    "No significant unmodelled effect from the library explains the remaining gap (nominal {}, re-identified {}; pathwise {} and {}).",
                    fmt_gap(self.nominal.gap),
                    fmt_gap(self.reidentified.gap),
                    fmt_gap(self.nominal.pathwise),
                    fmt_gap(self.reidentified.pathwise)
                );
                // What came nearest: a location the covariance rows point at, whose free
                // runs did not shrink the gap enough, is worth knowing.
                let nearest: Vec<_> = self
                    .ranking
                    .iter()
                    .filter(|c| c.value.is_finite())
                    .take(3)
                    .collect();
                if !nearest.is_empty() {
                    let _ = writeln!(
                        s,
                        "Nearest candidates (by the cross-validated covariance residual):"
                    );
                    for c in nearest {
                        let _ = writeln!(s, "  {}", candidate_line(c));
                    }
                }
            }
        }
        for n in &self.notes {
            let _ = writeln!(s, "Note: {n}");
        }
        s
    }

    /// The header and the gap tables.
    fn write_gaps(&self, s: &mut String) {
        use std::fmt::Write;
        let _ = writeln!(
            s,
            "Model `{}` against {} levels ({}); response signals: {}",
            self.model,
            self.levels.len(),
            self.levels.join(", "),
            self.response_signals.join(", ")
        );
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Gap (mean over response signals and levels; statistical: spectrum and std of each signal, the headline; pathwise: free-run NRMSE):"
        );
        let mut rows: Vec<(&str, &ModelGap)> = vec![
            ("nominal model", &self.nominal),
            ("re-identified (withheld level)", &self.reidentified),
        ];
        if !self.found.is_empty() {
            rows.push(("corrected model (withheld level)", &self.corrected));
        }
        *s += &gap_table(&rows);
        *s += &signal_table(&self.response_signals, &rows);
        *s += &self.force_table();
        let _ = writeln!(s);
    }

    /// Where the nominal model misses: the worst signals, the covariance residual of each
    /// equation, the parameters drifting with the level.
    fn write_where(&self, s: &mut String) {
        use std::fmt::Write;
        let worst: Vec<String> = {
            let mut sig: Vec<(String, Option<SignalMeans>)> = self
                .response_signals
                .iter()
                .map(|name| (name.clone(), signal_means(&self.nominal, name)))
                .collect();
            let key =
                |v: &Option<(f64, f64, String)>| v.as_ref().map_or(f64::NEG_INFINITY, |v| v.0);
            sig.sort_by(|a, b| key(&b.1).total_cmp(&key(&a.1)));
            sig.iter()
                .take(3)
                .map(|(n, v)| match v {
                    Some((g, rms, unit)) => {
                        format!("{n} {} (RMS {})", fmt_gap(*g), fmt_si(*rms, unit))
                    }
                    None => format!("{n} {}", fmt_opt_gap(None)),
                })
                .collect()
        };
        let _ = writeln!(s, "Where: worst signals (nominal): {}", worst.join(", "));
        let eqs: Vec<String> = self
            .equations
            .iter()
            .map(|e| {
                let v: Vec<f64> = e.per_level.iter().flatten().copied().collect();
                let mean = (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
                format!("{} {}", e.equation, fmt_opt_gap(mean))
            })
            .collect();
        let _ = writeln!(
            s,
            "       covariance residual per equation: {}",
            eqs.join(", ")
        );
        let drifting: Vec<String> = self
            .drift
            .iter()
            .filter(|d| d.significant)
            .map(|d| {
                let v: Vec<String> = d
                    .per_level
                    .iter()
                    .map(|x| x.map_or("–".into(), fmt_num))
                    .collect();
                format!("{} [{}]", d.name, v.join(" → "))
            })
            .collect();
        if drifting.is_empty() {
            let _ = writeln!(s, "       no parameter drifts significantly with the level");
        } else {
            let _ = writeln!(
                s,
                "       parameters drifting with level: {}",
                drifting.join(", ")
            );
        }
        let _ = writeln!(s);
    }

    /// The `k`-th found effect `f`: what and where, its estimate, gaps and confidence.
    fn write_found(&self, s: &mut String, k: usize, f: &FoundEffect) {
        use std::fmt::Write;
        let step = shrink(f.gap_before, f.gap_after);
        // The statistical gap does not see a signal's mean, all that a
        // constant force changes: its confidence counts the pathwise shrink.
        let mean_only = f.effect == Effect::ConstantForce
            && step.is_none_or(|x| x <= 0.0)
            && f.pathwise_gap_after < f.pathwise_gap_before;
        let seen = if mean_only {
            shrink(f.pathwise_gap_before, f.pathwise_gap_after)
        } else {
            step
        };
        let conf = confidence(f.value / f.stderr, seen.map_or(0.0, |x| 100.0 * x));
        let _ = writeln!(
            s,
            "{} missing effect: {} at {}{}{}",
            if k == 0 { "Most likely" } else { "Also" },
            f.effect.name(),
            f.location.label(),
            f.unit
                .map_or(String::new(), |u| format!(": {} {u}", fmt_num(f.value))),
            if f.location.elements.is_empty() {
                " (body to ground)".to_string()
            } else {
                format!(" (element {})", f.location.elements.join(", "))
            }
        );
        let _ = writeln!(
            s,
            "  identified {} = {} ± {} (|p|/σ = {:.0}); withheld gap {} → {} ({}; pathwise {} → {}); confidence: {}",
            f.param,
            fmt_num(f.value),
            fmt_num(f.stderr),
            f.value.abs() / f.stderr,
            fmt_gap(f.gap_before),
            fmt_gap(f.gap_after),
            fmt_shrink(step, "smaller")
                + if mean_only {
                    ", a mean the statistical gap does not see"
                } else {
                    ""
                },
            fmt_gap(f.pathwise_gap_before),
            fmt_gap(f.pathwise_gap_after),
            conf
        );
        if let Effect::Backlash { gap } = f.effect {
            let _ = writeln!(
                s,
                "  gap {} ± {} (profiled over the covariance least squares, grid start {})",
                fmt_num(gap),
                f.shape_stderr.map_or("n/a (flat profile)".into(), fmt_num),
                self.ranking
                    .iter()
                    .filter(|c| c.location == f.location)
                    .find_map(|c| match c.effect {
                        Effect::Backlash { gap } => Some(fmt_num(gap)),
                        _ => None,
                    })
                    .unwrap_or_else(|| "–".into()),
            );
        }
    }

    /// After the found effects: what re-identification and the effects each removed, the
    /// runner-up, and what remains below the acceptance threshold.
    fn write_missing_effect(&self, s: &mut String) {
        use std::fmt::Write;
        let _ = writeln!(
            s,
            "Re-identification alone: {} → {}; the effect{}: {} → {} ({})",
            fmt_gap(self.gap_before),
            fmt_gap(self.gap_reidentified),
            if self.found.len() > 1 { "s" } else { "" },
            fmt_gap(self.gap_reidentified),
            fmt_gap(self.gap_after),
            fmt_shrink(self.effect_shrink, "of the re-identified gap removed"),
        );
        let _ = writeln!(
            s,
            "Overall (nominal → corrected): {} → {} ({}); pathwise {} → {}",
            fmt_gap(self.gap_before),
            fmt_gap(self.gap_after),
            fmt_shrink(self.shrink, "of the gap removed"),
            fmt_gap(self.pathwise_gap_before),
            fmt_gap(self.pathwise_gap_after),
        );
        if let Some(next) = self
            .ranking
            .iter()
            .filter(|c| !c.accepted)
            .find(|c| c.gap.is_some())
        {
            let _ = writeln!(
                s,
                "  runner-up: {} at {} (withheld gap {})",
                next.effect.name(),
                next.location.label(),
                fmt_opt_gap(next.gap)
            );
        }
        if !self.residual_ranking.is_empty() {
            let _ = writeln!(s, "On top of that, below the acceptance threshold:");
            for c in self.residual_ranking.iter().take(4) {
                let _ = writeln!(s, "  {}", candidate_line(c));
            }
        }
    }

    /// Mis-tuned parameters: the gaps and the parameters that moved most.
    fn write_mistuned(&self, s: &mut String) {
        use std::fmt::Write;
        let _ = writeln!(
            s,
            "Mis-tuned parameters: re-identification alone removes the gap ({} → {}; pathwise {} → {}); no significant unmodelled effect.",
            fmt_gap(self.nominal.gap),
            fmt_gap(self.reidentified.gap),
            fmt_gap(self.nominal.pathwise),
            fmt_gap(self.reidentified.pathwise)
        );
        let mut moved = self.moved.clone();
        let size = |m: &MovedParam| m.change.map_or(f64::INFINITY, f64::abs);
        moved.sort_by(|a, b| size(b).total_cmp(&size(a)));
        for m in moved.iter().take(4) {
            let change = m.change.map_or("from 0".into(), |r| format!("{r:+.1} %"));
            let _ = writeln!(
                s,
                "  {}: {} → {} ({change})",
                m.name,
                fmt_num(m.nominal),
                fmt_num(m.identified)
            );
        }
    }
}

pub(super) fn confidence(t: f64, shrink: f64) -> &'static str {
    if t.abs() > 20.0 && shrink > 70.0 {
        "high"
    } else if t.abs() > 8.0 && shrink > 40.0 {
        "medium"
    } else {
        "low"
    }
}

/// One candidate as the search left it: effect, location, estimate, withheld gap where it
/// was scored, and why it was not accepted.
fn candidate_line(c: &CandidateScore) -> String {
    let gap = c
        .gap
        .map_or(String::new(), |g| format!(", withheld gap {}", fmt_gap(g)));
    let val = if c.value.is_finite() {
        format!("{} ± {}", fmt_num(c.value), fmt_num(c.stderr))
    } else {
        "–".into()
    };
    let why = match (c.note.is_empty(), c.gap.is_some()) {
        (false, _) => c.note.as_str(),
        (true, true) => "not accepted",
        (true, false) => "not scored",
    };
    format!(
        "{} at {}: {val}{gap} ({why})",
        c.effect.name(),
        c.location.label()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gap(gap: f64, pathwise: f64) -> ModelGap {
        ModelGap {
            label: String::new(),
            gap,
            pathwise,
            levels: Vec::new(),
        }
    }

    #[test]
    fn values_in_units_take_the_prefix_that_fits() {
        use crate::diagnose::fmt_si;
        assert_eq!(fmt_si(1.23e-5, "m"), "12.3 µm");
        assert_eq!(fmt_si(-3e-6, "m"), "-3 µm");
        assert_eq!(fmt_si(0.0834, "m"), "83.4 mm");
        assert_eq!(fmt_si(35.24, "N"), "35.2 N");
        assert_eq!(fmt_si(0.004, "m/s"), "4 mm/s");
        assert_eq!(fmt_si(0.9996, "N"), "1 N");
        assert_eq!(fmt_si(0.0, "N"), "0 N");
        assert_eq!(fmt_si(f64::NAN, "N"), "unavailable");
    }

    #[test]
    fn the_gap_table_keeps_its_columns_apart_at_any_value() {
        let (a, b, c) = (
            gap(8_878_825.0, 5_803_459_933.7),
            gap(0.8, f64::INFINITY),
            gap(f64::NAN, 12.34),
        );
        let t = gap_table(&[("nominal model", &a), ("re-identified", &b), ("x", &c)]);
        // Huge gaps are not printed digit by digit, and no two cells touch.
        assert!(!t.contains("8878825"), "{t}");
        assert!(t.contains("> 1000 %"), "{t}");
        for line in t.lines().skip(1) {
            assert!(!line.contains("%>") && !line.contains("%d") && !line.contains("%u"));
            let cells: Vec<&str> = line.split("  ").filter(|c| !c.trim().is_empty()).collect();
            assert_eq!(cells.len(), 3, "{line:?} in\n{t}");
        }
        // Ordinary values keep the layout the table always had.
        let t = gap_table(&[("nominal model", &gap(0.0, 0.0))]);
        assert_eq!(
            t,
            format!(
                "{:<38}{:>12}{:>12}\n  {:<36}{:>12}{:>12}\n",
                "", "statistical", "pathwise", "nominal model", "0.0 %", "0.0 %"
            )
        );
    }
}
