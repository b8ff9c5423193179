//! The HTML report of a diagnosis: one self-contained page (inline SVG figures drawn with
//! plotters, inline CSS, no scripts), so that it opens offline and can be mailed around.

use std::fmt::Write;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::register_font;
use dynid_runtime::diagnose::{
    fmt_gap, fmt_num, fmt_shrink, fmt_si, Diagnosis, ModelGap, Spectrum, Trace,
};

/// Line and bar colours, distinct on a white page and for the common colour-vision
/// deficiencies (no yellow: it vanishes on white).
const COLORS: [RGBColor; 8] = [
    RGBColor(25, 60, 160),
    RGBColor(200, 30, 45),
    RGBColor(20, 140, 60),
    RGBColor(215, 110, 0),
    RGBColor(120, 50, 160),
    RGBColor(0, 140, 160),
    RGBColor(140, 90, 40),
    RGBColor(90, 90, 90),
];

/// The measured signal under the models' lines: a wide grey band, so a model that matches
/// it draws inside the band instead of hiding it.
const MEASURED: RGBColor = RGBColor(175, 175, 175);

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Mean statistical gap (%) of one signal over the levels of a model's gap.
fn signal_mean(g: &ModelGap, sig: &str) -> f64 {
    let v: Vec<f64> = g
        .levels
        .iter()
        .filter_map(|l| l.signals.iter().find(|s| s.signal == sig))
        .map(|s| s.statistical)
        .collect();
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn bars_svg(d: &Diagnosis) -> Result<String, String> {
    let models: Vec<&ModelGap> = if d.found.is_empty() {
        vec![&d.nominal, &d.reidentified]
    } else {
        vec![&d.nominal, &d.reidentified, &d.corrected]
    };
    let sigs = &d.response_signals;
    let vals: Vec<Vec<f64>> = models
        .iter()
        .map(|m| sigs.iter().map(|s| signal_mean(m, s)).collect())
        .collect();
    let top = vals
        .iter()
        .flatten()
        .filter(|v| v.is_finite())
        .fold(1.0f64, |a, b| a.max(*b));
    // Headroom above the tallest bar for the value labels and the legend (one row per model).
    let ymax = top * (1.25 + 0.12 * models.len() as f64);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 380)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let n = sigs.len() as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Statistical gap per signal on the withheld levels (spectrum and std)",
                ("sans-serif", 19),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..n, 0.0..ymax)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(sigs.len() * 2 + 1)
            .x_label_formatter(&|x| {
                let k = x.floor() as usize;
                if (x - k as f64 - 0.5).abs() < 0.26 && k < sigs.len() {
                    sigs[k].clone()
                } else {
                    String::new()
                }
            })
            .x_desc("response signal")
            .y_desc("statistical gap (%)")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(|e| e.to_string())?;
        let w = 0.8 / models.len() as f64;
        // A bar of 0 % is still drawn: an outline one pixel-row high and its label.
        let min_h = ymax * 0.004;
        for (mi, m) in models.iter().enumerate() {
            let color = COLORS[mi % COLORS.len()];
            let bar = |k: usize, v: f64| {
                let x0 = k as f64 + 0.1 + mi as f64 * w;
                let v = if v.is_finite() { v } else { top };
                (x0, x0 + w * 0.92, v.max(min_h))
            };
            chart
                .draw_series(vals[mi].iter().enumerate().map(|(k, &v)| {
                    let (x0, x1, h) = bar(k, v);
                    Rectangle::new([(x0, 0.0), (x1, h)], color.filled())
                }))
                .map_err(|e| e.to_string())?
                .label(m.label.clone())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled())
                });
            chart
                .draw_series(vals[mi].iter().enumerate().map(|(k, &v)| {
                    let (x0, x1, h) = bar(k, v);
                    let text = if v.is_finite() {
                        format!("{v:.1}")
                    } else {
                        "diverged".into()
                    };
                    Text::new(
                        text,
                        (0.5 * (x0 + x1), h + 0.01 * ymax),
                        ("sans-serif", 13)
                            .into_font()
                            .color(&BLACK)
                            .pos(Pos::new(HPos::Center, VPos::Bottom)),
                    )
                }))
                .map_err(|e| e.to_string())?;
        }
        legend_and_present(&mut chart, &root, 14)?;
    }
    Ok(svg)
}

