//! The model printed back as `.dyn` source ([`to_source`]), the inverse of compilation.

use super::{control_rows, join_signed, Printer, P_MUL};
use crate::ir::*;
use crate::num::exact as fmt_num;
use std::fmt::Write;

fn node_name(ir: &ModelIr, n: Node) -> &str {
    match n {
        Node::Ground => "ground",
        Node::Body(b) => &ir.bodies[b.index()].name,
    }
}

fn value_suffix(kind: &ParamKind) -> String {
    match kind {
        ParamKind::Known(v) => format!(" = {}", fmt_num(*v)),
        ParamKind::Unknown { nominal: Some(v) } => format!(" ~ {}", fmt_num(*v)),
        ParamKind::Unknown { nominal: None } => String::new(),
    }
}

/// The model as `.dyn` source. Parameters are declared where they are first used, so
/// compiling the text gives back the same IR (spans aside).
pub fn to_source(ir: &ModelIr) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "model {} {{", ir.name);
    let mut declared = vec![false; ir.params.len()];
    for b in &ir.bodies {
        match b.mass.param {
            Some(p) => {
                declared[p.index()] = true;
                let _ = writeln!(
                    out,
                    "    body {}{}",
                    b.name,
                    value_suffix(&ir.params[p.index()].kind)
                );
            }
            None => {
                let _ = writeln!(out, "    body {} = {}", b.name, fmt_num(b.mass.scale));
            }
        }
    }
    for i in &ir.inputs {
        let _ = writeln!(
            out,
            "    input {} on {}",
            i.name,
            ir.bodies[i.body.index()].name
        );
    }
    for r in &ir.references {
        let _ = writeln!(out, "    reference {}", r.name);
    }
    for (input, law) in control_rows(ir) {
        let _ = writeln!(out, "    control {input} = {law}");
    }
    if ir.signals.iter().any(|s| !s.measured) {
        let m: Vec<&str> = ir
            .signals
            .iter()
            .filter(|s| s.measured)
            .map(|s| s.name.as_str())
            .collect();
        let _ = writeln!(out, "    measure {}", m.join(", "));
    }
    // Parameters owned by springs and dampers are declared by their statement, wherever
    // it stands, so force terms refer to them by name.
    let owned = |e: &ElementIr| -> Option<ParamId> {
        let basis = match e.kind {
            ElementKind::Spring => e.s,
            ElementKind::Damper => e.v,
            ElementKind::Force => return None,
        };
        match e.terms.as_slice() {
            [t] if t.basis == basis && t.coef.scale == 1.0 => {
                t.coef.param.filter(|p| ir.params[p.index()].name == e.name)
            }
            _ => None,
        }
    };
    for e in &ir.elements {
        if let Some(p) = owned(e) {
            declared[p.index()] = true;
        }
    }
    let shapes_declared = std::cell::RefCell::new(vec![false; ir.shapes.len()]);
    for e in &ir.elements {
        let (a, b) = (node_name(ir, e.nodes.0), node_name(ir, e.nodes.1));
        if let Some(p) = owned(e) {
            let kw = if e.kind == ElementKind::Spring {
                "spring"
            } else {
                "damper"
            };
            let _ = writeln!(
                out,
                "    {kw} {} ({a}, {b}){}",
                e.name,
                value_suffix(&ir.params[p.index()].kind)
            );
            continue;
        }
        let names = [(e.s, "s"), (e.v, "v")];
        let pr = Printer {
            ir,
            names: &names,
            declared: Some(&shapes_declared),
        };
        let mut pieces = Vec::new();
        for t in &e.terms {
            let mut factors = Vec::new();
            let a = t.coef.scale.abs();
            if a != 1.0 || t.coef.param.is_none() {
                factors.push(fmt_num(a));
            }
            if let Some(p) = t.coef.param {
                let param = &ir.params[p.index()];
                if declared[p.index()] {
                    factors.push(param.name.clone());
                } else {
                    declared[p.index()] = true;
                    factors.push(format!("{}{}", param.name, value_suffix(&param.kind)));
                }
            }
            // A constant force is written as its coefficient alone (`f0 ~ -0.5`).
            if !(ir.is_constant(t.basis) && t.coef.param.is_some()) {
                factors.push(pr.at(t.basis, P_MUL + 1));
            }
            pieces.push((t.coef.scale < 0.0, factors.join(" * ")));
        }
        let _ = writeln!(
            out,
            "    force {} ({a}, {b}) = {}",
            e.name,
            join_signed(&pieces)
        );
    }
    let excite = |out: &mut String, name: &str, filter: &FormFilter, levels: &[f64]| {
        let form = match *filter {
            FormFilter::Lowpass { corner } => format!("lowpass(corner = {})", fmt_num(corner)),
            FormFilter::SecondOrder { freq, damping } => format!(
                "second_order(freq = {}, damping = {})",
                fmt_num(freq),
                fmt_num(damping)
            ),
            FormFilter::White => "white".into(),
            FormFilter::Moves {
                distance,
                speed,
                accel,
                dwell,
            } => format!(
                "moves(distance = {}, speed = {}, accel = {}, dwell = {})",
                fmt_num(distance),
                fmt_num(speed),
                fmt_num(accel),
                fmt_num(dwell)
            ),
        };
        let levels: Vec<String> = levels.iter().map(|l| fmt_num(*l)).collect();
        let _ = writeln!(
            out,
            "    excite {name}: {form} levels [{}]",
            levels.join(", ")
        );
    };
    for x in &ir.excitation {
        excite(
            &mut out,
            &ir.inputs[x.input.index()].name,
            &x.filter,
            &x.levels,
        );
    }
    for x in &ir.reference_excitation {
        let name = &ir.references[x.reference.index()].name;
        excite(&mut out, name, &x.filter, &x.levels);
    }
    if let Some(f) = &ir.filter {
        let corners: Vec<String> = f.corners.iter().map(|c| fmt_num(*c)).collect();
        let _ = write!(
            out,
            "    filter corners [{}] order {}",
            corners.join(", "),
            f.order
        );
        if !f.driven_by.is_empty() {
            let d: Vec<&str> = f
                .driven_by
                .iter()
                .map(|s| ir.signal(*s).name.as_str())
                .collect();
            let _ = write!(out, " driven by {}", d.join(", "));
        }
        out.push('\n');
    }
    out.push_str("}\n");
    out
}
