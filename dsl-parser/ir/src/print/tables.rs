//! The parameter and column tables of a model (rows as data for JSON, and as aligned text),
//! and [`aligned`], the text-table layout every printed table uses.

use super::{join_signed, render_basis, render_expr};
use crate::ir::*;
use crate::num::exact as fmt_num;
use serde::Serialize;

/// A row of the parameter table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParamRow {
    pub name: String,
    /// `"unknown"` or `"known"`.
    pub kind: &'static str,
    /// The known value or the nominal one (absent for an unknown without nominal).
    pub value: Option<f64>,
    /// Elements (or `body (mass)`) whose terms use the parameter.
    pub used_by: Vec<String>,
}

/// A column of the least-squares problem restricted to one equation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ColumnRow {
    /// The unknown parameter (the column's name).
    pub column: String,
    /// The body whose equation this is.
    pub equation: String,
    /// The sum of the scaled bases the parameter multiplies in this equation.
    pub basis: String,
    /// `static`, `static (m1.v measured)` or `derivative (moved onto the filter)`.
    pub kind: String,
}

/// Per parameter, the terms it multiplies as (equation, term) indices in model order: one
/// pass over the equations, so the tables cost time linear in the model's size.
fn terms_by_param(ir: &ModelIr) -> Vec<Vec<(usize, usize)>> {
    let mut by = vec![Vec::new(); ir.params.len()];
    for (q, eq) in ir.equations.iter().enumerate() {
        for (k, t) in eq.terms.iter().enumerate() {
            if let Some(p) = t.coef.param.and_then(|p| by.get_mut(p.index())) {
                p.push((q, k));
            }
        }
    }
    by
}

pub fn param_rows(ir: &ModelIr) -> Vec<ParamRow> {
    let by = terms_by_param(ir);
    ir.params
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut used_by: Vec<String> = Vec::new();
            {
                for t in by[i].iter().map(|&(q, k)| &ir.equations[q].terms[k]) {
                    let who = match t.origin {
                        TermOrigin::Inertia(b) => format!("{} (mass)", ir.bodies[b.index()].name),
                        TermOrigin::Element(e) => ir.elements[e.index()].name.clone(),
                        TermOrigin::Input(j) => ir.inputs[j.index()].name.clone(),
                    };
                    if !used_by.contains(&who) {
                        used_by.push(who);
                    }
                }
            }
            ParamRow {
                name: p.name.clone(),
                kind: if p.is_unknown() { "unknown" } else { "known" },
                value: p.nominal(),
                used_by,
            }
        })
        .collect()
}

