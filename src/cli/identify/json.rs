//! The document of `dynid identify --json`: the runtime's [`IdentifyDoc`], the one that
//! Python's `Identification.to_dict()` gives (docs/json.md).

use super::RefineReport;
use dynid::schema::IdentifyDoc;
use dynid_runtime::ident::Identification;
use miette::IntoDiagnostic;

/// The text of `--json`: the document of `id` with the refinement and the closed-loop hint
/// where there are (their keys are absent otherwise), pretty-printed with the keys sorted.
pub fn document(
    id: &Identification,
    refined: Option<&RefineReport>,
    closed_loop_hint: Option<&str>,
) -> miette::Result<String> {
    let doc = IdentifyDoc {
        closed_loop_hint,
        ..IdentifyDoc::new(id).with_refined(refined)
    };
    // Through a `Value`: the keys sorted, as the file has always had them.
    let value = serde_json::to_value(doc).into_diagnostic()?;
    serde_json::to_string_pretty(&value).into_diagnostic()
}
