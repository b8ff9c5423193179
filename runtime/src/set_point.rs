//! A closed-loop record seen through an open-loop model: a data column the model does not
//! read that a measured position follows closely is most likely the set point of a
//! position controller. Driven by the recorded force alone, the free run of such a plant
//! (an integrator when nothing pulls it back) drifts; declared as a `reference` with the
//! controller's `control` law, the free run closes the loop on the recorded set point.

use crate::describe::{mean, std_dev};
use crate::record::Record;
use dynid_ir::ir::{ModelIr, SignalKind};
use serde::Serialize;

/// Correlation from which a position is said to follow a column.
pub const FOLLOWS: f64 = 0.95;

/// A free-run NRMSE of a position (in %) from which the free run is said to drift.
pub const DRIFTS: f64 = 20.0;

/// A column that looks like a set point of a measured position.
#[derive(Clone, Debug, Serialize)]
pub struct SetPoint {
    /// The data column the model does not read.
    pub column: String,
    /// The model's measured position that follows it.
    pub position: String,
    /// Correlation of the two (means removed).
    pub correlation: f64,
    /// The input acting on the position's body (the controller's output), if any.
    pub input: Option<String>,
}

/// Columns of `rec` that `ir` neither measures, reads nor declares, each paired with the
/// measured position that follows it best: correlation ≥ [`FOLLOWS`] and a spread within
/// a factor 2 of the position's (a set point in the position's units). Best first.
pub fn set_points(ir: &ModelIr, rec: &Record) -> Vec<SetPoint> {
    let positions: Vec<(usize, &str, &[f64])> = ir
        .signals
        .iter()
        .filter(|s| s.measured)
        .filter_map(|s| match s.kind {
            SignalKind::Position(b) => rec.column(&s.name).map(|c| (b.index(), s.name.as_str(), c)),
            _ => None,
        })
        .collect();
    let mut out = Vec::new();
    for (name, col) in rec.names.iter().zip(&rec.columns) {
        if ir.signals.iter().any(|s| &s.name == name) || col.len() < 3 {
            continue;
        }
        let best = positions
            .iter()
            .filter_map(|&(b, p, x)| {
                let c = correlation(col, x)?;
                let ratio = std_dev(col) / std_dev(x);
                (c >= FOLLOWS && (0.5..=2.0).contains(&ratio)).then_some((b, p, c))
            })
            .max_by(|a, b| a.2.total_cmp(&b.2));
        if let Some((b, p, c)) = best {
            out.push(SetPoint {
                column: name.clone(),
                position: p.to_string(),
                correlation: c,
                input: ir
                    .inputs
                    .iter()
                    .find(|i| i.body.index() == b)
                    .map(|i| i.name.clone()),
            });
        }
    }
    out.sort_by(|a, b| b.correlation.total_cmp(&a.correlation));
    out
}

/// Pearson correlation of two columns (the shorter length); `None` when either is constant
/// or not finite.
fn correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (ma, mb) = (mean(a), mean(b));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (x, y) = (x - ma, y - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    let c = sab / (saa * sbb).sqrt();
    c.is_finite().then_some(c)
}

impl SetPoint {
    /// The note for a free run of the position that drifts with NRMSE `drift` (in %): what
    /// was seen and the `reference` / `control` lines that close the loop.
    pub fn note(&self, drift: f64) -> String {
        let body = self
            .position
            .strip_suffix(".x")
            .unwrap_or(&self.position)
            .to_string();
        let input = self.input.as_deref().unwrap_or("u");
        // A reference is named like any signal of the language: a column with another name
        // is mapped onto it.
        let ident = |n: &str| {
            n.chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        };
        let (name, map) = if ident(&self.column) {
            (self.column.clone(), String::new())
        } else {
            let name = format!(
                "{}_ref",
                body.replace(|c: char| !c.is_ascii_alphanumeric(), "_")
            );
            let map = format!(" and give `--map {}={name}`", self.column);
            (name, map)
        };
        format!(
            "column `{col}` looks like a set point: `{pos}` follows it (correlation {c:.3}), \
             and the free run of `{pos}` driven by the recorded `{input}` drifts (NRMSE \
             {drift:.0} %). If the record was taken in closed loop, declare the set point and \
             the controller's law, so that the free runs close the loop on the recorded `{col}` \
             (docs/language.md, `reference` and `control`):\n    reference {name}\n    \
             control {input} = KP * ({name} - {pos}) - KD * {body}.v\nwith the controller's \
             gains as numbers or known parameters (`param kp = 80000`){map}.",
            col = self.column,
            pos = self.position,
            c = self.correlation,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OPEN: &str = "model axis {
        body m ~ 50
        input u on m
        measure m.x, u
        damper d (ground, m) ~ 120
    }";

    fn record(names: &[&str], columns: Vec<Vec<f64>>) -> Record {
        Record {
            names: names.iter().map(|s| s.to_string()).collect(),
            columns,
            ts: 1e-3,
            t0: 0.0,
        }
    }

    #[test]
    fn a_followed_column_is_a_set_point_and_an_unrelated_one_is_not() {
        let ir = dsl_parser::compile_str("axis", OPEN).expect("model compiles");
        let n = 2000;
        let xr: Vec<f64> = (0..n).map(|k| (k as f64 * 0.01).sin() * 0.05).collect();
        // The position lags the set point a little; `noise` is unrelated to it.
        let x: Vec<f64> = (0..n)
            .map(|k| ((k as f64 - 5.0) * 0.01).sin() * 0.05)
            .collect();
        let u: Vec<f64> = (0..n).map(|k| (k as f64 * 0.37).cos()).collect();
        let other: Vec<f64> = (0..n).map(|k| (k as f64 * 0.013).cos() * 0.05).collect();
        let rec = record(&["m.x", "u", "xr", "other"], vec![x, u, xr, other]);
        let found = set_points(&ir, &rec);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].column, "xr");
        assert_eq!(found[0].position, "m.x");
        assert_eq!(found[0].input.as_deref(), Some("u"));
        let note = found[0].note(85.0);
        assert!(note.contains("reference xr") && note.contains("control u = KP * (xr - m.x)"));
        // A model that already reads the column gets no hint.
        let closed = OPEN.replace(
            "measure m.x, u",
            "reference xr\n measure m.x, u\n control u = 1000 * (xr - m.x) - 100 * m.v",
        );
        let ir = dsl_parser::compile_str("axis", &closed).expect("model compiles");
        assert!(set_points(&ir, &rec).is_empty());
    }
}
