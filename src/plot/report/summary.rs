//! The figures of the whole diagnosis: the statistical gap per signal and model (bars), and
//! the per-level drift of the model's parameters.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{legend_and_present, COLORS};
use dynid_runtime::diagnose::{Diagnosis, ModelGap, ParamDrift};

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

/// One chart, built in plotters' order (area, mesh, series, legend); longer than most
/// functions here because each step is a call chain of its own, and split apart they would
/// pass the chart's typed context along.
pub(super) fn bars_svg(d: &Diagnosis) -> Result<String, String> {
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
fn drift_reference(p: &ParamDrift) -> Option<(usize, f64)> {
    p.per_level
        .iter()
        .enumerate()
        .find_map(|(k, v)| v.filter(|v| *v != 0.0 && v.is_finite()).map(|v| (k, v)))
}

/// One chart, built in plotters' order (area, mesh, series, legend); longer than most
/// functions here because each step is a call chain of its own, and split apart they would
/// pass the chart's typed context along.
pub(super) fn drift_svg(d: &Diagnosis) -> Result<String, String> {
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
