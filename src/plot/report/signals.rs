//! The figures of one level's signals: the power spectra of the measured and simulated
//! responses, and the time traces (whole record, a zoomed window, the free-run error).

use plotters::prelude::*;

use super::{legend_and_present, COLORS, MEASURED};
use dynid_runtime::diagnose::{fmt_si, Spectrum, Trace};

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
pub(super) fn spectra_fmax(spectra: &[Spectrum]) -> f64 {
    spectra
        .iter()
        .filter(|sp| sp.measured.len() > 1)
        .map(|sp| sp.freqs[spectrum_last_bin(sp)])
        .fold(0.0, f64::max)
}

/// One chart, built in plotters' order (area, mesh, series, legend); longer than most
/// functions here because each step is a call chain of its own, and split apart they would
/// pass the chart's typed context along.
pub(super) fn spectrum_svg(sp: &Spectrum, fmax: f64, unit: &str) -> Result<String, String> {
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
pub(super) fn trace_window(tr: &Trace) -> (usize, usize) {
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
/// One chart, built in plotters' order (area, mesh, series, legend); longer than most
/// functions here because each step is a call chain of its own, and split apart they would
/// pass the chart's typed context along.
pub(super) fn trace_svg(tr: &Trace, (a, b): (usize, usize), error: bool) -> Result<String, String> {
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
