//! The identifiers and literals of the generated code: type, field, constant and local
//! names resolved once per model (sanitised, made distinct, keywords escaped), and `f64`
//! literals that parse back to the same bits.

use super::naming::type_name;
use crate::ir::ModelIr;
use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};
use std::collections::HashSet;

/// Identifiers used by the generated code, resolved once so that every item agrees.
pub(super) struct Names {
    pub(super) ty: Ident,
    pub(super) params_ty: Ident,
    /// Field of each unknown parameter, in `ir.unknowns()` order.
    pub(super) fields: Vec<Ident>,
    /// Associated constant of each signal (SignalId order).
    pub(super) signal_consts: Vec<Ident>,
    /// Local variable holding each signal's sample (SignalId order).
    pub(super) signal_locals: Vec<Ident>,
}

/// Associated items of the model struct that a signal constant must not shadow.
pub(super) const RESERVED_CONSTS: &[&str] = &[
    "NAME",
    "SOURCE",
    "PARAM_NAMES",
    "SIGNAL_NAMES",
    "N_SIGNALS",
    "N_ROOTS",
];

impl Names {
    pub(super) fn new(ir: &ModelIr) -> Self {
        let ty_name = type_name(&ir.name);
        let upper = |s: &str| sanitize(s).to_ascii_uppercase();
        let lower = |s: &str| format!("s_{}", sanitize(s).to_ascii_lowercase());
        Names {
            ty: Ident::new(&ty_name, Span::call_site()),
            params_ty: format_ident!("{}Params", ty_name),
            fields: ir
                .unknowns()
                .iter()
                .map(|p| field_ident(&ir.params[p.index()].name))
                .collect(),
            signal_consts: unique(ir.signals.iter().map(|s| upper(&s.name)), RESERVED_CONSTS)
                .iter()
                .map(|s| Ident::new(s, Span::call_site()))
                .collect(),
            signal_locals: unique(ir.signals.iter().map(|s| lower(&s.name)), &[])
                .iter()
                .map(|s| Ident::new(s, Span::call_site()))
                .collect(),
        }
    }
}

/// `m1.x` → `m1_x`: any character that cannot appear in an identifier becomes `_`.
pub(super) fn sanitize(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.starts_with(|c: char| c.is_ascii_digit()) {
        format!("_{s}")
    } else {
        s
    }
}

/// Make names distinct (and distinct from `reserved`) by appending the position.
pub(super) fn unique(names: impl Iterator<Item = String>, reserved: &[&str]) -> Vec<String> {
    let mut seen: HashSet<String> = reserved.iter().map(|s| s.to_string()).collect();
    names
        .enumerate()
        .map(|(i, n)| {
            let n = if seen.contains(&n) {
                format!("{n}_{i}")
            } else {
                n
            };
            seen.insert(n.clone());
            n
        })
        .collect()
}

/// A struct field for a parameter name; Rust keywords become raw identifiers.
pub(super) fn field_ident(name: &str) -> Ident {
    let name = sanitize(name);
    if syn::parse_str::<Ident>(&name).is_ok() {
        Ident::new(&name, Span::call_site())
    } else if matches!(name.as_str(), "self" | "Self" | "super" | "crate" | "_") {
        format_ident!("{}_", name)
    } else {
        Ident::new_raw(&name, Span::call_site())
    }
}

/// An `f64` expression that is bit-for-bit `v`, for a place where the type is known.
pub(super) fn f64_tokens(v: f64) -> TokenStream {
    f64_literal(v, false)
}

/// An `f64` expression that is bit-for-bit `v`; `suffixed` where the type is not known from
/// context (the receiver of a method call).
pub(super) fn f64_literal(v: f64, suffixed: bool) -> TokenStream {
    if !v.is_finite() {
        let bits = Literal::u64_suffixed(v.to_bits());
        return quote!(f64::from_bits(#bits));
    }
    // `Display` of f64 is the shortest representation that parses back to the same bits.
    let lit = if suffixed {
        Literal::f64_suffixed(v.abs())
    } else {
        Literal::f64_unsuffixed(v.abs())
    };
    if v.is_sign_negative() {
        quote!((-#lit))
    } else {
        quote!(#lit)
    }
}

/// A `#[doc = …]` attribute.
pub(super) fn doc(text: &str) -> TokenStream {
    quote!(#[doc = #text])
}