/// The value a parameter's per-level values are divided by in the drift figure: its value
/// on the first level that has one (a steady parameter then stays at 1; the pooled value
/// would place every steady one off 1 whenever another parameter drifts).
fn drift_reference(p: &dynid_runtime::diagnose::ParamDrift) -> Option<(usize, f64)> {
    p.per_level
        .iter()
        .enumerate()
        .find_map(|(k, v)| v.filter(|v| *v != 0.0 && v.is_finite()).map(|v| (k, v)))
}

fn drift_svg(d: &Diagnosis) -> Result<String, String> {
    let n = d.levels.len();
    // (name, [(level, value / reference, stderr / reference)]) per parameter.
    type Points = Vec<(f64, f64, f64)>;
    let series: Vec<(String, Points)> = d
        .drift
        .iter()
        .filter_map(|p| {
            let (_, r) = drift_reference(p)?;
            let pts: Points = p
                .per_level
                .iter()
                .zip(&p.stderr)
                .enumerate()
                .filter_map(|(k, (v, e))| {
                    let e = e.filter(|e| e.is_finite()).unwrap_or(0.0);
                    v.map(|v| ((k + 1) as f64, v / r, (e / r).abs()))
                })
                .collect();
            Some((p.name.clone(), pts))
        })
        .collect();
    let (lo, hi) = series
        .iter()
        .flat_map(|s| s.1.iter().flat_map(|p| [p.1 - p.2, p.1 + p.2]))
        .filter(|y| y.is_finite())
        .fold((0.9f64, 1.1f64), |(a, b), y| (a.min(y), b.max(y)));
    // Room above for the legend, one row per parameter.
    let span = hi - lo;
    let top = hi + span * (0.08 + 0.07 * series.len() as f64);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 400)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Per-level identification of the model as given",
                ("sans-serif", 19),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.6..n as f64 + 0.4, (lo - 0.05 * span)..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_labels(n)
            .x_label_formatter(&|x| {
                if (x - x.round()).abs() < 1e-6 {
                    format!("level {}", x.round())
                } else {
                    String::new()
                }
            })
            .y_desc("value / value on level 1 (± 1 SE)")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, (name, pts)) in series.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            // Side by side within a level, so error bars of equal values do not overlap.
            let dx = 0.04 * (i as f64 - 0.5 * (series.len() as f64 - 1.0));
            chart
                .draw_series(LineSeries::new(
                    pts.iter().map(|p| (p.0 + dx, p.1)),
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 14, y)], color.stroke_width(2))
                });
            chart
                .draw_series(pts.iter().map(|p| {
                    ErrorBar::new_vertical(
                        p.0 + dx,
                        p.1 - p.2,
                        p.1,
                        p.1 + p.2,
                        color.stroke_width(2),
                        8,
                    )
                }))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(
                    pts.iter()
                        .map(|p| Circle::new((p.0 + dx, p.1), 4, color.filled())),
                )
                .map_err(|e| e.to_string())?;
        }
        legend_and_present(&mut chart, &root, 14)?;
    }
    Ok(svg)
}

/// Index of the bin up to which a spectrum is drawn: 1.5 × the frequency below which
/// 99.9 % of the measured power lies.
fn spectrum_last_bin(sp: &Spectrum) -> usize {
    let total: f64 = sp.measured.iter().skip(1).sum();
    let mut acc = 0.0;
    for (k, p) in sp.measured.iter().enumerate().skip(1) {
        acc += p;
        if acc >= 0.999 * total {
            return (k * 3 / 2).min(sp.measured.len() - 1);
        }
    }
    sp.measured.len().saturating_sub(1)
}

