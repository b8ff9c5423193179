//! The report of `dynid identify` on the terminal: equations, parameter table,
//! diagnostics, and the refinement's table.

use super::RefineReport;
use dsl_parser::ir::ModelIr;
use dynid_runtime::ident::{print, Identification};
use dynid_runtime::refine;

/// Both estimates side by side, and their free-run errors.
pub fn render_refined(rep: &RefineReport) -> String {
    let r = &rep.refinement;
    let mut s = format!(
        "\noutput-error refinement: {} iterations ({}), {} sub-records, {} samples, \
         mean-square weighted error {:.3e} -> {:.3e}\n",
        r.iterations,
        if r.converged {
            "converged"
        } else {
            "iteration limit"
        },
        r.segments,
        r.samples,
        r.cost_start,
        r.cost_end
    );
    if let Some(note) = &r.note {
        s.push_str(&format!("refinement {note}\n"));
    }
    s.push_str(&format!(
        "{:<12} {:>14} {:>14} {:>12} {:>9}\n",
        "parameter", "covariance", "refined", "std. error", "change"
    ));
    for p in &r.params {
        let change = if p.start != 0.0 {
            format!("{:>+8.2}%", 100.0 * (p.value / p.start - 1.0))
        } else {
            format!("{:>9}", "-")
        };
        s.push_str(&format!(
            "{:<12} {:>14} {:>14} {:>12} {change}\n",
            p.name,
            print::fmt_num(p.start),
            print::fmt_num(p.value),
            print::fmt_num(p.stderr),
        ));
    }
    s.push_str(
        "(std. error of the refined values from the final Jacobian, white residuals assumed: \
         a lower bound)\n",
    );
    s.push_str(&format!(
        "\n{:<28} {:>14} {:>14}\n",
        "free-run RMS error", "covariance", "refined"
    ));
    for (what, (cov, refd)) in [("estimation", &rep.estimation), ("test", &rep.test)] {
        for (c, f) in cov.iter().zip(refd) {
            s.push_str(&format!(
                "{:<28} {:>14} {:>14}   ({:.2}% -> {:.2}% of the signal std)\n",
                format!("{what} {}", c.signal),
                print::fmt_num(c.rms),
                print::fmt_num(f.rms),
                100.0 * c.relative,
                100.0 * f.relative
            ));
        }
    }
    s.push_str(&format!(
        "(each record driven by its inputs from its {})\n",
        refine::FREE_RUN_START
    ));
    s
}

