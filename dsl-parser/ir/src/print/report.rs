//! The report of `dynid compile`: the model's counts, measured signals, control laws,
//! equations, parameter and column tables, as text ([`render_report`]) or JSON
//! ([`report_json`]).

use super::tables::{column_rows, param_rows, render_columns, render_params, ColumnRow, ParamRow};
use super::{control_rows, render_equation};
use crate::ir::*;
use crate::num::exact as fmt_num;
use serde::Serialize;
use std::fmt::Write;

/// The full text report of `dynid compile`.
pub fn render_report(ir: &ModelIr) -> String {
    let mut out = String::new();
    let n_unknown = ir.unknowns().len();
    let _ = writeln!(
        out,
        "model {}: {} bod{}, {} input{}, {} parameter{} ({n_unknown} unknown)",
        ir.name,
        ir.bodies.len(),
        if ir.bodies.len() == 1 { "y" } else { "ies" },
        ir.inputs.len(),
        if ir.inputs.len() == 1 { "" } else { "s" },
        ir.params.len(),
        if ir.params.len() == 1 { "" } else { "s" },
    );
    let measured: Vec<&str> = ir
        .signals
        .iter()
        .filter(|s| s.measured)
        .map(|s| s.name.as_str())
        .collect();
    let _ = writeln!(out, "measured: {}", measured.join(", "));
    for (input, law) in control_rows(ir) {
        let _ = writeln!(out, "closed loop: {input} = {law}");
    }
    out.push_str("\nequations of motion:\n");
    for eq in &ir.equations {
        let _ = writeln!(out, "  {}", render_equation(ir, eq));
    }
    out.push_str("\nparameters:\n");
    out.push_str(&render_params(ir));
    for sh in &ir.shapes {
        let _ = writeln!(
            out,
            "  shape parameter {} ~ {} (a gap or limit: profiled by identification, not a column)",
            sh.name,
            fmt_num(sh.nominal)
        );
    }
    out.push_str("\nleast-squares columns:\n");
    out.push_str(&render_columns(ir));
    out
}

#[derive(Serialize)]
struct JsonEquation {
    body: String,
    text: String,
}

#[derive(Serialize)]
struct JsonControl {
    input: String,
    law: String,
}

#[derive(Serialize)]
struct JsonReport {
    model: String,
    measured: Vec<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    controls: Vec<JsonControl>,
    equations: Vec<JsonEquation>,
    params: Vec<ParamRow>,
    columns: Vec<ColumnRow>,
}

/// The report of `dynid compile --format json`.
pub fn report_json(ir: &ModelIr) -> serde_json::Value {
    let r = JsonReport {
        model: ir.name.clone(),
        measured: ir
            .signals
            .iter()
            .filter(|s| s.measured)
            .map(|s| s.name.clone())
            .collect(),
        controls: control_rows(ir)
            .into_iter()
            .map(|(input, law)| JsonControl { input, law })
            .collect(),
        equations: ir
            .equations
            .iter()
            .map(|eq| JsonEquation {
                body: ir.bodies[eq.body.index()].name.clone(),
                text: render_equation(ir, eq)
                    .split_once(": ")
                    .map(|(_, t)| t.to_string())
                    .unwrap_or_default(),
            })
            .collect(),
        params: param_rows(ir),
        columns: column_rows(ir),
    };
    serde_json::to_value(r).unwrap_or(serde_json::Value::Null)
}
