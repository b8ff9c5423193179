//! Measurement noise: its level per measured signal, and moments of nonlinear static terms
//! freed of the bias it causes (errors in variables).
//!
//! # Why linear terms need nothing and nonlinear ones do
//!
//! A measured signal is `y = x + n` with white noise `n` of variance `σ²`. The instruments
//! are filter states of relative degree ≥ 2, which depend on the current sample only
//! through the first-order-hold weight `Γ₁ ≈ (λTₛ)ʳ/(r+1)!`, so `⟨ζ n⟩ ≈ 0` and a column
//! linear in `y` keeps its moment. A nonlinear column does not: `E[(x+n)³] = x³ + 3σ²x`, and
//! `E[sign(v+n) | v] = erf(v/(√2 σ))` is a flattened step. The `Γ₁` part is removed as well
//! (`⟨ζᵢ y⟩` loses `Γ₁ᵢ σ²` per sample for a column linear in the driver `y`).
//!
//! The rows of the filtered equation ([`super::filtered`]) are the exception: they multiply
//! two states of the same chain, whose noise parts correlate over the chain's memory, so
//! `⟨ζᵢ ζⱼ⟩` loses `σ² Pᵢⱼ` per sample ([`crate::ident::filter::ChainDisc::noise_covariance`]).
//! Their nonlinear columns enter only through the chains they drive, which the fixes below
//! do not reach: none is attached there, and such terms are reported uncorrected.
//!
//! # Noise level
//!
//! Estimated per measured signal in the first pass, from its high-frequency floor: see
//! [`super::first_pass::floor`].
//!
//! # De-biased moments
//!
//! Only signals whose estimated noise is at least [`SIGNIFICANT`] of their standard
//! deviation are corrected; below that the bias (`∝ σ²`) is negligible next to the
//! estimates' spread (the measured errors with and without the correction are in
//! docs/performance.md, from the example `measurements -- noise`). The moments are changed
//! after accumulation, block by block, so the batch-means errors see the corrected moments too.
//!
//! - `c·sᵖ` with `s = Σ aₖ yₖ` a linear form in measured signals (noise variance
//!   `σ_s² = Σ aₖ² σₖ²`): the column becomes that of the unbiased polynomial
//!   `σ_sᵖ Heₚ(s/σ_s) = Σₘ (−1)ᵐ p!/(m!(p−2m)! 2ᵐ) σ_s²ᵐ s^{p−2m}` (probabilists' Hermite),
//!   whose expectation over the noise is `sᵖ`. The lower powers are columns already there:
//!   `s¹` is a combination of the measured signals, `s⁰` is a constant column added for
//!   the purpose, other powers must be basis terms of the model (else the term is left
//!   uncorrected and named in [`NoiseSummary::uncorrected`]).
//! - `c·sign(v)` with `v` a linear form: `sign − σ² δ'` has the expectation `sign(v)` to
//!   first order in `σ²` (`E[f(v+n)] = f(v) + σ²f''(v)/2 + …`, `sign'' = 2δ'`). The moment
//!   `⟨ι (−δ')(v)⟩` is taken with Gaussian kernels `v φ_h(v)/h²` (added columns); over the
//!   noise one of width `h` estimates `E(H) = g'(0) + g'''(0) H²/2 + …` with
//!   `g(v) = E(ι|v) p(v)` and `H² = h² + σ²`, while the exact bias of the sign moment is
//!   `σ² g'(0) + σ⁴ g'''(0)/4 + …`. A single kernel (`h = σ`: `H² = 2σ²`) over-weights the
//!   `g'''` term four times, and with the peaked velocity density of a Coulomb contact
//!   (`g''' < 0`) it under-corrected. The combination `σ² [2 E(h = σ/2) − E(h = σ)]` matches
//!   both terms. A point mass at `v = 0` (sticking) adds nothing, as it should.
//! - Other nonlinear terms in noisy signals (products, `abs`, `tanh`, dead zones) are left
//!   as they are and named in [`NoiseSummary::uncorrected`].
//!
//! [`super::IdentifyOptions::noise_correction`] switches the correction off (the CLI's
//! `--no-noise-correction`); the noise levels are estimated and reported either way.

mod correct;
mod decide;
pub(crate) mod fix;

pub(crate) use correct::{attach, debias, extra_widths};
pub(crate) use decide::{decide_designed, needs_fixes};

use serde::Serialize;
use std::collections::BTreeMap;

/// Noise below this fraction of a signal's standard deviation is left uncorrected.
pub const SIGNIFICANT: f64 = 0.02;
/// What the noise analysis found and did, over the levels of one identification.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct NoiseSummary {
    /// Estimated noise standard deviation relative to the signal's, per measured signal:
    /// the largest over the levels.
    pub fraction: BTreeMap<String, f64>,
    /// Whether the correction was enabled.
    pub enabled: bool,
    /// Terms whose moments were de-biased at one level at least.
    pub corrected: Vec<String>,
    /// Nonlinear terms in signals with significant noise that no correction covers.
    pub uncorrected: Vec<String>,
    /// Signals whose high-frequency floor is dominated by signal content at some level:
    /// their estimate is uncertain and no correction uses it.
    pub uncertain: Vec<String>,
}
