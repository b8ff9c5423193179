use super::idents::{f64_literal, field_ident, unique, RESERVED_CONSTS};
use super::*;

#[test]
fn type_names_are_camel_case() {
    assert_eq!(type_name("two_mass"), "TwoMass");
    assert_eq!(type_name("sdof"), "Sdof");
    assert_eq!(type_name("SDOF_rig2"), "SDOFRig2");
    assert_eq!(type_name("2dof"), "Model2dof");
}

#[test]
fn keywords_become_raw_fields() {
    assert_eq!(field_ident("k").to_string(), "k");
    assert_eq!(field_ident("type").to_string(), "r#type");
    assert_eq!(field_ident("self").to_string(), "self_");
}

#[test]
fn clashing_names_are_made_unique() {
    let names = ["M1_X", "M1_X", "SOURCE"].iter().map(|s| s.to_string());
    assert_eq!(
        unique(names, RESERVED_CONSTS),
        ["M1_X", "M1_X_1", "SOURCE_2"]
    );
}

#[test]
fn float_literals_round_trip_bit_for_bit() {
    for v in [
        0.1,
        -0.0,
        -2.5,
        1e-300,
        f64::MIN_POSITIVE,
        f64::MAX,
        f64::INFINITY,
        f64::NAN,
        std::f64::consts::PI,
    ] {
        for suffixed in [false, true] {
            let expr: syn::Expr = syn::parse2(f64_literal(v, suffixed)).unwrap();
            let text = quote!(#expr).to_string();
            let back = parse_f64_expr(&text);
            assert_eq!(back.to_bits(), v.to_bits(), "{v} printed as {text}");
        }
    }
}

/// Evaluates the three shapes `f64_tokens` emits, the way rustc would.
fn parse_f64_expr(text: &str) -> f64 {
    let t = text.replace(' ', "");
    if let Some(bits) = t.strip_prefix("f64::from_bits(") {
        return f64::from_bits(bits.trim_end_matches("u64)").parse().unwrap());
    }
    let (neg, t) = match t.strip_prefix("(-") {
        Some(rest) => (true, rest.trim_end_matches(')')),
        None => (false, t.as_str()),
    };
    let v: f64 = t.trim_end_matches("f64").parse().unwrap();
    if neg {
        -v
    } else {
        v
    }
}
