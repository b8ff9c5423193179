//! The HTML report of a diagnosis.

use super::Diagnosis;

/// A self-contained HTML page.
pub fn render_html(d: &Diagnosis) -> String {
    format!("<html><body><pre>{}</pre></body></html>", d.summary())
}
