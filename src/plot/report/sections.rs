//! The text sections of the diagnosis report, in page order: each writes its HTML (headings,
//! tables, its figures through [`super::figure`]) onto the page.

use std::fmt::Write;

use super::signals::{spectra_fmax, spectrum_svg, trace_svg, trace_window};
use super::summary::{bars_svg, drift_svg};
use super::{esc, figure};
use dynid_runtime::diagnose::{fmt_gap, fmt_num, fmt_shrink, fmt_si, Diagnosis};

/// The page head (title and style sheet) and the title line.
pub(super) fn page_head(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>dynid diagnosis: {}</title><style>\
body{{font-family:sans-serif;max-width:1100px;margin:24px auto;padding:0 16px;color:#222}}\
h1{{font-size:26px}} h2{{font-size:20px;margin-top:32px;border-bottom:1px solid #ccc}}\
table{{border-collapse:collapse;font-size:14px}} td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}\
th{{background:#f0f0f0}} td.l,th.l{{text-align:left}} tr.acc{{background:#e6f4e6;font-weight:bold}}\
.big{{font-size:20px;padding:12px 16px;background:#f4f7fc;border-left:5px solid #193ca0}}\
.fig{{display:inline-block;margin:8px}} pre{{background:#f7f7f7;padding:10px;white-space:pre-wrap;overflow-wrap:anywhere}}\
</style></head><body>",
        esc(&d.model)
    );
    let _ = write!(
        h,
        "<h1>Sim-to-real gap of <code>{}</code></h1>",
        esc(&d.model)
    );
}

/// The one-paragraph verdict and the text summary.
pub(super) fn headline(h: &mut String, d: &Diagnosis) {
    let first = d
        .found
        .first()
        .map(|f| (f.effect.name(), f.location.label()));
    let headline = match &first {
        Some((e, l)) => format!(
            "Missing effect: <b>{}</b> at <b>{}</b>. Statistical gap (spectrum and std) on withheld levels: nominal {}, re-identified {}, corrected {}: <b>{}</b> overall, {}. Pathwise (free-run NRMSE): {} → {}.",
            esc(e),
            esc(l),
            fmt_gap(d.gap_before),
            fmt_gap(d.gap_reidentified),
            fmt_gap(d.gap_after),
            fmt_shrink(d.shrink, "of the gap removed"),
            fmt_shrink(d.effect_shrink, "of the re-identified gap removed by the effect"),
            fmt_gap(d.pathwise_gap_before),
            fmt_gap(d.pathwise_gap_after),
        ),
        _ => format!(
            "No significant unmodelled effect ({:?}). Statistical gap: nominal {}, re-identified {}; pathwise: nominal {}, re-identified {}.",
            d.verdict,
            fmt_gap(d.nominal.gap),
            fmt_gap(d.reidentified.gap),
            fmt_gap(d.nominal.pathwise),
            fmt_gap(d.reidentified.pathwise)
        ),
    };
    let _ = write!(h, "<p class=\"big\">{headline}</p>");
    let _ = write!(h, "<h2>Summary</h2><pre>{}</pre>", esc(&d.summary()));
}

/// Where the gap lies: the bar figure and the mean gaps per signal and model.
pub(super) fn gap_table(h: &mut String, d: &Diagnosis) {
    let _ = write!(h, "<h2>Where: gap per signal</h2>");
    figure(h, bars_svg(d));
    let _ = write!(
        h,
        "<table><tr><th class=\"l\">signal</th><th class=\"l\">model</th><th>statistical gap %</th><th>spectral error %</th><th>std error %</th><th>PSD gap (log10)</th><th>pathwise NRMSE %</th><th>free-run RMS error</th><th>std difference</th></tr>"
    );
    for sig in &d.response_signals {
        let models = if d.found.is_empty() {
            vec![&d.nominal, &d.reidentified]
        } else {
            vec![&d.nominal, &d.reidentified, &d.corrected]
        };
        for m in models {
            let rows: Vec<_> = m
                .levels
                .iter()
                .filter_map(|l| l.signals.iter().find(|s| &s.signal == sig))
                .collect();
            let mean = |f: fn(&dynid_runtime::diagnose::SignalGap) -> f64| {
                let v = rows.iter().map(|s| f(s)).sum::<f64>() / rows.len().max(1) as f64;
                (!rows.is_empty() && v.is_finite()).then_some(v)
            };
            let cell = |v: Option<f64>, digits: usize, sign: bool| match v {
                Some(v) if sign => format!("{v:+.digits$}"),
                Some(v) => format!("{v:.digits$}"),
                None => "–".into(),
            };
            let unit = rows.first().map_or("", |s| s.unit.as_str());
            let si = |v: Option<f64>| v.map_or("–".into(), |v| fmt_si(v, unit));
            let _ = write!(
                h,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(sig),
                esc(&m.label),
                cell(mean(|s| s.statistical), 1, false),
                cell(mean(|s| s.spectral), 1, false),
                cell(mean(|s| s.std_error), 1, true),
                cell(mean(|s| s.psd_gap), 3, false),
                cell(mean(|s| s.nrmse), 1, false),
                si(mean(|s| s.rms_error)),
                si(mean(|s| s.std_diff)),
            );
        }
    }
    let _ = write!(h, "</table>");
}

/// The covariance-equation residual of the nominal model per equation and level.
pub(super) fn equation_residuals(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<h3>Covariance-equation residual of the nominal model (%)</h3><table><tr><th class=\"l\">equation</th>"
    );
    for l in &d.levels {
        let _ = write!(h, "<th>{}</th>", esc(l));
    }
    let _ = write!(h, "</tr>");
    for e in &d.equations {
        let _ = write!(h, "<tr><td class=\"l\">{}</td>", esc(&e.equation));
        for v in &e.per_level {
            let _ = write!(
                h,
                "<td>{}</td>",
                v.map_or("–".into(), |v| format!("{v:.1}"))
            );
        }
        let _ = write!(h, "</tr>");
    }
    let _ = write!(h, "</table>");
}

/// The corrected model's parameters with their standard errors.
pub(super) fn parameters(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<h2>Parameters of the corrected model</h2><p>Identified on all levels{}; \
the values the corrected model's source holds (rounded there to five significant digits). \
Standard errors: batch-means sandwich.</p>\
<table><tr><th class=\"l\">parameter</th><th>value</th><th>standard error</th><th>nominal</th><th class=\"l\">kind</th></tr>",
        if d.found.is_empty() {
            " (the model as given: nothing was added)"
        } else {
            ", with every found effect"
        }
    );
    for p in &d.parameters {
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
            esc(&p.name),
            fmt_num(p.value),
            fmt_num(p.stderr),
            p.nominal.map_or("–".into(), fmt_num),
            p.kind
        );
    }
    let _ = write!(h, "</table>");
}

/// The per-level drift of the model's parameters: figure and table.
pub(super) fn drift(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<h2>Parameter drift over the levels</h2><p>The model as given, identified on each \
level alone (masses held at their pooled value); the figure divides each parameter by its \
value on level 1, so a steady parameter stays at 1. The pooled column is the model as given \
fitted to all levels without any found effect.</p>"
    );
    figure(h, drift_svg(d));
    let _ = write!(
        h,
        "<table><tr><th class=\"l\">parameter</th><th>nominal</th><th>pooled</th>"
    );
    for k in 0..d.levels.len() {
        let _ = write!(h, "<th>level {}</th>", k + 1);
    }
    let _ = write!(h, "<th>drift %</th><th class=\"l\">significant</th></tr>");
    for p in &d.drift {
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td>",
            esc(&p.name),
            p.nominal.map_or("–".into(), fmt_num),
            p.pooled.map_or("–".into(), fmt_num)
        );
        for ((v, e), why) in p.per_level.iter().zip(&p.stderr).zip(&p.missing) {
            let _ = write!(
                h,
                "<td>{}</td>",
                match (v, e, why) {
                    (Some(v), Some(e), _) => format!("{} ± {}", fmt_num(*v), fmt_num(*e)),
                    (_, _, Some(why)) => format!("– <small>({})</small>", esc(why)),
                    _ => "–".into(),
                }
            );
        }
        let _ = write!(
            h,
            "<td>{:.1}</td><td class=\"l\">{}</td></tr>",
            p.drift,
            if p.significant { "yes" } else { "no" }
        );
    }
    let _ = write!(h, "</table>");
}

/// The spectra and time traces of the level where the nominal model misses most.
pub(super) fn spectra_and_traces(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<h2>Spectra before and after</h2><p>On the level where the nominal model misses most. The re-identified and corrected models are the ones fitted on the other levels (this level withheld), as they are scored.</p>"
    );
    let fmax = spectra_fmax(&d.spectra);
    for sp in &d.spectra {
        let unit = d
            .traces
            .iter()
            .find(|t| t.signal == sp.signal)
            .map_or("", |t| t.unit.as_str());
        figure(h, spectrum_svg(sp, fmax, unit));
    }

    let _ = write!(
        h,
        "<h2>Time traces</h2><p>The level of the spectra: measured and free runs (from the measured initial state, driven by the measured inputs) over the whole record, zoomed on a window of two dominant periods (at most a third of the record) around the largest nominal error, and the free-run error there in the signal's unit.</p>"
    );
    for tr in &d.traces {
        if tr.measured.is_empty() {
            continue;
        }
        let n = tr.measured.len();
        figure(h, trace_svg(tr, (0, n), false));
        let w = trace_window(tr);
        if w != (0, n) {
            figure(h, trace_svg(tr, w, false));
        }
        figure(h, trace_svg(tr, w, true));
    }
}

/// The ranking of the first search step's candidates.
pub(super) fn ranking(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<h2>Candidate ranking (first search step)</h2><p>Each candidate is fitted on all levels but one and scored on the withheld one (rotated). The free-run gaps (statistical and pathwise) are computed for the best admissible candidates by covariance score.</p>\
<table><tr><th>#</th><th class=\"l\">effect</th><th class=\"l\">location</th><th>coefficient</th><th>|p|/σ</th><th>CV cov. residual %</th><th>CV statistical gap</th><th>CV pathwise gap</th><th class=\"l\">note</th></tr>"
    );
    for (i, c) in d.ranking.iter().enumerate() {
        let _ = write!(
            h,
            "<tr{}><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{:.1}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
            if c.accepted { " class=\"acc\"" } else { "" },
            i + 1,
            esc(&c.effect.name()),
            esc(&c.location.label()),
            if c.value.is_finite() {
                format!("{} ± {}", fmt_num(c.value), fmt_num(c.stderr))
            } else {
                "–".into()
            },
            c.t_ratio,
            if c.cv_residual.is_finite() {
                format!("{:.2}", c.cv_residual)
            } else {
                "–".into()
            },
            c.gap.map_or("".into(), fmt_gap),
            c.pathwise_gap.map_or("".into(), fmt_gap),
            esc(&c.note)
        );
    }
    let _ = write!(h, "</table>");
}

/// The corrected model's source, and the end of the page.
pub(super) fn corrected_model(h: &mut String, d: &Diagnosis) {
    let _ = write!(
        h,
        "<h2>Corrected model</h2><pre>{}</pre></body></html>",
        esc(&d.fixed_source)
    );
}