pub fn column_rows(ir: &ModelIr) -> Vec<ColumnRow> {
    let by = terms_by_param(ir);
    let mut rows = Vec::new();
    for p in ir.unknowns() {
        let uses = &by[p.index()];
        // The equations this parameter appears in, in model order.
        let mut eqs: Vec<usize> = uses.iter().map(|&(q, _)| q).collect();
        eqs.dedup();
        for q in eqs {
            let eq = &ir.equations[q];
            let terms: Vec<&TermIr> = uses
                .iter()
                .filter(|&&(qq, _)| qq == q)
                .map(|&(_, k)| &eq.terms[k])
                .collect();
            let mut pieces = Vec::new();
            let (mut is_static, mut velocities, mut derivative) = (false, Vec::new(), false);
            let mut constant = false;
            // Terms of bodies measured only by accelerations: formed from `b.a` by the
            // band-pass instruments (`ẍ` is the acceleration itself).
            let mut integrated: Vec<String> = Vec::new();
            let mut nonlinear_acc: Vec<String> = Vec::new();
            for t in &terms {
                let b = match (terms.len(), t.basis, t.coef.scale) {
                    // A lone positive term needs no parentheses.
                    (1, Basis::Expr(e), s) if s > 0.0 => render_expr(ir, e),
                    _ => render_basis(ir, t.basis),
                };
                let a = t.coef.scale.abs();
                let text = if a == 1.0 {
                    b
                } else if matches!(t.basis, Basis::Expr(e) if ir.is_constant(e)) {
                    fmt_num(a)
                } else {
                    format!("{} {b}", fmt_num(a))
                };
                pieces.push((t.coef.scale < 0.0, text));
                let accel_only = |body: BodyId| {
                    ir.acceleration_only(body)
                        .then(|| ir.acceleration(body))
                        .flatten()
                        .map(|a| ir.signal(a).name.clone())
                };
                let from_acc: Vec<String> = match t.basis {
                    Basis::Expr(e) => ir
                        .expr_signals(e)
                        .into_iter()
                        .filter_map(|s| match ir.signal(s).kind {
                            SignalKind::Position(b) | SignalKind::Velocity(b) => accel_only(b),
                            _ => None,
                        })
                        .collect(),
                    Basis::Deriv { body, .. } => accel_only(body).into_iter().collect(),
                };
                if !from_acc.is_empty() {
                    // Nonlinear: evaluated on motion integrated from the acceleration.
                    match t.basis {
                        Basis::Expr(e) if ir.linear_form(e).is_none() => {
                            nonlinear_acc.extend(from_acc)
                        }
                        _ => integrated.extend(from_acc),
                    }
                    continue;
                }
                match t.basis {
                    Basis::Expr(e) if ir.is_constant(e) => constant = true,
                    Basis::Expr(_) => is_static = true,
                    Basis::Deriv { body, order: 1 } if ir.signal(ir.velocity(body)).measured => {
                        velocities.push(ir.signal(ir.velocity(body)).name.clone());
                    }
                    Basis::Deriv { .. } => derivative = true,
                }
            }
            let mut kinds = Vec::new();
            if constant {
                kinds.push("constant (needs data with a mean)".to_string());
            }
            if is_static || !velocities.is_empty() {
                kinds.push(if velocities.is_empty() {
                    "static".to_string()
                } else {
                    velocities.sort();
                    velocities.dedup();
                    format!("static ({} measured)", velocities.join(", "))
                });
            }
            if derivative {
                kinds.push("derivative (moved onto the filter)".to_string());
            }
            if !integrated.is_empty() {
                integrated.sort();
                integrated.dedup();
                kinds.push(format!(
                    "from {} (integrals moved onto band-pass filters)",
                    integrated.join(", ")
                ));
            }
            if !nonlinear_acc.is_empty() {
                nonlinear_acc.sort();
                nonlinear_acc.dedup();
                kinds.push(format!(
                    "static, on motion integrated from {}",
                    nonlinear_acc.join(", ")
                ));
            }
            rows.push(ColumnRow {
                column: ir.params[p.index()].name.clone(),
                equation: ir.bodies[eq.body.index()].name.clone(),
                basis: join_signed(&pieces),
                kind: kinds.join(" + "),
            });
        }
    }
    rows
}

fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let all: Vec<Vec<String>> = std::iter::once(header.iter().map(|h| h.to_string()).collect())
        .chain(rows.iter().cloned())
        .collect();
    aligned(&all, &[], "  ")
}

/// Text columns padded to their widest cell, counted in characters (so that σ, χ² and Δ
/// do not throw the alignment off), two spaces apart, each line starting with `indent`.
/// `right[j]` right-aligns column j (left where absent); a left-aligned last cell is not
/// padded and lines carry no trailing spaces.
pub fn aligned(rows: &[Vec<String>], right: &[bool], indent: &str) -> String {
    let ncol = rows.iter().map(Vec::len).max().unwrap_or(0);
    let width: Vec<usize> = (0..ncol)
        .map(|j| {
            rows.iter()
                .filter_map(|r| r.get(j))
                .map(|c| c.chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut out = String::new();
    for r in rows {
        let mut line = indent.to_string();
        for (j, c) in r.iter().enumerate() {
            let pad = " ".repeat(width[j] - c.chars().count());
            let last = j + 1 == r.len();
            if j > 0 {
                line.push_str("  ");
            }
            if right.get(j).copied().unwrap_or(false) {
                line.push_str(&pad);
                line.push_str(c);
            } else {
                line.push_str(c);
                if !last {
                    line.push_str(&pad);
                }
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

/// The parameter table as text.
pub fn render_params(ir: &ModelIr) -> String {
    let rows: Vec<Vec<String>> = param_rows(ir)
        .into_iter()
        .map(|r| {
            let value = match (r.kind, r.value) {
                ("known", Some(v)) => format!("= {}", fmt_num(v)),
                (_, Some(v)) => format!("~ {}", fmt_num(v)),
                (_, None) => "(no nominal)".into(),
            };
            vec![r.name, r.kind.to_string(), value, r.used_by.join(", ")]
        })
        .collect();
    table(&["parameter", "kind", "value", "used by"], &rows)
}

/// The column table as text.
pub fn render_columns(ir: &ModelIr) -> String {
    let rows: Vec<Vec<String>> = column_rows(ir)
        .into_iter()
        .map(|r| vec![r.column, r.equation, r.basis, r.kind])
        .collect();
    table(&["column", "equation", "basis", "kind"], &rows)
}
