//! Parameter identification by the covariance (filter) method.
//!
//! Each equation of motion of body `l` is linear in the unknown parameters,
//! `Σᵢ coefᵢ · basisᵢ = 0`, with `basis ∈ {static g(signals), ẋₖ, ẍₖ}`. Multiplying by an
//! instrument `ι(t)` and averaging over a record of length `T` gives one linear equation per
//! (instrument, equation, level). Derivatives are moved onto the instrument by the exact
//! finite-record identities
//!
//! ```text
//! ⟨ι ẋ⟩ = −⟨ι' x⟩ + [ι x]₀ᵀ/T,    ⟨ι ẍ⟩ = ⟨ι'' x⟩ − [ι' x]₀ᵀ/T + [ι ẋ]₀ᵀ/T,
//! ```
//!
//! so no measured signal is ever differentiated. Instruments are the states of a bank of
//! low-pass chains driven by measured positions and inputs (see [`filter`]); a state of
//! relative degree `r` has `ι'` (r ≥ 2) and `ι''` (r ≥ 3) free of the driving signal, which
//! keeps white measurement noise out of every product. Where velocities are measured the
//! balance instruments `xₖ` (virial, `⟨x ẍ⟩ = −⟨v²⟩ + [x v]/T`) and `v_l` (power balance,
//! `⟨v_l ẍ_l⟩ = [v_l²/2]/T`) can be added. Rows of all levels are stacked into one
//! least-squares problem `C p = c`, solved by SVD after row normalisation and column
//! scaling.
//!
//! # Standard errors
//!
//! A batch-means sandwich (see [`stats`]): the weighted residual rows `W (C p̂ − c)` are
//! exactly the sum of the contributions of overlapping hat-shaped time windows, each an
//! exact estimating equation of its own (see the `moments` module), levels are
//! independent, and `Cov p̂ = Σ_levels A⁺ Ŝ A⁺ᵀ` with `A = W C` and `Ŝ` the spread of the
//! window contributions. It is linear in the per-level terms, so the same record given
//! twice gives the same estimate and standard errors smaller by exactly √2. A
//! delete-one-block jackknife is not: a deleted block leaves a gap whose two boundary terms
//! (point values of a noisy velocity times an instrument) no longer cancel, so every
//! replicate carries noise the estimate itself does not have, and the replicates re-solve a
//! nonlinear problem in which that noise does not scale with the level count.
//!
//! Only rank loss removes a parameter (a zero column, or collinear columns by the condition
//! number); an estimate within [`SIGNIFICANCE_T`] standard errors of zero stays in the fit
//! and is flagged ([`ParamEstimate::significant`]). Estimates that are unphysical for the
//! kind of term they multiply are reported in [`Identification::warnings`]; a residual the
//! model cannot explain (a large relative residual, a pooled estimate outside every
//! level's) in [`Identification::fit_warnings`], with its likely cause (see [`guard`]).
//!
//! Noise in a measured signal inside a nonlinear static term (`s³`, `sign(v)`) biases its
//! moments; the first pass estimates each signal's noise level and the moments of such
//! terms are de-biased where it is significant (see [`noise`]).
//!
//! # Code map, by phase
//!
//! | phase | modules |
//! |-------|---------|
//! | entry points | `identify` ([`identify`](fn@identify), [`identify_with`], [`identify_per_level`], [`assemble`]) |
//! | the measuring pass, step by step | `measure` ([`measure`](fn@measure): `checks`, `pass`) |
//! | first pass: statistics, noise floors, screening | `first_pass` (`floor`, `screen`, `signal`) |
//! | design: the bank, the corners, the time blocks | `bank`, [`design`] |
//! | filter bank: reference chain, portable kernel, x86 vector paths | [`filter`] |
//! | accumulation of the moments, streamed | `accumulate` (`task`, `end_velocity`) |
//! | moment views: whole record, hat windows | `moments` |
//! | moment statistics as a value: design, pieces, merge, `.dynm` files | `pieces` ([`MomentStats`], [`MomentDesign`]) |
//! | noise: correction types, decision, de-biasing | [`noise`] (`fix`, `decide`, `correct`) |
//! | rows and solve | `plan`, `instruments`, `columns`, [`Measurement`], `restrict`, `solve` |
//! | statistics: standard errors, warnings | `stats` |
//! | checks of the result | [`guard`], `corners` ([`corner_moves`]) |
//! | around the method | `accel`, [`rests`], [`velocity`], [`shape`], [`memory`], [`print`], `types` |

mod accel;
mod accumulate;
mod bank;
mod columns;
mod corners;
pub mod design;
mod ends;
pub mod filter;
pub(crate) mod filtered;
mod first_pass;
pub mod guard;
mod identify;
mod input_delay;
mod instruments;
pub mod integrate;
mod measure;
mod measurement;
pub mod memory;
mod moments;
pub mod noise;
mod pieces;
mod plan;
pub mod print;
mod restrict;
pub mod rests;
pub mod shape;
mod solve;
mod stats;
mod types;
pub mod velocity;

pub use corners::{check_corners, corner_moves, CORNER_CHECK_FACTOR, CORNER_CHECK_MIN_REL};
pub use filter::Hold;
pub use identify::{accel_rows, assemble, identify, identify_per_level, identify_with, servo_rows};
pub use measure::measure;
pub use measurement::Measurement;
pub use memory::MemoryEstimate;
pub use moments::PhaseTimes;
pub use noise::NoiseSummary;
pub use pieces::{
    model_hash, DesignOptions, MomentDesign, MomentStats, MomentsError, FORMAT_VERSION, MAGIC,
};
pub use rests::RestSummary;
pub use types::*;
pub use velocity::VelocityEstimate;

#[cfg(test)]
mod tests;
