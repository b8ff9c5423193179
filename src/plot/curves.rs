//! Figures of the detection curves: one panel per parameter curve with the per-level
//! estimates and their error bars over the element's intensity (log axis: the levels are
//! usually spaced by factors), the constant fit, and the best templates of the element.
//!
//! The PNG back end rasterises text with the embedded font (see [`super`]).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{register_font, PlotError};
use crate::output::Staged;
use dsl_parser::num;
use dynid_runtime::detect::{
    fmt_g, fmt_pm, Detection, ParamCurveResult, Role, TemplateFit, Verdict,
};

const PANEL_W: u32 = 760;
const PANEL_H: u32 = 430;
/// How many of an element's best templates are drawn.
const N_TEMPLATES: usize = 3;

const TEMPLATE_COLORS: [RGBColor; N_TEMPLATES] = [
    RGBColor(200, 30, 45),
    RGBColor(20, 140, 60),
    RGBColor(230, 140, 0),
];
const POINT_COLOR: RGBColor = RGBColor(25, 60, 160);

/// Write the figure to `path`, all or nothing: SVG, or PNG when the name ends in `.png`.
/// Panels are laid out two per row, one per curve in `detection.params`.
pub fn plot_curves(detection: &Detection, path: impl AsRef<Path>) -> Result<(), PlotError> {
    let path = path.as_ref();
    let err = |message: String| PlotError {
        path: path.display().to_string(),
        message,
    };
    let mut staged = Staged::new();
    let tmp = staged.temp_for(path).map_err(|e| err(e.to_string()))?;
    draw_curves(detection, &tmp).map_err(|e| err(e.message))?;
    staged.commit().map_err(|e| err(e.to_string()))
}

/// Draw the figure into `path` as it is (no temporary): for a caller that stages several
/// outputs itself ([`crate::output::Staged`]). The format follows the extension of `path`.
pub fn draw_curves(detection: &Detection, path: &Path) -> Result<(), PlotError> {
    register_font();
    let n = detection.params.len().max(1);
    let cols = if n == 1 { 1 } else { 2 };
    let rows = n.div_ceil(cols);
    let size = (PANEL_W * cols as u32, PANEL_H * rows as u32);
    let err = |message: String| PlotError {
        path: path.display().to_string(),
        message,
    };
    let png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png {
        let root = BitMapBackend::new(path, size).into_drawing_area();
        draw(&root, detection, rows, cols).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))
    } else {
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
            draw(&root, detection, rows, cols).map_err(err)?;
            root.present().map_err(|e| err(e.to_string()))?;
        }
        std::fs::write(path, svg).map_err(|e| err(e.to_string()))
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    det: &Detection,
    rows: usize,
    cols: usize,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let panels = root.split_evenly((rows, cols));
    for (area, p) in panels.iter().zip(&det.params) {
        panel(area, det, p).map_err(|e| format!("panel `{}`: {e}", p.curve.param))?;
    }
    Ok(())
}

/// Axis ticks: at most four significant digits, without trailing zeros.
fn fmt_tick(v: f64) -> String {
    num::sig(v, 4, false)
}

