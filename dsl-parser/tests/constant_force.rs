//! A constant force: a term that is a parameter (times a number) and depends on no signal.
//! Its basis is the constant 1; it prints as its coefficient alone and survives the
//! round trip through `to_source`. A bare number with no parameter stays an error.

use dsl_parser::ir::{Basis, ElementKind, ExprNode, ModelIr, ParamKind};
use dsl_parser::{compile_str, print, ErrorKind};

fn model(force: &str) -> String {
    format!(
        "model offset {{
    body m = 1.0
    input u on m
    spring k (ground, m) ~ 4.0
    damper d (ground, m) ~ 0.4
    force {force}
    excite u: lowpass(corner = 10) levels [6, 15]
}}
"
    )
}

fn compile(force: &str) -> ModelIr {
    let src = model(force);
    compile_str("offset.dyn", &src).unwrap_or_else(|e| panic!("{}", e.render_plain(100)))
}

fn without_spans(mut ir: ModelIr) -> ModelIr {
    ir.spans = Default::default();
    ir
}

/// The terms of element `name` as (scale, parameter name, basis is the constant 1).
fn terms(ir: &ModelIr, name: &str) -> Vec<(f64, Option<String>, bool)> {
    let e = ir.elements.iter().find(|e| e.name == name).unwrap();
    assert_eq!(e.kind, ElementKind::Force);
    e.terms
        .iter()
        .map(|t| {
            let one = ir.expr(t.basis) == ExprNode::constant(1.0);
            assert_eq!(one, ir.is_constant(t.basis));
            (
                t.coef.scale,
                t.coef.param.map(|p| ir.params[p.index()].name.clone()),
                one,
            )
        })
        .collect()
}

#[test]
fn a_lone_parameter_is_a_constant_force_with_basis_one() {
    let ir = compile("off (ground, m) = f0 ~ -0.5");
    assert_eq!(terms(&ir, "off"), vec![(1.0, Some("f0".into()), true)]);
    let f0 = &ir.params[ir.param_id("f0").unwrap().index()];
    assert_eq!(
        f0.kind,
        ParamKind::Unknown {
            nominal: Some(-0.5)
        }
    );
    // The offset acts on m with the sign of every force term: `+ f0` on the left.
    let eq = print::render_equation(&ir, &ir.equations[0]);
    assert_eq!(eq, "m: 1 m.x'' + k m.x + d m.x' + f0 = u");
    // One static column, the constant 1, that every evaluator computes.
    let roots = ir.eval_roots();
    assert!(roots.iter().any(|&r| ir.is_constant(r)), "{roots:?}");
    let e = ir.equations[0]
        .terms
        .iter()
        .find(|t| t.coef.param == ir.param_id("f0"))
        .unwrap();
    assert!(matches!(e.basis, Basis::Expr(b) if ir.is_constant(b)));
}

#[test]
fn a_scaled_parameter_mixed_with_other_terms() {
    let ir = compile("nl (ground, m) = k3 ~ 2 * s^3 + f0 ~ -0.5 - 2 * g0 ~ 0.1 * 3");
    assert_eq!(
        terms(&ir, "nl"),
        vec![
            (1.0, Some("k3".into()), false),
            (1.0, Some("f0".into()), true),
            (-6.0, Some("g0".into()), true),
        ]
    );
    let eq = print::render_equation(&ir, &ir.equations[0]);
    assert!(eq.ends_with("+ k3 m.x^3 + f0 - 6 g0 = u"), "{eq}");
}

#[test]
fn the_column_table_names_the_constant() {
    let ir = compile("off (ground, m) = 2 * f0 ~ -0.5");
    let rows = print::column_rows(&ir);
    let f0 = rows.iter().find(|r| r.column == "f0").unwrap();
    assert_eq!(f0.basis, "2");
    assert_eq!(f0.kind, "constant (needs data with a mean)");
    let params = print::render_params(&ir);
    assert!(
        params.contains("f0") && params.contains("~ -0.5"),
        "{params}"
    );
}

#[test]
fn a_constant_force_round_trips_through_source() {
    for force in [
        "off (ground, m) = f0 ~ -0.5",
        "off (m, ground) = -f0 ~ 0.25 * 4",
        "nl (ground, m) = k3 ~ 2 * s^3 + f0 ~ -0.5",
        "nl (ground, m) = f0 ~ -0.5 + k3 ~ 2 * s^3 - f0 * 2",
    ] {
        let ir = compile(force);
        let printed = print::to_source(&ir);
        assert!(!printed.contains("* 1\n"), "{printed}");
        let again = compile_str("printed.dyn", &printed)
            .unwrap_or_else(|e| panic!("{printed}\n{}", e.render_plain(100)));
        assert_eq!(print::to_source(&again), printed);
        assert_eq!(without_spans(again), without_spans(ir), "{printed}");
    }
    let printed = print::to_source(&compile("off (ground, m) = f0 ~ -0.5"));
    assert!(
        printed.contains("force off (ground, m) = f0 ~ -0.5\n"),
        "{printed}"
    );
}

#[test]
fn a_known_constant_force_is_allowed() {
    let ir = compile("off (ground, m) = g0 = 9.81");
    assert_eq!(terms(&ir, "off"), vec![(1.0, Some("g0".into()), true)]);
    let eq = print::render_equation(&ir, &ir.equations[0]);
    assert!(eq.ends_with("+ g0 = u"), "{eq}");
}

#[test]
fn a_bare_number_is_rejected_with_a_constant_term_error() {
    let src = model("bias (ground, m) = 0.5 * 2");
    let errs = compile_str("bare.dyn", &src).unwrap_err();
    assert_eq!(errs.kinds(), vec![ErrorKind::ConstantTerm]);
    let e = &errs.errors[0];
    assert!(e.message().contains("bare number"), "{}", e.message());
    assert!(e.help_text().contains("`f0 ~ 0.5`"), "{}", e.help_text());
}

#[test]
fn a_zero_constant_term_is_rejected() {
    let src = model("bias (ground, m) = f0 ~ 1.0 * 0");
    let errs = compile_str("zero.dyn", &src).unwrap_err();
    assert_eq!(errs.kinds(), vec![ErrorKind::ConstantTerm]);
    assert!(errs.errors[0].message().contains("zero"));
}
