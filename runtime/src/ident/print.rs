//! Identified equations as a person reads them:
//! `m1: 1.000 m1.x'' + 0.4010(±0.0020) m1.x' + 3.990 m1.x + … = u`.

use super::types::Identification;
use dynid_ir::ir::{Basis, ModelIr, ParamKind, TermOrigin};
use dynid_ir::print::render_basis;

/// A number with four significant digits, without trailing noise.
pub fn fmt_num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    if (-3..5).contains(&mag) {
        let dec = (3 - mag).max(0) as usize;
        format!("{v:.dec$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A standard error with two significant digits.
fn fmt_se(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    if (-4..4).contains(&mag) {
        let dec = (1 - mag).max(0) as usize;
        format!("{v:.dec$}")
    } else {
        format!("{v:.1e}")
    }
}

/// Every equation of motion with the identified values substituted. Input forces are
/// written on the right-hand side; unidentifiable parameters appear by name with `?`.
pub fn format_equations(ir: &ModelIr, id: &Identification) -> String {
    let mut out = String::new();
    for (l, eq) in ir.equations.iter().enumerate() {
        let mut lhs = String::new();
        let mut rhs = String::new();
        for t in &eq.terms {
            let (val, unc) = match t.coef.param {
                None => (Some(t.coef.scale), None),
                Some(p) => {
                    let param = &ir.params[p.index()];
                    match param.kind {
                        ParamKind::Known(v) => (Some(v * t.coef.scale), None),
                        ParamKind::Unknown { .. } => match id.param(&param.name) {
                            Some(e) => (Some(e.value * t.coef.scale), Some(e.stderr)),
                            None => (None, None),
                        },
                    }
                }
            };
            let basis = render_basis(ir, t.basis);
            let to_rhs = matches!(t.origin, TermOrigin::Input(_));
            let side = if to_rhs { &mut rhs } else { &mut lhs };
            let val = val.map(|v| if to_rhs { -v } else { v });
            let (neg, coef) = match val {
                Some(v) => {
                    let mag = v.abs();
                    let c = match unc {
                        Some(se) => format!("{}(±{}) ", fmt_num(mag), fmt_se(se)),
                        None if (mag - 1.0).abs() < 1e-15 && to_rhs => String::new(),
                        None => format!("{} ", fmt_num(mag)),
                    };
                    (v < 0.0, c)
                }
                None => {
                    let p = t.coef.param.map(|p| ir.params[p.index()].name.clone());
                    let s = if t.coef.scale == 1.0 {
                        String::new()
                    } else {
                        format!("{}·", fmt_num(t.coef.scale))
                    };
                    (false, format!("{s}?{} ", p.unwrap_or_default()))
                }
            };
            if side.is_empty() {
                if neg {
                    side.push('-');
                }
            } else {
                side.push_str(if neg { " - " } else { " + " });
            }
            match t.basis {
                // A constant force is its coefficient alone: `- 0.5000(±0.00013)`.
                Basis::Expr(e) if ir.is_constant(e) => side.push_str(coef.trim_end()),
                _ => {
                    side.push_str(&coef);
                    side.push_str(&basis);
                    // A delayed input: `u(t − 5.1e-5(±2.2e-6) s)`.
                    let delay = match t.origin {
                        TermOrigin::Input(i) => {
                            id.param(&super::input_delay::name(&ir.inputs[i.index()].name))
                        }
                        _ => None,
                    };
                    if let Some(d) = delay {
                        side.push_str(&format!(
                            "(t {} {}(±{}) s)",
                            if d.value < 0.0 { "+" } else { "−" },
                            fmt_num(d.value.abs()),
                            fmt_se(d.stderr)
                        ));
                    }
                }
            }
        }
        if rhs.is_empty() {
            rhs.push('0');
        }
        out.push_str(&format!("{}: {} = {}\n", ir.bodies[l].name, lhs, rhs));
    }
    out
}
