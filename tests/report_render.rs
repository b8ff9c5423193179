//! The figures as a reader sees them: the diagnosis report and the `detect --plot` figures
//! rendered by a headless browser at a laptop's width (1366 px), with the layout measured
//! in the browser (tests/render/layout.js): every label inside its figure, no label on top
//! of another, none smaller than 10 px, nothing wider than the window. A screenshot of each
//! page is left under the test's temporary target folder for a person to look at.
//!
//! Needs Chromium (`chromium`, or the browser named by `DYNID_BROWSER`); without one the test
//! says so and passes, unless `DYNID_REQUIRE_BROWSER=1` (set by `.ci/run` where it could
//! install the browser) makes a missing browser a failure.

mod common;

use common::{dynid, model_path as model, stderr, two_mass_levels};
use std::path::{Path, PathBuf};
use std::process::Command;

const WIDTH: u32 = 1366;

fn browser() -> Option<PathBuf> {
    if let Some(b) = std::env::var_os("DYNID_BROWSER") {
        return Some(PathBuf::from(b));
    }
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .map(PathBuf::from)
}

/// The browser's flags for a run on a closed network (no background connections) as root.
fn headless(browser: &Path, profile: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        "--virtual-time-budget=5000",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

/// What tests/render/layout.js measured on a page.
#[derive(Debug, serde::Deserialize)]
struct Layout {
    window_width: f64,
    page_width: f64,
    figures: usize,
    labels: usize,
    min_label_px: Option<f64>,
    outside: Vec<String>,
    overlapping: Vec<String>,
    too_small: Vec<String>,
    too_wide: Vec<String>,
}

/// Render `page` (an HTML file) with the layout script added, at [`WIDTH`] px, and return
/// what the script measured; a screenshot goes to `shot`.
fn render(browser: &Path, page: &Path, shot: &Path) -> Layout {
    let work = tempfile::tempdir().unwrap();
    let html = std::fs::read_to_string(page).unwrap();
    let script = format!("<script>{}</script>", include_str!("render/layout.js"));
    let checked = match html.rfind("</body>") {
        Some(i) => format!("{}{script}{}", &html[..i], &html[i..]),
        None => format!("{html}{script}"),
    };
    let checked_path = work.path().join("checked.html");
    std::fs::write(&checked_path, checked).unwrap();
    let out = headless(browser, &work.path().join("profile"))
        .arg(format!("--window-size={WIDTH},900"))
        .arg("--dump-dom")
        .arg(format!("file://{}", checked_path.display()))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let dom = String::from_utf8_lossy(&out.stdout);
    let start = dom
        .rfind("<pre id=\"dynid-layout\">")
        .unwrap_or_else(|| panic!("the layout script did not run on {}", page.display()))
        + "<pre id=\"dynid-layout\">".len();
    let end = start + dom[start..].find("</pre>").unwrap();
    let json = dom[start..end]
        .replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    let shot_out = headless(browser, &work.path().join("profile"))
        .arg(format!("--window-size={WIDTH},8000"))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    assert!(shot_out.status.success(), "{}", stderr(&shot_out));
    serde_json::from_str(&json).unwrap_or_else(|e| panic!("{e}: {json}"))
}

/// `fit_window`: the page must be no wider than the window (a report; a figure file is
/// looked at whole, fitted to the screen by the viewer).
fn assert_readable(what: &str, l: &Layout, min_figures: usize, fit_window: bool) {
    eprintln!(
        "{what}: {} figures, {} labels, smallest label {:.1} px, page {} px wide in a {} px window",
        l.figures,
        l.labels,
        l.min_label_px.unwrap_or(f64::NAN),
        l.page_width,
        l.window_width
    );
    assert!(l.figures >= min_figures, "{what}: {l:#?}");
    assert!(
        l.labels > 10 * l.figures,
        "{what}: figures without labels: {l:#?}"
    );
    assert!(
        l.outside.is_empty(),
        "{what}: labels cut by their figure: {:#?}",
        l.outside
    );
    assert!(
        l.overlapping.is_empty(),
        "{what}: labels on top of each other: {:#?}",
        l.overlapping
    );
    assert!(
        l.too_small.is_empty(),
        "{what}: labels under 10 px: {:#?}",
        l.too_small
    );
    if fit_window {
        assert!(
            l.too_wide.is_empty(),
            "{what}: wider than the window: {:#?}",
            l.too_wide
        );
        assert!(
            l.page_width <= l.window_width,
            "{what}: the page scrolls sideways: {l:#?}"
        );
    }
}

#[test]
fn the_report_and_the_detect_figures_are_readable_on_a_laptop_screen() {
    let Some(browser) = browser() else {
        assert!(
            std::env::var("DYNID_REQUIRE_BROWSER").as_deref() != Ok("1"),
            "DYNID_REQUIRE_BROWSER=1 but no browser found (chromium, or DYNID_BROWSER)"
        );
        eprintln!("skipped: no headless browser (install chromium, or set DYNID_BROWSER)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let levels = two_mass_levels(dir.path());
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report_render");
    std::fs::create_dir_all(&shots).unwrap();

    let report = dir.path().join("gap.html");
    let out = dynid()
        .arg("diagnose")
        .arg(model("two_mass_linear.dyn"))
        .args(&levels)
        .arg("--quiet")
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let l = render(&browser, &report, &shots.join("report.png"));
    // Bars, drift, 4 spectra, 8 time traces, 4 frequency responses at least.
    assert_readable("diagnosis report", &l, 15, true);

    // `detect --plot` writes the drift curves and the frequency responses beside them.
    let plot = dir.path().join("curves.svg");
    let out = dynid()
        .arg("detect")
        .arg(model("two_mass_linear.dyn"))
        .args(&levels)
        .arg("--quiet")
        .arg("--plot")
        .arg(&plot)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let svgs: Vec<PathBuf> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .collect();
    assert!(svgs.len() >= 2, "detect --plot wrote {svgs:?}");
    for svg in svgs {
        // Checked at its own size: its labels readable, none cut or on top of another.
        let page = svg.with_extension("html");
        let body = std::fs::read_to_string(&svg).unwrap();
        std::fs::write(
            &page,
            format!("<!DOCTYPE html><html><body style=\"margin:0\">{body}</body></html>"),
        )
        .unwrap();
        let name = svg.file_name().unwrap().to_string_lossy().into_owned();
        let l = render(&browser, &page, &shots.join(format!("{name}.png")));
        assert_readable(&format!("detect --plot {name}"), &l, 1, false);
    }
    eprintln!("screenshots in {}", shots.display());
}
