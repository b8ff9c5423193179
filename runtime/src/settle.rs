//! How long a filter chain needs to forget its start: a fact shared by identification
//! (which designs its corners so that the slowest chain settles within the record) and by
//! the data layer (which cuts a record into levels no shorter than that).
//!
//! A chain of `n` first-order sections with corner `λ` has time constant `τ = n/λ`; a record
//! must span at least `SETTLE · τ`.

/// Record length in time constants of the slowest chain.
pub const SETTLE: f64 = 10.0;
