//! Figures: where output is made, not in the numerics. The detection curves
//! ([`curves::plot_curves`], SVG or PNG) and the diagnosis' HTML report with inline SVG
//! figures ([`report::render_html`]), drawn with plotters.
//!
//! Text is drawn with one embedded font (DejaVu Sans, licence in
//! `assets/DejaVuSans-LICENSE.txt`), registered once per process, so that plotting needs
//! no system font libraries.

pub mod curves;
pub mod frf;
pub mod report;

pub use curves::{draw_curves, plot_curves};
pub use frf::{draw_frf, frf_svg_strings};
pub use report::render_html;

use plotters::style::FontStyle;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Make the embedded font the `sans-serif` family of plotters.
fn register_font() {
    REGISTER.call_once(|| {
        // The embedded file is a valid TrueType font; failure here is a build defect.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
        let _ = plotters::style::register_font("sans-serif", FontStyle::Bold, FONT);
    });
}

/// A figure could not be drawn or written.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[error("cannot write the plot `{path}`: {message}")]
#[diagnostic(
    code(dynid::plot),
    help("check that the directory exists and is writable; use a .svg or .png file name")
)]
pub struct PlotError {
    pub path: String,
    pub message: String,
}
