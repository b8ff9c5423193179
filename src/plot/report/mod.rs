//! The HTML report of a diagnosis: one self-contained page (inline SVG figures drawn with
//! plotters, inline CSS, no scripts), so that it opens offline and can be mailed around.
//!
//! [`render_html`] writes the page section by section (`sections`); the figures of the
//! whole diagnosis are drawn in `summary`, those of one level's signals in `signals`.

mod sections;
mod signals;
mod summary;

use std::fmt::Write;

use plotters::prelude::*;

use super::register_font;
use dynid_runtime::diagnose::Diagnosis;

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

/// `s` with the characters HTML gives a meaning escaped.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
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
    sections::page_head(&mut h, d);
    sections::headline(&mut h, d);
    sections::gap_table(&mut h, d);
    sections::equation_residuals(&mut h, d);
    sections::parameters(&mut h, d);
    sections::drift(&mut h, d);
    sections::spectra_and_traces(&mut h, d);
    sections::ranking(&mut h, d);
    sections::corrected_model(&mut h, d);
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
