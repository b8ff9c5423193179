//! The frequency response per level: for each measured response a column of three panels
//! (magnitude on log axes, phase in degrees, coherence), frequency in Hz on a log axis. Each
//! level has one colour: the measured FRF (H1, or the per-period average at the excited
//! lines) as a solid line (points for periodic data), the fitted linear model's FRF at that
//! level dashed. A peak that moves and broadens from level to level is the nonlinearity.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{register_font, PlotError};
use dsl_parser::num;
use dynid_runtime::frf::{FrfMethod, LevelFrf};

const PANEL_W: u32 = 640;
const MAG_H: u32 = 400;
const PHASE_H: u32 = 250;
const COH_H: u32 = 200;

const LEVEL_COLORS: [RGBColor; 8] = [
    RGBColor(25, 60, 160),
    RGBColor(200, 30, 45),
    RGBColor(20, 140, 60),
    RGBColor(230, 140, 0),
    RGBColor(120, 50, 170),
    RGBColor(0, 150, 170),
    RGBColor(150, 90, 40),
    RGBColor(90, 90, 90),
];

/// Draw the figure into `path` as it is (no temporary): SVG, or PNG when the name ends in
/// `.png`. The caller stages it ([`crate::output::Staged`]).
pub fn draw_frf(levels: &[LevelFrf], path: &Path) -> Result<(), PlotError> {
    register_font();
    let err = |message: String| PlotError {
        path: path.display().to_string(),
        message,
    };
    let cols = levels.first().map_or(1, |l| l.outputs.len().max(1));
    let size = (PANEL_W * cols as u32, MAG_H + PHASE_H + COH_H);
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        let root = BitMapBackend::new(path, size).into_drawing_area();
        draw(&root, levels, 0..cols).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))
    } else {
        let svg = frf_svg(levels, 0..cols, size).map_err(err)?;
        std::fs::write(path, svg).map_err(|e| err(e.to_string()))
    }
}

/// Width of one response's column in the HTML report: two columns side by side fit the
/// report's 1100 px page (a laptop screen) with their margins.
const REPORT_PANEL_W: u32 = 500;

/// The figure for the HTML report: one SVG per response (a column of three panels
/// [`REPORT_PANEL_W`] wide), so that the page wraps them instead of growing wider than
/// the screen.
pub fn frf_svg_strings(levels: &[LevelFrf]) -> Result<Vec<String>, String> {
    register_font();
    let n = levels.first().map_or(0, |l| l.outputs.len());
    (0..n)
        .map(|j| frf_svg(levels, j..j + 1, (REPORT_PANEL_W, MAG_H + PHASE_H + COH_H)))
        .collect()
}

fn frf_svg(
    levels: &[LevelFrf],
    which: std::ops::Range<usize>,
    size: (u32, u32),
) -> Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw(&root, levels, which)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// Draw the responses `which` side by side, one column of panels each.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    levels: &[LevelFrf],
    which: std::ops::Range<usize>,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let Some(first) = levels.first() else {
        return Ok(());
    };
    let cols = root.split_evenly((1, which.len().max(1)));
    for (col, j) in cols.iter().zip(which) {
        let (mag, rest) = col.split_vertically(MAG_H);
        let (phase, coh) = rest.split_vertically(PHASE_H);
        column(&mag, &phase, &coh, levels, j).map_err(|e| format!("{}: {e}", first.outputs[j]))?;
    }
    Ok(())
}

/// Labels for a legend: where they are paths, without the folder they all share
/// (`runs/a/level_1.csv`, `runs/b/level_1.csv` → `a/level_1.csv`, `b/level_1.csv`).
fn strip_shared_folder<'a>(labels: &[&'a str]) -> Vec<&'a str> {
    let Some((first, rest)) = labels.split_first() else {
        return Vec::new();
    };
    let mut cut = first.rfind(['/', '\\']).map_or(0, |i| i + 1);
    for l in rest {
        while cut > 0 && l.as_bytes().get(..cut) != Some(&first.as_bytes()[..cut]) {
            cut = first[..cut - 1].rfind(['/', '\\']).map_or(0, |i| i + 1);
        }
    }
    labels.iter().map(|l| &l[cut..]).collect()
}