/// Ticks of a log10 axis drawn linearly: plotters' own log axis puts as few as one
/// label on a decade, while evenly spaced log10 ticks give 1, 1.6, 2.5, 4, 6.3, …
fn fmt_tick_log(lv: f64) -> String {
    let v = 10f64.powf(lv);
    let digits = (1 - v.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The x-axis: what the intensity is, with its SI unit (translational elements).
fn intensity_label(sigma_name: &str) -> String {
    match sigma_name {
        "σ_s" => "σ_s: RMS deflection of the element (m, log scale)".into(),
        "σ_v" => "σ_v: RMS relative velocity of the element (m/s, log scale)".into(),
        other => format!("{other} (log scale)"),
    }
}

/// The y-axis: the parameter, what the per-level value is, and its SI unit.
fn param_label(param: &str, role: Role) -> String {
    match role {
        Role::Stiffness => format!("{param}, equivalent linear (N/m)"),
        Role::Damping => format!("{param}, equivalent linear (N·s/m)"),
        Role::Mass => format!("{param} (kg)"),
        Role::Other => format!("{param}, equivalent linear"),
    }
}

fn short_verdict(v: &Verdict) -> String {
    match v {
        Verdict::Linear => "linear".into(),
        Verdict::Nonlinear { best, .. } => best.clone(),
        Verdict::Ambiguous { candidates } => format!("ambiguous: {}", candidates.join(" / ")),
        Verdict::Unexplained { .. } => "drifts, unexplained".into(),
        Verdict::TooFewLevels { .. } => "drifts, too few levels".into(),
    }
}

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    det: &Detection,
    p: &ParamCurveResult,
) -> Result<(), String> {
    let finding = det.elements.iter().find(|e| e.element == p.curve.element);
    let templates: Vec<_> = finding
        .map(|f| {
            f.ranking
                .iter()
                .filter(|t| t.aicc.is_finite())
                .take(N_TEMPLATES)
                .collect()
        })
        .unwrap_or_default();
    let x: &[f64] = &p.sigma;
    let y = &p.curve.values;
    let se = &p.curve.stderrs;
    let (xmin, xmax) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let (x0, x1) = if xmax > xmin {
        (xmin / 1.35, xmax * 1.35)
    } else {
        (xmin / 2.0, xmax * 2.0)
    };
    let mut ylo = f64::INFINITY;
    let mut yhi = f64::NEG_INFINITY;
    for i in 0..y.len() {
        ylo = ylo.min(y[i] - se[i]);
        yhi = yhi.max(y[i] + se[i]);
    }
    ylo = ylo.min(p.mean);
    yhi = yhi.max(p.mean);
    let span = (yhi - ylo).max(1e-3 * p.mean.abs()).max(1e-12);
    // Templates may run off far outside the data; show them only near it.
    let (clip_lo, clip_hi) = (ylo - 0.5 * span, yhi + 0.5 * span);
    for t in &templates {
        for pr in t.predictions.iter().filter(|pr| pr.param == p.curve.param) {
            for (&xs, &v) in pr.sigma.iter().zip(&pr.value) {
                if xs >= x0 && xs <= x1 && v.is_finite() {
                    ylo = ylo.min(v.max(clip_lo));
                    yhi = yhi.max(v.min(clip_hi));
                }
            }
        }
    }
    let span = (yhi - ylo).max(1e-3 * p.mean.abs()).max(1e-12);
    // Room at the top for the legend.
    let n_legend = 2 + templates.len();
    let (y0, y1) = (
        ylo - 0.08 * span,
        yhi + (0.12 + 0.085 * n_legend as f64) * span,
    );

    let status = if p.drifting { "drifts" } else { "constant" };
    let p_text = if p.p_value < 1e-16 {
        "p < 1e-16".to_string()
    } else {
        format!("p = {:.1e}", p.p_value)
    };
    let title = format!(
        "{} · {} ({status}, {p_text}) — {}",
        p.curve.element,
        p.curve.param,
        finding.map_or_else(
            || "—".to_string(),
            |f| match &f.suspected {
                Some(x) => format!("{} (+ {}?)", short_verdict(&f.verdict), x.effect),
                None => short_verdict(&f.verdict),
            }
        ),
    );
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 19))
        .margin(12)
        .x_label_area_size(46)
        .y_label_area_size(72)
        .build_cartesian_2d(x0.log10()..x1.log10(), y0..y1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(intensity_label(&p.sigma_name))
        .y_desc(param_label(&p.curve.param, p.curve.role))
        .axis_desc_style(("sans-serif", 16))
        .label_style(("sans-serif", 15))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&|v| fmt_tick_log(*v))
        .y_label_formatter(&|v| fmt_tick(*v))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(|e| e.to_string())?;

    let gray = RGBColor(110, 110, 110);
    chart
        .draw_series(DashedLineSeries::new(
            [(x0.log10(), p.mean), (x1.log10(), p.mean)],
            8,
            5,
            gray.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?
        .label(format!("constant {}", fmt_pm(p.mean, p.mean_stderr)))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], gray.stroke_width(2)));

    let template_points = |t: &TemplateFit| -> Vec<(f64, f64)> {
        t.predictions
            .iter()
            .filter(|pr| pr.param == p.curve.param)
            .flat_map(|pr| pr.sigma.iter().zip(&pr.value))
            .filter(|(&xs, &v)| xs >= x0 && xs <= x1 && v >= y0 && v <= y1)
            .map(|(&xs, &v)| (xs.log10(), v))
            .collect()
    };
    for (i, t) in templates.iter().enumerate() {
        let color = TEMPLATE_COLORS[i];
        for pr in t.predictions.iter().filter(|pr| pr.param == p.curve.param) {
            let pts: Vec<(f64, f64)> = pr
                .sigma
                .iter()
                .zip(&pr.value)
                .filter(|(&xs, &v)| xs >= x0 && xs <= x1 && v >= y0 && v <= y1)
                .map(|(&xs, &v)| (xs.log10(), v))
                .collect();
            let est: Vec<String> = t.effect_estimates().iter().map(|e| e.to_string()).collect();
            // The best template solid, the others dashed: where templates predict the
            // same curve, every one of them still shows.
            let (dash, gap) = [(0, 0), (14, 6), (5, 5)][i];
            let style = color.stroke_width(if i == 0 { 2 } else { 3 });
            let drawn = if i == 0 {
                chart.draw_series(LineSeries::new(pts, style))
            } else {
                chart.draw_series(DashedLineSeries::new(pts, dash, gap, style))
            };
            drawn
                .map_err(|e| e.to_string())?
                .label(format!(
                    "{} (ΔAICc {}): {}",
                    t.name,
                    fmt_g(t.delta_aicc),
                    est.join(", ")
                ))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(2))
                });
        }
    }
    // The constant fit again, thin, above the templates that may coincide with it.
    chart
        .draw_series(DashedLineSeries::new(
            [(x0.log10(), p.mean), (x1.log10(), p.mean)],
            8,
            5,
            gray.stroke_width(1),
        ))
        .map_err(|e| e.to_string())?;

    // The best template again, on top of the others it may coincide with.
    if let Some(t) = templates.first() {
        chart
            .draw_series(LineSeries::new(
                template_points(t),
                TEMPLATE_COLORS[0].stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
    }
    chart
        .draw_series(x.iter().zip(y).zip(se).map(|((&xs, &v), &e)| {
            ErrorBar::new_vertical(xs.log10(), v - e, v, v + e, POINT_COLOR.stroke_width(2), 10)
        }))
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(
            x.iter()
                .zip(y)
                .map(|(&xs, &v)| Circle::new((xs.log10(), v), 4, POINT_COLOR.filled())),
        )
        .map_err(|e| e.to_string())?
        .label("per-level estimate ± 1 s.e.")
        .legend(|(x, y)| Circle::new((x + 11, y), 4, POINT_COLOR.filled()));

    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynid_runtime::detect::{
        detect, DetectOptions, DetectionInput, ElementIntensity, ParamCurve, Role,
    };

    /// Two elements over six levels: one hardening spring with level-dependent damping
    /// (Coulomb friction), one linear element.
    fn detection() -> Detection {
        let ss: Vec<f64> = (0..6).map(|i| 0.1 * 2f64.powi(i)).collect();
        let sv: Vec<f64> = ss.iter().map(|s| 2.0 * s).collect();
        let curve = |param: &str, element: &str, role, values: Vec<f64>, rel: f64| {
            let stderrs = values.iter().map(|v| rel * v.abs()).collect();
            ParamCurve {
                param: param.into(),
                element: element.into(),
                role,
                values,
                stderrs,
            }
        };
        let k = ss.iter().map(|s| 4.0 + 6.0 * s * s).collect();
        let d = sv.iter().map(|v| 0.4 + 0.24 / v).collect();
        let input = DetectionInput {
            held: Vec::new(),
            level_labels: Vec::new(),
            elements: vec![
                ElementIntensity {
                    element: "spring1".into(),
                    sigma_s: ss.clone(),
                    sigma_v: sv.clone(),
                    ..Default::default()
                },
                ElementIntensity {
                    element: "spring2".into(),
                    sigma_s: ss.iter().map(|s| 0.5 * s).collect(),
                    sigma_v: sv.iter().map(|v| 0.5 * v).collect(),
                    ..Default::default()
                },
            ],
            curves: vec![
                curve("k1", "spring1", Role::Stiffness, k, 0.01),
                curve("d1", "spring1", Role::Damping, d, 0.02),
                curve("k2", "spring2", Role::Stiffness, vec![2.0; 6], 0.01),
                curve("d2", "spring2", Role::Damping, vec![0.2; 6], 0.02),
            ],
        };
        detect(&input, &[], &DetectOptions::default()).expect("detects")
    }

    #[test]
    fn curves_are_written_as_svg_and_png_or_not_at_all() {
        let det = detection();
        let dir = tempfile::tempdir().unwrap();
        let svg = dir.path().join("curves.svg");
        let png = dir.path().join("curves.png");
        plot_curves(&det, &svg).unwrap();
        plot_curves(&det, &png).unwrap();
        let svg_text = std::fs::read_to_string(&svg).unwrap();
        assert!(svg_text.contains("<svg") && svg_text.contains("cubic stiffness"));
        let png_bytes = std::fs::read(&png).unwrap();
        assert_eq!(&png_bytes[1..4], b"PNG");
        if let Ok(keep) = std::env::var("DYNID_KEEP_PLOTS") {
            std::fs::copy(&svg, format!("{keep}.svg")).unwrap();
            std::fs::copy(&png, format!("{keep}.png")).unwrap();
        }
        // No partial file is left when the target cannot be written.
        let bad = dir.path().join("missing-dir").join("x.png");
        assert!(plot_curves(&det, &bad).is_err());
        let mut left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        assert_eq!(left, ["curves.png", "curves.svg"]);
    }
}