/// One frequency range for every spectrum of a report (Hz): the widest of their ranges.
fn spectra_fmax(spectra: &[Spectrum]) -> f64 {
    spectra
        .iter()
        .filter(|sp| sp.measured.len() > 1)
        .map(|sp| sp.freqs[spectrum_last_bin(sp)])
        .fold(0.0, f64::max)
}

fn spectrum_svg(sp: &Spectrum, fmax: f64, unit: &str) -> Result<String, String> {
    if sp.measured.len() < 2 {
        return Err("the spectrum has no bins".into());
    }
    let last = sp
        .freqs
        .iter()
        .rposition(|f| *f <= fmax)
        .unwrap_or(sp.freqs.len() - 1)
        .max(1);
    let floor = 1e-14 * sp.measured.iter().cloned().fold(0.0, f64::max);
    let lg = |v: f64| (v + floor).log10();
    let mut all: Vec<(String, Vec<(f64, f64)>)> = vec![(
        "measured".into(),
        (1..=last)
            .map(|k| (sp.freqs[k], lg(sp.measured[k])))
            .collect(),
    )];
    for (name, p) in &sp.models {
        all.push((
            name.clone(),
            (1..=last).map(|k| (sp.freqs[k], lg(p[k]))).collect(),
        ));
    }
    let (ylo, yhi) = all
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
    if !(ylo.is_finite() && yhi.is_finite()) {
        return Err("no finite values to draw".into());
    }
    // Room above for the legend (one row per line).
    let top = yhi + 0.3 + 0.1 * (yhi - ylo) * all.len() as f64;
    let psd_unit = match unit {
        "" => "1/Hz".to_string(),
        u if u.contains('/') => format!("({u})²/Hz"),
        u => format!("{u}²/Hz"),
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (520, 360)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("PSD of {} (level {})", sp.signal, sp.level + 1),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..sp.freqs[last], (ylo - 0.3)..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("frequency (Hz)")
            .y_desc(format!("log10 PSD ({psd_unit})"))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, (name, pts)) in all.iter().enumerate() {
            let (color, width) = if i == 0 {
                (MEASURED, 6)
            } else {
                (COLORS[i % COLORS.len()], 2)
            };
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(width)))
                .map_err(|e| e.to_string())?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 14, y)], color.stroke_width(width.min(4)))
                });
        }
        legend_and_present(&mut chart, &root, 13)?;
    }
    Ok(svg)
}

/// Most points of one drawn series: longer series are cut into buckets, each drawn as its
/// minimum and maximum (the envelope a denser plot would show).
const TRACE_POINTS: usize = 1500;

/// `(t, x)` of `x[a..b]` (sample `k` at `t0 + k·ts`), at most [`TRACE_POINTS`] points.
fn envelope(x: &[f64], t0: f64, ts: f64, a: usize, b: usize, scale: f64) -> Vec<(f64, f64)> {
    let n = b.saturating_sub(a);
    let half = TRACE_POINTS / 2;
    if n <= TRACE_POINTS {
        return (a..b).map(|k| (t0 + k as f64 * ts, x[k] * scale)).collect();
    }
    let mut out = Vec::with_capacity(2 * half);
    for j in 0..half {
        let (lo, hi) = (a + j * n / half, a + (j + 1) * n / half);
        let (mut kmin, mut kmax) = (lo, lo);
        for k in lo..hi {
            if x[k] < x[kmin] {
                kmin = k;
            }
            if x[k] > x[kmax] {
                kmax = k;
            }
        }
        let (k1, k2) = (kmin.min(kmax), kmin.max(kmax));
        out.push((t0 + k1 as f64 * ts, x[k1] * scale));
        out.push((t0 + k2 as f64 * ts, x[k2] * scale));
    }
    out
}