/// Human-readable report: equations, parameter table, diagnostics.
pub fn render(ir: &ModelIr, id: &Identification) -> String {
    let mut s = print::format_equations(ir, id);
    s.push('\n');
    s.push_str(&format!(
        "{:<12} {:>14} {:>12} {:>9}\n",
        "parameter", "value", "std. error", "rel."
    ));
    for p in &id.params {
        let rel = if p.value != 0.0 {
            format!("{:>8.2}%", 100.0 * p.stderr / p.value.abs())
        } else {
            format!("{:>9}", "-")
        };
        s.push_str(&format!(
            "{:<12} {:>14} {:>12} {rel}{}\n",
            p.name,
            print::fmt_num(p.value),
            print::fmt_num(p.stderr),
            if p.significant { "" } else { "  (n.s.)" }
        ));
    }
    for sh in &id.shapes {
        let (se, rel) = match sh.stderr {
            Some(e) if sh.value != 0.0 => (
                print::fmt_num(e),
                format!("{:>8.2}%", 100.0 * e / sh.value.abs()),
            ),
            Some(e) => (print::fmt_num(e), format!("{:>9}", "-")),
            None => ("–".to_string(), format!("{:>9}", "-")),
        };
        s.push_str(&format!(
            "{:<12} {:>14} {:>12} {rel}  (shape, profiled)\n",
            sh.name,
            print::fmt_num(sh.value),
            se
        ));
    }
    if id.params.iter().any(|p| !p.significant) {
        s.push_str(&format!(
            "(n.s.): not significant, |value| ≤ {} std. errors — kept in the fit; the data \
             do not show the term\n",
            dynid_runtime::ident::SIGNIFICANCE_T
        ));
    }
    for u in &id.unidentifiable {
        s.push_str(&format!("{:<12} not identifiable: {}\n", u.name, u.reason));
    }
    s.push_str(&format!(
        "\ncondition {:.3e}, {} rows, filter corners {} rad/s\n",
        id.condition,
        id.rows,
        id.filter
            .corners
            .iter()
            .map(|c| print::fmt_num(*c))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    s.push_str(&format!(
        "corners chosen by: {}\n",
        id.filter.describe_corners()
    ));
    if id.filter.auto_rows && id.filter.weighted_rows {
        s.push_str(&format!(
            "rows: the instrument rows, each weighted by its own estimated error ({}), \
             chosen for this record (measured accelerations, where the unit-norm rows shrink \
             the estimates; --instrument-rows for those)\n",
            id.filter.describe_weighting(),
        ));
    } else if id.filter.weighted_rows {
        s.push_str(&format!(
            "rows: weighted by their estimated covariance ({})\n",
            id.filter.describe_weighting()
        ));
    } else if id.filter.auto_rows {
        s.push_str(
            "rows: the filtered equation with the input's delay, chosen for this record \
             (friction with a sign of a velocity, a measured force, velocities estimated from \
             positions with no noise worth a correction: a servo axis's record, where they are \
             far more precise than the instrument rows; --instrument-rows for those)\n",
        );
    }
    for r in &id.residual {
        let lv: Vec<String> = r.per_level.iter().map(|v| format!("{v:.2e}")).collect();
        let noise: Vec<String> = r.noise.iter().map(|v| format!("{v:.2e}")).collect();
        let alone = if noise.is_empty() {
            String::new()
        } else {
            format!(" (noise alone {})", noise.join(" / "))
        };
        s.push_str(&format!(
            "residual {}: {}{alone}\n",
            r.equation,
            lv.join(" / ")
        ));
    }
    for e in &id.estimated {
        if e.method != dynid_runtime::ident::velocity::METHOD {
            // Integrated from an acceleration: the high-pass corner, or over whole periods
            // the lowest line kept (0 in moment files that predate it: "exact").
            let cut: Vec<String> = e
                .cutoff
                .iter()
                .map(|&c| {
                    if c > 0.0 {
                        print::fmt_num(c)
                    } else {
                        "exact".into()
                    }
                })
                .collect();
            // Over whole periods: the lowest line each kept; levels of both kinds: either.
            let periodic = dynid_runtime::ident::integrate::METHOD_PERIODIC;
            let what = if e.method.starts_with(periodic) {
                "lowest line kept"
            } else if e.method.contains(periodic) {
                "corner or, over whole periods, lowest line kept"
            } else {
                "corner"
            };
            s.push_str(&format!(
                "{} integrated from {} ({}; {what} {} rad/s per level)\n",
                e.signal,
                e.from,
                e.method,
                cut.join(" / ")
            ));
            continue;
        }
        let cut: Vec<String> = e.cutoff.iter().map(|c| print::fmt_num(*c)).collect();
        s.push_str(&format!(
            "velocity {} estimated from {} (zero-phase differentiator, cutoff {} rad/s per level)\n",
            e.signal,
            e.from,
            cut.join(" / ")
        ));
    }
    s.push_str(&rest_line(id));
    s.push_str(&noise_line(&id.noise, id.filter.corners_from.filtered));
    s
}

/// One line where rests were left out: how many, per level, and the speed below which a
/// body counted as standing still (on the first level that has rests). Nothing where no
/// level has one.
fn rest_line(id: &dynid_runtime::ident::Identification) -> String {
    let found: Vec<&dynid_runtime::ident::RestSummary> = id
        .levels
        .iter()
        .filter_map(|l| l.rests.as_ref())
        .filter(|r| r.intervals > 0)
        .collect();
    let Some(first) = found.first() else {
        return String::new();
    };
    let per_level: Vec<String> = id
        .levels
        .iter()
        .map(|l| match &l.rests {
            Some(r) => format!(
                "{} ({} samples, {:.0}%)",
                r.intervals,
                r.samples,
                100.0 * r.samples as f64 / l.samples.max(1) as f64
            ),
            None => "-".into(),
        })
        .collect();
    let thr: Vec<String> = first
        .threshold
        .iter()
        .map(|(b, t)| format!("{b} {} m/s", print::fmt_num(*t)))
        .collect();
    if id.filter.corners_from.filtered {
        return format!(
            "slow passages left out of the filtered equation, each with the filter's memory \
             after it (at rest a Coulomb force is anywhere within its bound, at a reversal \
             the filtered sign carries the velocity estimate's timing): {} per level; slow: \
             speed below {} % of the RMS ({}), any length (--keep-rests keeps them)\n",
            per_level.join(" / "),
            100.0 * dynid_runtime::ident::rests::REST_FRACTION,
            thr.join(", "),
        );
    }
    format!(
        "rests left out of the moments (at rest a Coulomb force is anywhere within its bound): {} \
         per level; at rest: speed below {} % of the RMS ({}) for at \
         least {} ms (--keep-rests keeps them)\n",
        per_level.join(" / "),
        100.0 * dynid_runtime::ident::rests::REST_FRACTION,
        thr.join(", "),
        1e3 * dynid_runtime::ident::rests::MIN_REST
    )
}

/// One line: the estimated noise per signal and what was done about it (`filtered`: the rows
/// of the filtered equation, which correct no nonlinear term, say so).
fn noise_line(n: &dynid_runtime::ident::NoiseSummary, filtered: bool) -> String {
    let levels: Vec<String> = n
        .fraction
        .iter()
        .map(|(sig, f)| format!("{sig} {:.1}%", 100.0 * f))
        .collect();
    let mut s = format!(
        "measurement noise (estimated std / signal std, largest level): {}",
        levels.join(", ")
    );
    if !n.uncertain.is_empty() {
        s.push_str(&format!(
            " (uncertain, floor dominated by the signal: {})",
            n.uncertain.join(", ")
        ));
    }
    if !n.corrected.is_empty() {
        s.push_str(&format!("; de-biased: {}", n.corrected.join(", ")));
    }
    if !n.uncorrected.is_empty() {
        s.push_str(&format!(
            "; {}: {}",
            if n.enabled {
                "no correction for"
            } else {
                "correction off, biased"
            },
            n.uncorrected.join(", ")
        ));
        if n.enabled && filtered {
            s.push_str(
                " (the rows of the filtered equation correct no nonlinear term for noise; \
                 the instrument rows, the default, do)",
            );
        }
    }
    s.push('\n');
    s
}
