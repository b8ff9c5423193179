//! Helpers shared by the subcommands.

use dsl_parser::ir::ModelIr;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::Path;

/// Load a model: `.dyn` source through the compiler (all diagnostics rendered against the
/// file), or a `.json` file holding a compiled `ModelIr` (`dynid compile --emit json`).
pub fn load_model(path: &Path) -> miette::Result<ModelIr> {
    if path.extension().is_some_and(|e| e == "json") {
        let text = std::fs::read_to_string(path)
            .into_diagnostic()
            .wrap_err_with(|| format!("cannot read the model `{}`", path.display()))?;
        let ir: ModelIr = serde_json::from_str(&text)
            .into_diagnostic()
            .wrap_err_with(|| format!("`{}` is not a compiled model (JSON IR)", path.display()))?;
        ir.check_invariants()
            .map_err(|e| miette!("`{}` is not a consistent model: {e}", path.display()))?;
        return Ok(ir);
    }
    Ok(dsl_parser::compile_file(path)?)
}
