//! The identification filter bank: chains of first-order low-pass sections, discretised
//! exactly for piecewise-linear (first-order-hold) input.
//!
//! One chain per (driving signal `s`, corner `λ`) of order `n`:
//!
//! ```text
//! ζ₁' = λ (s − ζ₁),   ζᵢ' = λ (ζᵢ₋₁ − ζᵢ)  (i = 2 … n)
//! ```
//!
//! so state `ζᵢ` has relative degree `i` with respect to `s`. In state form the whole bank is
//! `ζ' = F ζ + H s` with block-diagonal `F`. Sampling with interval `Tₛ` and assuming `s` linear
//! between samples, the exact recursion is
//!
//! ```text
//! ζ[k+1] = Φ ζ[k] + Γ₀ s[k] + Γ₁ s[k+1]
//! ```
//!
//! with `Φ, Γ₀, Γ₁` read off the matrix exponential of the augmented generator
//! `[[F Tₛ, H Tₛ, 0], [0, 0, 1], [0, 0, 0]]` (state `[ζ, s, Δs]`). A zero-order hold instead
//! (`Γ₀ = ∫Φ H`, `Γ₁ = 0`) delays the input by half a sample, which at `Tₛ = 0.01 s` biases a
//! damping estimate by tens of percent; it is kept only for the comparison test.
//!
//! # Layout
//!
//! - [`chain`]: the exact discretisation of one chain ([`ChainDisc`]), the reference every
//!   other path is checked against.
//! - `layout`: the whole bank in structure-of-arrays form ([`FilterBank`], [`BankState`]),
//!   which every path reads.
//! - `bank`: construction, free response (binary powers of `Φ`), and the dispatch of
//!   [`FilterBank::advance`] to a kernel.
//! - `kernel`: the portable kernel — one step of a block of [`LANES`] chains, as fused
//!   multiply-adds in a fixed order.
//! - `x86`: the AVX and AVX-512 paths, the same operations in the same order on wider
//!   vectors (bit for bit the portable kernel's outputs).
//! - `tests`: the paths against each other and against the reference chain.

mod bank;
pub mod chain;
mod kernel;
mod layout;
#[cfg(test)]
mod tests;
#[cfg(target_arch = "x86_64")]
mod x86;
#[cfg(target_arch = "x86_64")]
pub(crate) use x86::{has_avx512, has_avx_fma};

pub use chain::{ChainDisc, Hold};
pub use layout::LANES;
pub use layout::{BankState, FilterBank, MAX_ORDER};