/// The window of a trace to zoom into: two dominant periods of the measured signal (from
/// its mean-crossing rate), at most a third of the record and at least 200 samples,
/// centred where the nominal model's free run is farthest from the measurement.
fn trace_window(tr: &Trace) -> (usize, usize) {
    let x = &tr.measured;
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n.max(1) as f64;
    let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n.max(1) as f64).sqrt();
    let (mut side, mut crossings) = (0i8, 0usize);
    for &v in x {
        let now = if v > mean + 0.05 * sd {
            1
        } else if v < mean - 0.05 * sd {
            -1
        } else {
            0
        };
        if now != 0 && now != side {
            crossings += usize::from(side != 0);
            side = now;
        }
    }
    let len = if crossings >= 2 {
        (2.0 * 2.0 * n as f64 / crossings as f64) as usize
    } else {
        n
    }
    .min(n / 3)
    .max(200.min(n));
    let worst = tr.models.first().map_or(0, |(_, y)| {
        (0..n.min(y.len()))
            .max_by(|&a, &b| (y[a] - x[a]).abs().total_cmp(&(y[b] - x[b]).abs()))
            .unwrap_or(0)
    });
    let a = worst.saturating_sub(len / 2).min(n - len);
    (a, a + len)
}

/// The SI prefix (scale and unit) that suits values up to `peak` in `unit`.
fn scaled_unit(peak: f64, unit: &str) -> (f64, String) {
    let text = fmt_si(peak, unit);
    let shown = text.split(' ').nth(1).unwrap_or(unit).to_string();
    let prefix = shown.strip_suffix(unit).unwrap_or("");
    let scale = match prefix {
        "M" => 1e-6,
        "k" => 1e-3,
        "m" => 1e3,
        "µ" => 1e6,
        "n" => 1e9,
        _ => 1.0,
    };
    (scale, shown)
}

/// One panel of a trace: the measured signal and the models' free runs over samples
/// `a..b` (`error`: each model minus the measurement instead).
fn trace_svg(tr: &Trace, (a, b): (usize, usize), error: bool) -> Result<String, String> {
    let x = &tr.measured;
    let series: Vec<(String, Vec<f64>)> = if error {
        tr.models
            .iter()
            .map(|(name, y)| {
                let e = y.iter().zip(x).map(|(y, x)| y - x).collect();
                (format!("{name} − measured"), e)
            })
            .collect()
    } else {
        std::iter::once(("measured".to_string(), x.clone()))
            .chain(tr.models.iter().cloned())
            .collect()
    };
    let peak = series
        .iter()
        .flat_map(|(_, v)| v[a..b].iter())
        .filter(|v| v.is_finite())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let (scale, unit) = scaled_unit(peak, &tr.unit);
    let pts: Vec<(String, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(name, v)| (name.clone(), envelope(v, tr.t0, tr.ts, a, b, scale)))
        .collect();
    let (ylo, yhi) = pts
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), y| {
            (l.min(y), h.max(y))
        });
    if !(ylo.is_finite() && yhi.is_finite()) {
        return Err("no finite values to draw".into());
    }
    let pad = 0.05 * (yhi - ylo).max(1e-12);
    // Room above the curves for the legend (one row per series).
    let legend_room = 0.085 * (yhi - ylo).max(1e-12) * pts.len() as f64;
    let (t_a, t_b) = (
        tr.t0 + a as f64 * tr.ts,
        tr.t0 + (b - 1).max(a + 1) as f64 * tr.ts,
    );
    let title = match (error, a == 0 && b == x.len()) {
        (true, _) => format!("Free-run error of {} (level {})", tr.signal, tr.level + 1),
        (false, true) => format!("{} (level {}), whole record", tr.signal, tr.level + 1),
        (false, false) => format!("{} (level {}), zoomed", tr.signal, tr.level + 1),
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (520, 320)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 17))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(60)
            .build_cartesian_2d(t_a..t_b, (ylo - pad)..(yhi + pad + legend_room))
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(if unit.is_empty() {
                tr.signal.clone()
            } else {
                format!("{} ({unit})", tr.signal)
            })
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, (name, p)) in pts.iter().enumerate() {
            let (color, width) = match (error, i) {
                (false, 0) => (MEASURED, 5),
                (false, i) => (COLORS[i % COLORS.len()], 1),
                (true, i) => (COLORS[(i + 1) % COLORS.len()], 1),
            };
            chart
                .draw_series(LineSeries::new(p.clone(), color.stroke_width(width)))
                .map_err(|e| e.to_string())?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 14, y)], color.stroke_width(2))
                });
        }
        legend_and_present(&mut chart, &root, 12)?;
    }
    Ok(svg)
}

