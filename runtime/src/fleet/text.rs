//! The fleet's view as text: the fleet's model, the flagged machines with what moved, the
//! machines not tested (what `dynid fleet` prints and Python's `Fleet` shows).

use super::{FleetView, MachineParam, Status};
use dynid_ir::num::sig;

impl FleetView {
    /// The text report: the fleet's model, the flagged machines with what moved, the machines
    /// not tested, and a count of the rest.
    pub fn table(&self) -> String {
        let v = self;
        let mut out = String::new();
        let line = |out: &mut String, s: String| {
            out.push_str(&s);
            out.push('\n');
        };
        line(
        &mut out,
        format!(
            "Fleet of {} machine(s): {} tested, {} consistent, {} flagged (family-wise α = {}: d² > {} for {} parameters)",
            v.machines.len(),
            v.tested,
            v.held,
            v.flagged().count(),
            sig(v.alpha, 3, false),
            sig(v.critical_d2, 3, false),
            v.params.len()
        ),
    );
        line(&mut out, String::new());
        line(
            &mut out,
            format!(
                "  {:<12} {:>12} {:>10} {:>22} {:>12}",
                "parameter", "fleet", "± (mean)", "between machines", "within"
            ),
        );
        for p in &v.params {
            let rel = if p.value != 0.0 {
                format!(" ({} %)", sig(100.0 * p.spread / p.value.abs(), 2, false))
            } else {
                String::new()
            };
            line(
                &mut out,
                format!(
                    "  {:<12} {:>12} {:>10} {:>22} {:>12}",
                    p.name,
                    sig(p.value, 4, false),
                    sig(p.stderr, 2, false),
                    format!("{}{rel}", sig(p.spread, 2, false)),
                    sig(p.within, 2, false)
                ),
            );
        }
        if v.between_clipped > 0 {
            line(
            &mut out,
            format!(
                "  ({} direction(s) without between-machine spread: the machines scatter there no more than their own errors)",
                v.between_clipped
            ),
        );
        }
        if let Some(n) = v.alternated {
            line(&mut out, String::new());
            line(
                &mut out,
                format!(
                    "  warning: the set of consistent machines did not settle in {} round(s): it alternated between {n} sets, and the fleet's model rests on the machines held in all of them — look at the machines near the limit",
                    v.rounds
                ),
            );
        }
        let flagged: Vec<_> = v.flagged().collect();
        if !flagged.is_empty() {
            line(&mut out, String::new());
            line(&mut out, "Flagged (inconsistent with the fleet):".into());
        }
        for m in flagged {
            let t = m
                .test
                .as_ref()
                .expect("invariant: a flagged machine was tested");
            let p = if t.p_value > 0.0 {
                format!("p = {}", sig(t.p_value, 2, false))
            } else {
                "p < 1e-300".into()
            };
            let moved: Vec<String> = m.moved.iter().map(describe).collect();
            line(
                &mut out,
                format!(
                    "  {:<12} d² = {} ({} dof, {p}): {}",
                    m.name,
                    sig(t.d2, 4, false),
                    t.dof,
                    moved.join(", ")
                ),
            );
        }
        let untested: Vec<_> = v
            .machines
            .iter()
            .filter(|m| matches!(m.status, Status::Failed | Status::RankDeficient))
            .collect();
        if !untested.is_empty() {
            line(&mut out, String::new());
            line(&mut out, "Not tested:".into());
        }
        for m in untested {
            line(
                &mut out,
                format!("  {:<12} {}", m.name, m.note.as_deref().unwrap_or("")),
            );
        }
        let notes: Vec<_> = v
            .machines
            .iter()
            .filter(|m| m.test.is_some() && m.note.is_some())
            .collect();
        for m in notes {
            line(
                &mut out,
                format!("  {:<12} {}", m.name, m.note.as_deref().unwrap_or("")),
            );
        }
        out
    }
}

/// `fv 2.03× fleet (+41 σ)`.
fn describe(p: &MachineParam) -> String {
    let ratio = p
        .ratio
        .map_or(String::new(), |r| format!(" {}× fleet", sig(r, 3, true)));
    format!("{}{ratio} ({:+.0} σ)", p.name, p.z)
}
