//! The diagnosis as text: verdict, location, effect, gaps and the evidence behind them.

use super::fmt_num;
use super::types::{Diagnosis, MovedParam, Verdict};

impl Diagnosis {
    /// A short human summary: verdict, location, effect, shrink, evidence.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Model `{}` against {} levels ({}); response signals: {}",
            self.model,
            self.levels.len(),
            self.levels.join(", "),
            self.response_signals.join(", ")
        );
        let _ = writeln!(s);
        let _ = writeln!(s, "Gap (free-run NRMSE, mean over response signals):");
        let _ = writeln!(
            s,
            "  nominal model                      {:>7.1} %",
            self.nominal.gap
        );
        let _ = writeln!(
            s,
            "  re-identified (withheld level)     {:>7.1} %",
            self.reidentified.gap
        );
        if !self.found.is_empty() {
            let _ = writeln!(
                s,
                "  corrected model (withheld level)   {:>7.1} %",
                self.corrected.gap
            );
        }
        let _ = writeln!(s);
        // Where.
        let worst: Vec<String> = {
            let mut sig: Vec<(String, f64)> = self
                .response_signals
                .iter()
                .map(|name| {
                    let v: Vec<f64> = self
                        .nominal
                        .levels
                        .iter()
                        .filter_map(|l| l.signals.iter().find(|g| &g.signal == name))
                        .map(|g| g.nrmse)
                        .collect();
                    (name.clone(), v.iter().sum::<f64>() / v.len().max(1) as f64)
                })
                .collect();
            sig.sort_by(|a, b| b.1.total_cmp(&a.1));
            sig.iter()
                .take(3)
                .map(|(n, v)| format!("{n} {v:.1} %"))
                .collect()
        };
        let _ = writeln!(s, "Where: worst signals (nominal): {}", worst.join(", "));
        let eqs: Vec<String> = self
            .equations
            .iter()
            .map(|e| {
                format!(
                    "{} {:.1} %",
                    e.equation,
                    e.per_level.iter().sum::<f64>() / e.per_level.len().max(1) as f64
                )
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
        match self.verdict {
            Verdict::MissingEffect => {
                for (k, f) in self.found.iter().enumerate() {
                    let shrink = 100.0 * (1.0 - f.gap_after / f.gap_before.max(1e-300));
                    let conf = confidence(f.value / f.stderr, shrink);
                    let _ = writeln!(
                        s,
                        "{} missing effect: {} at {}{}",
                        if k == 0 { "Most likely" } else { "Also" },
                        f.effect.name(),
                        f.location.label(),
                        if f.location.elements.is_empty() {
                            " (body to ground)".to_string()
                        } else {
                            format!(" (element {})", f.location.elements.join(", "))
                        }
                    );
                    let _ = writeln!(
                        s,
                        "  identified {} = {} ± {} (|p|/σ = {:.0}); withheld gap {:.1} % → {:.1} % ({:.0} % smaller); confidence: {}",
                        f.param,
                        fmt_num(f.value),
                        fmt_num(f.stderr),
                        f.value.abs() / f.stderr,
                        f.gap_before,
                        f.gap_after,
                        shrink,
                        conf
                    );
                }
                let _ = writeln!(
                    s,
                    "Overall: {:.1} % → {:.1} % ({:.0} % of the gap removed); remaining {:.1} %",
                    self.gap_before,
                    self.gap_after,
                    100.0 * self.shrink,
                    self.gap_after
                );
                if let Some(next) = self
                    .ranking
                    .iter()
                    .filter(|c| !c.accepted)
                    .find(|c| c.gap.is_some())
                {
                    let _ = writeln!(
                        s,
                        "  runner-up: {} at {} (withheld gap {:.1} %)",
                        next.effect.name(),
                        next.location.label(),
                        next.gap.unwrap_or(f64::NAN)
                    );
                }
                if !self.residual_ranking.is_empty() {
                    let _ = writeln!(s, "On top of that, below the acceptance threshold:");
                    for c in self.residual_ranking.iter().take(4) {
                        let gap = c
                            .gap
                            .map_or(String::new(), |g| format!(", withheld gap {g:.1} %"));
                        let val = if c.value.is_finite() {
                            format!("{} ± {}", fmt_num(c.value), fmt_num(c.stderr))
                        } else {
                            "–".into()
                        };
                        let _ = writeln!(
                            s,
                            "  {} at {}: {val}{gap} ({})",
                            c.effect.name(),
                            c.location.label(),
                            if c.note.is_empty() {
                                "not scored"
                            } else {
                                &c.note
                            }
                        );
                    }
                }
            }
            Verdict::MistunedParameters => {
                let _ = writeln!(
                    s,
                    "Mis-tuned parameters: re-identification alone removes the gap ({:.1} % → {:.1} %); no significant unmodelled effect.",
                    self.nominal.gap, self.reidentified.gap
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
            Verdict::Consistent => {
                let _ = writeln!(
                    s,
                    "No significant unmodelled effect: the model matches the data within {:.1} %.",
                    self.reidentified.gap.min(self.nominal.gap)
                );
            }
            Verdict::Unexplained => {
                let _ = writeln!(
                    s,
                    "No significant unmodelled effect from the library explains the remaining gap of {:.1} %.",
                    self.reidentified.gap
                );
            }
        }
        for n in &self.notes {
            let _ = writeln!(s, "Note: {n}");
        }
        s
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