/// Log10 of the frequency range over every level, padded.
fn freq_range(levels: &[LevelFrf]) -> (f64, f64) {
    let (lo, hi) = levels
        .iter()
        .flat_map(|l| l.measured.freq_hz.iter())
        .fold((f64::INFINITY, 0.0f64), |(a, b), &f| (a.min(f), b.max(f)));
    if !(lo.is_finite() && hi > lo) {
        return (-2.0, 1.0);
    }
    (lo.log10() - 0.05, hi.log10() + 0.05)
}

fn fmt_tick_log(lv: f64) -> String {
    let v = 10f64.powf(lv);
    num::sig(v, 2, false)
}

fn mag(h: [f64; 2]) -> f64 {
    (h[0] * h[0] + h[1] * h[1]).sqrt()
}

fn phase_deg(h: [f64; 2]) -> f64 {
    h[1].atan2(h[0]).to_degrees()
}

fn column<DB: DrawingBackend>(
    mag_area: &DrawingArea<DB, Shift>,
    phase_area: &DrawingArea<DB, Shift>,
    coh_area: &DrawingArea<DB, Shift>,
    levels: &[LevelFrf],
    j: usize,
) -> Result<(), String> {
    let first = &levels[0];
    let (x0, x1) = freq_range(levels);
    let mags = levels.iter().flat_map(|l| {
        l.measured.h[j]
            .iter()
            .map(|&h| mag(h))
            .chain(l.model[j].iter().flatten().map(|&h| mag(h)))
    });
    let (mlo, mhi) = mags
        .filter(|m| *m > 0.0 && m.is_finite())
        .fold((f64::INFINITY, 0.0f64), |(a, b), m| (a.min(m), b.max(m)));
    let (y0, y1) = if mlo.is_finite() && mhi > mlo {
        // Room above the highest peak for the legend (two entries per level), so that it
        // hides no data.
        let span = (mhi.log10() - mlo.log10()).max(0.5);
        let entries = 2.0 * levels.len() as f64;
        (
            mlo.log10() - 0.05 * span,
            mhi.log10() + (0.1 + 0.085 * entries) * span,
        )
    } else {
        (-3.0, 1.0)
    };
    let periodic = matches!(first.measured.method, FrfMethod::Periodic { .. });
    let method = match first.measured.method {
        FrfMethod::Welch { segment } => format!("H1, Welch segments of {segment} samples"),
        FrfMethod::Periodic { .. } => "average over periods, excited lines".to_string(),
    };
    let title = format!("{} / {} — {method}", first.outputs[j], first.input);
    let mut chart = ChartBuilder::on(mag_area)
        .caption(title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("frequency (Hz, log scale)")
        .y_desc(format!("|H| ({}, log scale)", first.units[j]))
        .axis_desc_style(("sans-serif", 14))
        .label_style(("sans-serif", 12))
        .x_label_formatter(&|v| fmt_tick_log(*v))
        .y_label_formatter(&|v| num::sig(10f64.powf(*v), 2, false))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(|e| e.to_string())?;
    let labels: Vec<&str> = levels.iter().map(|l| l.label.as_str()).collect();
    let names = strip_shared_folder(&labels);
    for (l, lev) in levels.iter().enumerate() {
        let color = LEVEL_COLORS[l % LEVEL_COLORS.len()];
        let pts: Vec<(f64, f64)> = lev
            .measured
            .freq_hz
            .iter()
            .zip(&lev.measured.h[j])
            .filter(|(_, h)| mag(**h) > 0.0)
            .map(|(f, h)| (f.log10(), mag(*h).log10()))
            .collect();
        let label = format!("{} measured", names[l]);
        if periodic {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 2, color.filled())))
                .map_err(|e| e.to_string())?
                .label(label)
                .legend(move |(x, y)| Circle::new((x + 11, y), 3, color.filled()));
        } else {
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(1)))
                .map_err(|e| e.to_string())?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(2))
                });
        }
        let model: Vec<(f64, f64)> = lev
            .measured
            .freq_hz
            .iter()
            .zip(&lev.model[j])
            .filter_map(|(f, h)| {
                h.filter(|h| mag(*h) > 0.0)
                    .map(|h| (f.log10(), mag(h).log10()))
            })
            .collect();
        if !model.is_empty() {
            chart
                .draw_series(DashedLineSeries::new(
                    model,
                    6,
                    4,
                    color.mix(0.9).stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(format!("{} linear model", names[l]))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 8, y)], color.stroke_width(2))
                });
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 13))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .draw()
        .map_err(|e| e.to_string())?;

    let mut ph = ChartBuilder::on(phase_area)
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, -180.0..180.0)
        .map_err(|e| e.to_string())?;
    ph.configure_mesh()
        .x_desc("frequency (Hz, log scale)")
        .y_desc("phase of H (degrees)")
        .axis_desc_style(("sans-serif", 14))
        .label_style(("sans-serif", 12))
        .x_label_formatter(&|v| fmt_tick_log(*v))
        .y_labels(7)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(|e| e.to_string())?;
    for (l, lev) in levels.iter().enumerate() {
        let color = LEVEL_COLORS[l % LEVEL_COLORS.len()];
        let pts = lev
            .measured
            .freq_hz
            .iter()
            .zip(&lev.measured.h[j])
            .map(|(f, h)| (f.log10(), phase_deg(*h)));
        ph.draw_series(pts.map(|p| Circle::new(p, 1, color.filled())))
            .map_err(|e| e.to_string())?;
        let model: Vec<(f64, f64)> = lev
            .measured
            .freq_hz
            .iter()
            .zip(&lev.model[j])
            .filter_map(|(f, h)| h.map(|h| (f.log10(), phase_deg(h))))
            .collect();
        // Break the dashed line where the phase wraps.
        for seg in split_wraps(&model) {
            ph.draw_series(DashedLineSeries::new(seg, 6, 4, color.stroke_width(2)))
                .map_err(|e| e.to_string())?;
        }
    }

    let mut co = ChartBuilder::on(coh_area)
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, 0.0..1.05)
        .map_err(|e| e.to_string())?;
    co.configure_mesh()
        .x_desc("frequency (Hz, log scale)")
        .y_desc("coherence γ² (1)")
        .axis_desc_style(("sans-serif", 14))
        .label_style(("sans-serif", 12))
        .x_label_formatter(&|v| fmt_tick_log(*v))
        .y_labels(6)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(|e| e.to_string())?;
    for (l, lev) in levels.iter().enumerate() {
        let color = LEVEL_COLORS[l % LEVEL_COLORS.len()];
        let pts: Vec<(f64, f64)> = lev
            .measured
            .freq_hz
            .iter()
            .zip(&lev.measured.coherence[j])
            .map(|(f, c)| (f.log10(), *c))
            .collect();
        if periodic {
            co.draw_series(pts.iter().map(|&p| Circle::new(p, 1, color.filled())))
                .map_err(|e| e.to_string())?;
        } else {
            co.draw_series(LineSeries::new(pts, color.stroke_width(1)))
                .map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}

/// Split a phase curve where consecutive points jump by more than 180°.
fn split_wraps(pts: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for w in pts {
        if let Some(last) = out.last().and_then(|s| s.last()) {
            if (w.1 - last.1).abs() > 180.0 {
                out.push(Vec::new());
            }
        }
        out.last_mut().expect("invariant: never empty").push(*w);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::strip_shared_folder;

    #[test]
    fn legends_name_files_without_their_shared_folder() {
        assert_eq!(
            strip_shared_folder(&["/tmp/x/data/level_1.csv", "/tmp/x/data/level_2.csv"]),
            ["level_1.csv", "level_2.csv"]
        );
        assert_eq!(
            strip_shared_folder(&["runs/a/level_1.csv", "runs/b/level_1.csv"]),
            ["a/level_1.csv", "b/level_1.csv"]
        );
        assert_eq!(
            strip_shared_folder(&["a/l.csv", "l2.csv"]),
            ["a/l.csv", "l2.csv"]
        );
        assert_eq!(
            strip_shared_folder(&["level 1", "level 2"]),
            ["level 1", "level 2"]
        );
        assert_eq!(strip_shared_folder(&["dir/only.csv"]), ["only.csv"]);
        assert!(strip_shared_folder(&[]).is_empty());
    }
}
