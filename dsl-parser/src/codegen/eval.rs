//! The basis evaluator of the generated code: `impl BasisEval` whose `eval_block` computes
//! [`ModelIr::eval_roots`] with straight-line code, node by node, in one loop over the
//! samples (bit-for-bit the interpreter's operations).

use super::idents::{f64_literal, f64_tokens, Names};
use super::CodegenOptions;
use crate::ir::{BinaryOp, ExprId, ExprNode, ModelIr, UnaryOp};
use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};

/// `impl BasisEval` for the model struct: one loop over the samples, straight-line code for
/// every needed node, the roots stored into the output block.
///
/// Longer than most functions here: it is a code template, and the `quote!` at its end
/// needs every piece (columns, locals, node statements, stores) in scope.
pub(super) fn basis_eval_impl(ir: &ModelIr, n: &Names, opts: &CodegenOptions) -> TokenStream {
    let krate = &opts.crate_path;
    let ty = &n.ty;
    let roots = ir.eval_roots();
    let needed = ir.needed_nodes(&roots);

    // A constant is written as an unsuffixed literal, except where it receives a method call.
    let receiver = |e: ExprId, value: &[TokenStream]| match ir.exprs[e.index()] {
        ExprNode::Const(b) => f64_literal(f64::from_bits(b), true),
        _ => value[e.index()].clone(),
    };
    // How each node is referred to: constants inline, signals and computed nodes by name.
    let mut value: Vec<TokenStream> = Vec::with_capacity(needed.len());
    let mut body = Vec::new();
    let mut helpers: Vec<&'static str> = Vec::new();
    let mut signals_read = Vec::new();
    for (i, &need) in needed.iter().enumerate() {
        let node = ir.exprs[i];
        if !need {
            value.push(TokenStream::new());
            continue;
        }
        let rhs = match node {
            ExprNode::Const(b) => {
                value.push(f64_tokens(f64::from_bits(b)));
                continue;
            }
            ExprNode::Signal(s) => {
                signals_read.push(s.index());
                let local = &n.signal_locals[s.index()];
                value.push(quote!(#local));
                continue;
            }
            _ => computed_node(node, &value, &mut helpers, receiver),
        };
        let local = format_ident!("e{}", i);
        body.push(quote!(let #local: f64 = #rhs;));
        value.push(quote!(#local));
    }
    signals_read.sort_unstable();
    signals_read.dedup();
    helpers.sort_unstable();
    helpers.dedup();

    let n_roots = Literal::usize_unsuffixed(roots.len());
    let outs: Vec<Ident> = (0..roots.len()).map(|r| format_ident!("o{}", r)).collect();
    let stores = roots.iter().zip(&outs).map(|(root, o)| {
        let v = &value[root.index()];
        quote!(#o[i] = #v;)
    });
    let cols: Vec<Ident> = signals_read
        .iter()
        .map(|&s| format_ident!("c_{}", n.signal_locals[s].to_string()))
        .collect();
    let locals = signals_read.iter().map(|&s| &n.signal_locals[s]);
    let sig_idx = signals_read.iter().map(|&s| Literal::usize_unsuffixed(s));
    let helper_idents = helpers.iter().map(|h| Ident::new(h, Span::call_site()));
    let uses = if helpers.is_empty() {
        TokenStream::new()
    } else {
        quote!(use #krate::dsl_parser::ir::{#(#helper_idents),*};)
    };
    let eval_body = if roots.is_empty() {
        quote!(let _ = (signals, len, out, scratch);)
    } else {
        quote! {
            #uses
            let _ = scratch;
            ::core::assert!(out.len() >= #n_roots * len, "output block too small");
            // Slicing every column to `len` once lets the compiler drop the bounds checks
            // in the loop.
            #(let #cols: &[f64] = &signals[#sig_idx][..len];)*
            let rest = &mut out[..#n_roots * len];
            #(let (#outs, rest) = rest.split_at_mut(len);)*
            let _ = rest;
            for i in 0..len {
                #(let #locals: f64 = #cols[i];)*
                #(#body)*
                #(#stores)*
            }
        }
    };
    quote! {
        impl #krate::runtime::BasisEval for #ty {
            fn n_roots(&self) -> usize {
                #n_roots
            }

            #[allow(clippy::all, unused_variables)]
            fn eval_block(
                &self,
                signals: &[&[f64]],
                len: usize,
                out: &mut [f64],
                scratch: &mut ::std::vec::Vec<f64>,
            ) {
                #eval_body
            }
        }
    }
}

/// The right-hand side of a computed node (not a constant nor a signal): the same
/// floating-point operations, in the same order, as the runtime tape. `value` refers to
/// the nodes before it; `receiver` writes an operand that receives a method call; the
/// helpers it calls from [`crate::ir`] are added to `helpers`.
fn computed_node(
    node: ExprNode,
    value: &[TokenStream],
    helpers: &mut Vec<&'static str>,
    receiver: impl Fn(ExprId, &[TokenStream]) -> TokenStream,
) -> TokenStream {
    match node {
        ExprNode::Unary(op, a) => {
            let a = &receiver(a, value);
            match op {
                UnaryOp::Neg => quote!(-#a),
                UnaryOp::Abs => quote!(#a.abs()),
                UnaryOp::Sign => {
                    helpers.push("sign");
                    quote!(sign(#a))
                }
                UnaryOp::Tanh => quote!(#a.tanh()),
                UnaryOp::Sqrt => quote!(#a.sqrt()),
                UnaryOp::Exp => quote!(#a.exp()),
                UnaryOp::Sin => quote!(#a.sin()),
                UnaryOp::Cos => quote!(#a.cos()),
            }
        }
        ExprNode::Binary(op, a, b) => {
            let (a, b) = (&value[a.index()], &value[b.index()]);
            match op {
                BinaryOp::Add => quote!(#a + #b),
                BinaryOp::Sub => quote!(#a - #b),
                BinaryOp::Mul => quote!(#a * #b),
                BinaryOp::Div => quote!(#a / #b),
            }
        }
        // The tape special-cases these two exponents; `a * a * a` is `(a * a) * a`.
        ExprNode::Powi(a, 2) => {
            let a = &value[a.index()];
            quote!(#a * #a)
        }
        ExprNode::Powi(a, 3) => {
            let a = &value[a.index()];
            quote!(#a * #a * #a)
        }
        ExprNode::Powi(a, k) => {
            let a = &receiver(a, value);
            let abs = Literal::u32_unsuffixed(k.unsigned_abs());
            let k = if k < 0 { quote!(-#abs) } else { quote!(#abs) };
            quote!(#a.powi(#k))
        }
        ExprNode::Deadzone(a, g) => {
            helpers.push("deadzone");
            let (a, g) = (&value[a.index()], f64_tokens(f64::from_bits(g)));
            quote!(deadzone(#a, #g))
        }
        ExprNode::Saturate(a, l) => {
            helpers.push("saturate");
            let (a, l) = (&value[a.index()], f64_tokens(f64::from_bits(l)));
            quote!(saturate(#a, #l))
        }
        ExprNode::Const(_) | ExprNode::Signal(_) => {
            unreachable!("invariant: constants and signals are referred to, not computed")
        }
    }
}