/// Draws the series legend in the upper right corner and writes the figure out.
fn legend_and_present<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    root: &DrawingArea<DB, plotters::coord::Shift>,
    font_size: u32,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    CT: plotters::coord::CoordTranslate,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", font_size))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

fn figure(out: &mut String, svg: Result<String, String>) {
    match svg {
        Ok(s) => {
            let _ = write!(out, "<div class=\"fig\">{s}</div>");
        }
        Err(e) => {
            let _ = write!(out, "<p class=\"err\">figure not drawn: {}</p>", esc(&e));
        }
    }
}

/// A self-contained HTML page (inline SVG and CSS, no scripts).
pub fn render_html(d: &Diagnosis) -> String {
    register_font();
    let mut h = String::new();
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

    let _ = write!(h, "<h2>Where: gap per signal</h2>");
    figure(&mut h, bars_svg(d));
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

    let _ = write!(
        h,
        "<h2>Parameter drift over the levels</h2><p>The model as given, identified on each \
level alone (masses held at their pooled value); the figure divides each parameter by its \
value on level 1, so a steady parameter stays at 1. The pooled column is the model as given \
fitted to all levels without any found effect.</p>"
    );
    figure(&mut h, drift_svg(d));
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
        figure(&mut h, spectrum_svg(sp, fmax, unit));
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
        figure(&mut h, trace_svg(tr, (0, n), false));
        let w = trace_window(tr);
        if w != (0, n) {
            figure(&mut h, trace_svg(tr, w, false));
        }
        figure(&mut h, trace_svg(tr, w, true));
    }

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
    let _ = write!(
        h,
        "<h2>Corrected model</h2><pre>{}</pre></body></html>",
        esc(&d.fixed_source)
    );
    h
}

/// The report's section of the frequency response per level (inline SVG, see
/// [`super::frf`]); a figure that cannot be drawn is said so in its place.
pub fn frf_section(frfs: &[dynid_runtime::frf::LevelFrf]) -> String {
    let fig = match super::frf::frf_svg_strings(frfs) {
        Ok(svgs) => svgs
            .iter()
            .map(|svg| format!("<div class=\"fig\">{svg}</div>"))
            .collect(),
        Err(e) => format!("<p>The figure could not be drawn: {}</p>", esc(&e)),
    };
    let method = match frfs.first().map(|f| f.measured.method) {
        Some(dynid_runtime::frf::FrfMethod::Periodic { period }) => format!(
            "averaged over whole periods of {period} samples at the excited lines"
        ),
        Some(dynid_runtime::frf::FrfMethod::Welch { segment }) => format!(
            "H1 = S<sub>uy</sub>/S<sub>uu</sub> over Hann-windowed segments of {segment} samples, 50 % overlap"
        ),
        None => String::new(),
    };
    format!(
        "<h2>Frequency response per level</h2><p>Measured ({method}; coherence below) \
         and the linear part of the model with the parameters identified at each level \
         (dashed, H(jω) = −(−ω²M + jωD + K)<sup>−1</sup>B). A peak that moves or broadens \
         with the level is a nonlinearity; a model curve that misses the measured one at \
         every level is a linear modelling error.</p>{fig}"
    )
}
