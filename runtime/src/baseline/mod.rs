//! Reference estimators for benches and tests — **not the method**. They are the two
//! classical regressions that the covariance method is measured against on records of one
//! body, and they are kept small and plain on purpose (the whole record is held in memory;
//! nothing is designed from the data beyond what is stated here).
//!
//! Both fit the linear-in-parameters equation of one body,
//!
//! ```text
//! Σⱼ θⱼ φⱼ(x, x', x'') = u        e.g.  m x'' + fv x' + fc sign(x') + f0 = u
//! ```
//!
//! with the basis columns `φⱼ` chosen from [`Term`] ([`SERVO_TERMS`] is the servo axis
//! above), from a [`Record`] and the names of its position and force columns:
//!
//! - [`idim_ls`] — inverse-dynamics least squares: the measured position and the force both
//!   pass through the same zero-phase Butterworth low-pass (forward–backward, "parallel
//!   filtering"), velocity and acceleration are central differences of the filtered
//!   position, the rows are decimated, rows at rest (`|v|` below a threshold) are dropped,
//!   and the rows are regressed by ordinary least squares ([`idim`]).
//! - [`svf_ls`] — the filtered equation: a causal fourth-order state-variable filter `L`
//!   gives `L x`, `(L x)'`, `(L x)''` from its states (no differencing of data), every
//!   column and the force pass through `L`, and the filtered equation is regressed sample by
//!   sample ([`svf`]).
//!
//! Ordinary least squares is solved by a Householder QR of the column-scaled matrix and an
//! SVD of its triangular factor, never by the normal equations ([`ols`]); both the
//! classical standard error (residual variance times `(XᵀX)⁻¹`) and a Newey–West (HAC)
//! sandwich with a Bartlett kernel are returned, the lag of the latter chosen from the
//! memory of the filter (the filtered residuals are correlated over it).

mod filter;
mod idim;
mod ols;
mod svf;
#[cfg(test)]
mod tests;

pub use filter::{Butterworth, StateVariableFilter};
pub use idim::{idim_ls, IdimOptions};
pub use ols::Fit;
pub use svf::{svf_ls, SvfOptions};

use crate::record::Record;

/// A basis column of the regression, evaluated on the (filtered) position.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Term {
    /// `x''` (inertia).
    Acceleration,
    /// `x'` (viscous friction).
    Velocity,
    /// `sign(x')` (Coulomb friction), `0` where the velocity is exactly zero.
    SignVelocity,
    /// `1` (a constant force offset).
    Constant,
    /// `x` (a spring to a fixed point).
    Position,
}

impl Term {
    /// The column as it is printed: `x''`, `x'`, `sign(x')`, `1`, `x`.
    pub fn label(self) -> &'static str {
        match self {
            Term::Acceleration => "x''",
            Term::Velocity => "x'",
            Term::SignVelocity => "sign(x')",
            Term::Constant => "1",
            Term::Position => "x",
        }
    }
}

/// `m x'' + fv x' + fc sign(x') + f0 = u`: one body with inertia, viscous and Coulomb
/// friction and a force offset.
pub const SERVO_TERMS: [Term; 4] = [
    Term::Acceleration,
    Term::Velocity,
    Term::SignVelocity,
    Term::Constant,
];

/// Why a baseline could not be fitted.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum BaselineError {
    #[error("the record has no column `{name}` (it has {available})")]
    #[diagnostic(
        code(dynid::baseline::column),
        help("name the position and force columns as the record spells them")
    )]
    MissingColumn { name: String, available: String },
    #[error("invalid setting: {message}")]
    #[diagnostic(code(dynid::baseline::setting), help("{help}"))]
    BadSetting { message: String, help: String },
    #[error("column `{name}` is not finite at sample {at}")]
    #[diagnostic(
        code(dynid::baseline::non_finite),
        help("remove or repair the samples that are NaN or infinite")
    )]
    NonFinite { name: String, at: usize },
    #[error("{rows} rows are left for {cols} parameters")]
    #[diagnostic(
        code(dynid::baseline::too_few_rows),
        help("give a longer record, or lower the rest threshold (the rows at rest are dropped)")
    )]
    TooFewRows { rows: usize, cols: usize },
    #[error("the columns {terms} are collinear on these rows (condition number {condition:.3e})")]
    #[diagnostic(
        code(dynid::baseline::collinear),
        help("the record does not excite these terms separately; drop one of them or excite the axis differently")
    )]
    Collinear { terms: String, condition: f64 },
}

/// The named column of `rec`, checked finite.
fn column<'r>(rec: &'r Record, name: &str) -> Result<&'r [f64], BaselineError> {
    let col = rec
        .column(name)
        .ok_or_else(|| BaselineError::MissingColumn {
            name: name.to_string(),
            available: rec
                .names
                .iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", "),
        })?;
    match col.iter().position(|v| !v.is_finite()) {
        Some(at) => Err(BaselineError::NonFinite {
            name: name.to_string(),
            at,
        }),
        None => Ok(col),
    }
}

/// Checks shared by both estimators: a positive, finite sample interval, a corner below the
/// Nyquist frequency and at least one term.
fn check(rec: &Record, corner_hz: f64, terms: &[Term]) -> Result<(), BaselineError> {
    if !(rec.ts.is_finite() && rec.ts > 0.0) {
        return Err(BaselineError::BadSetting {
            message: format!("the record's sample interval is {} s", rec.ts),
            help: "give the record a positive sample interval".into(),
        });
    }
    let nyquist = 0.5 / rec.ts;
    if !(corner_hz.is_finite() && corner_hz > 0.0 && corner_hz < 0.8 * nyquist) {
        return Err(BaselineError::BadSetting {
            message: format!(
                "corner {corner_hz} Hz; it must be positive and below 0.8 × the Nyquist frequency ({} Hz)",
                0.8 * nyquist
            ),
            help: "choose a corner between the bandwidth of the motion and the Nyquist frequency".into(),
        });
    }
    if terms.is_empty() {
        return Err(BaselineError::BadSetting {
            message: "no terms to fit".into(),
            help: "give at least one term, e.g. `SERVO_TERMS`".into(),
        });
    }
    Ok(())
}
