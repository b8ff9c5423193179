//! The plain-text report of a [`Detection`].

use super::format::{fmt_g, fmt_pm};
use super::types::{Detection, Verdict};
use dynid_ir::print::aligned;

impl Detection {
    /// A plain-text report: the constancy test of every curve, then one block per element
    /// with its verdict and template ranking.
    pub fn render_table(&self) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let _ = writeln!(out, "Parameter curves over {} levels", self.n_levels);
        if let Some(line) = self.rows.describe() {
            let _ = writeln!(out, "{line}");
        }
        let mut rows = vec![vec![
            "param".to_string(),
            "element".into(),
            "role".into(),
            "weighted mean".into(),
            "change".into(),
            "χ²/dof".into(),
            "p".into(),
            "drifts".into(),
        ]];
        for p in &self.params {
            rows.push(vec![
                p.curve.param.clone(),
                p.curve.element.clone(),
                format!("{:?}", p.curve.role),
                fmt_pm(p.mean, p.mean_stderr),
                format!("{:.1} %", 100.0 * p.rel_change),
                fmt_g(p.chi2 / p.dof as f64),
                format!("{:.2e}", p.p_value),
                if p.drifting { "DRIFTS" } else { "-" }.into(),
            ]);
        }
        out.push_str(&aligned(
            &rows,
            &[false, false, false, true, true, true, true, false],
            "  ",
        ));
        let _ = writeln!(out, "Per level (value ± standard error):");
        let mut rows = vec![std::iter::once("param".to_string())
            .chain(self.level_labels.iter().cloned())
            .collect::<Vec<_>>()];
        for p in &self.params {
            rows.push(
                std::iter::once(p.curve.param.clone())
                    .chain(
                        p.curve
                            .values
                            .iter()
                            .zip(&p.curve.stderrs)
                            .map(|(v, s)| fmt_pm(*v, *s)),
                    )
                    .collect(),
            );
        }
        let mut right = vec![true; self.n_levels + 1];
        right[0] = false;
        out.push_str(&aligned(&rows, &right, "  "));
        if !self.held.is_empty() {
            let h: Vec<String> = self
                .held
                .iter()
                .map(|h| format!("{} = {}", h.param, fmt_pm(h.value, h.stderr)))
                .collect();
            let _ = writeln!(
                out,
                "Held at one value for all levels (a mass at the weighted mean of its free \
                 per-level estimates, a constant\n  force at its pooled estimate; linearisation \
                 changes neither): {}",
                h.join(", ")
            );
        }
        for e in &self.elements {
            let _ = writeln!(out);
            let _ = writeln!(out, "Element {}: {}", e.element, e.verdict);
            if let Verdict::Nonlinear { summary, .. } = &e.verdict {
                let _ = writeln!(out, "  {summary}");
            }
            if !e.estimator.is_empty() {
                let tried: Vec<String> = e
                    .estimator
                    .iter()
                    .map(|f| {
                        let what = if f.explains {
                            "explains all".to_string()
                        } else if f.still_drifting.is_empty() {
                            "not simulated at every level".to_string()
                        } else {
                            format!("leaves {} drifting", f.still_drifting.join(", "))
                        };
                        format!(
                            "{} {} = {} (χ² {}/{}, {what})",
                            f.effect,
                            f.coef_name,
                            fmt_pm(f.value, f.stderr),
                            fmt_g(f.chi2),
                            f.dof
                        )
                    })
                    .collect();
                let _ = writeln!(
                    out,
                    "  through the estimator (simulated at the measured inputs, refitted per \
                     level):\n    {}",
                    tried.join(";\n    ")
                );
            }
            if let Some(why) = &e.explained_by {
                let _ = writeln!(out, "  drifts ({}), but {why}", e.drifting.join(", "));
            }
            if let Some(x) = &e.suspected {
                let _ = writeln!(
                    out,
                    "  also suspected: {} — `{}` drifts too (p = {:.1e}) and the verdict leaves \
                     that unexplained;\n  the pair is #{} in the ranking (ΔAICc {}): {};\n  more levels \
                     would separate the two",
                    x.effect,
                    x.curve,
                    x.curve_p_value,
                    x.pair_rank,
                    fmt_g(x.pair_delta_aicc),
                    x.pair_summary
                );
            }
            if let Some(line) = e.unranked_explanation() {
                let _ = writeln!(out, "  {line}");
            }
            if e.ranking.is_empty() {
                continue;
            }
            let mut rows = vec![vec![
                "#".to_string(),
                "template".into(),
                "ΔAICc".into(),
                "explains".into(),
                "χ²/dof".into(),
                "implied parameters".into(),
            ]];
            for (i, f) in e.ranking.iter().take(6).enumerate() {
                let est: Vec<String> = f.effect_estimates().iter().map(|x| x.to_string()).collect();
                rows.push(vec![
                    (i + 1).to_string(),
                    f.name.clone(),
                    fmt_g(f.delta_aicc),
                    format!("{:.1} %", 100.0 * f.explained),
                    fmt_g(f.reduced_chi2),
                    est.join(", "),
                ]);
            }
            out.push_str(&aligned(
                &rows,
                &[true, false, true, true, true, false],
                "  ",
            ));
            let _ = writeln!(
                out,
                "  constant (linear) model: ΔAICc = {}, over-dispersion ĉ = {}",
                fmt_g(e.constant_aicc - e.ranking[0].aicc),
                fmt_g(e.c_hat)
            );
        }
        for c in &self.constant_forces {
            let _ = writeln!(out);
            let _ = writeln!(out, "Mean not explained by the linear model: {}", c.message);
        }
        if !self.measured_s.is_empty() || !self.measured_v.is_empty() {
            let _ = writeln!(out);
            let what = |v: &[String], sig: &str| {
                if v.is_empty() {
                    String::new()
                } else {
                    format!("{sig}: {}; ", v.join(", "))
                }
            };
            let _ = writeln!(
                out,
                "Templates linearised over the measured distribution of {}{}Gaussian elsewhere.",
                what(&self.measured_s, "s"),
                what(&self.measured_v, "v")
            );
        }
        out
    }
}
