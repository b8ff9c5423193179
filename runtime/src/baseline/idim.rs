//! Inverse-dynamics least squares (IDIM-LS).
//!
//! 1. The position `x` and the force `u` pass through the same zero-phase Butterworth
//!    low-pass ([`Butterworth::filtfilt`], order [`IdimOptions::order`], corner
//!    [`IdimOptions::corner_hz`]): filtering both sides alike keeps the equation between
//!    them, and the force's noise above the corner goes with the position's.
//! 2. Velocity and acceleration are central differences of the filtered position,
//!    `v = (x̃ₖ₊₁ − x̃ₖ₋₁) / 2Tₛ`, `a = (x̃ₖ₊₁ − 2x̃ₖ + x̃ₖ₋₁) / Tₛ²`.
//! 3. Rows within the filter's memory (1 % envelope) of either end are discarded (the edge
//!    extension continues value and slope, not curvature), then every `D`-th row is kept:
//!    by default `D = ⌊f_s / (2 f_c)⌋`, the sample spacing at which the filtered band is
//!    sampled at its Nyquist rate — the filtered residual is correlated over about
//!    `1 / (2 f_c)`, so closer rows add little information and make the classical standard
//!    error too small.
//! 4. Rows at rest (`|v|` below [`IdimOptions::rest`]) are dropped: there the Coulomb force
//!    is anywhere in `±fc` and the model does not hold.
//! 5. Ordinary least squares ([`super::ols`]); the Newey–West lag is twice the filter's
//!    memory (the support of the forward–backward kernel's autocorrelation), in kept rows.

use super::filter::{memory_samples, Butterworth};
use super::{check, column, ols, BaselineError, Fit, Term};
use crate::record::Record;
use nalgebra::{DMatrix, DVector};

/// Settings of [`idim_ls`].
#[derive(Clone, Debug, PartialEq)]
pub struct IdimOptions {
    /// Corner of the Butterworth low-pass in Hz (each pass −3 dB there).
    pub corner_hz: f64,
    /// Order of the Butterworth low-pass (each pass).
    pub order: usize,
    /// Keep every `D`-th row; `None`: `⌊f_s / (2 f_c)⌋` (at least 1).
    pub decimation: Option<usize>,
    /// Rows with `|v|` below this (m/s, or the position's unit per second) are dropped.
    pub rest: f64,
    /// The basis columns.
    pub terms: Vec<Term>,
}

impl Default for IdimOptions {
    /// 100 Hz, order 4, automatic decimation, rest below 1 mm/s, [`super::SERVO_TERMS`].
    fn default() -> Self {
        IdimOptions {
            corner_hz: 100.0,
            order: 4,
            decimation: None,
            rest: 1e-3,
            terms: super::SERVO_TERMS.to_vec(),
        }
    }
}

/// IDIM-LS of the columns `position` and `force` of `rec` (see the module doc).
pub fn idim_ls(
    rec: &Record,
    position: &str,
    force: &str,
    opts: &IdimOptions,
) -> Result<Fit, BaselineError> {
    check(rec, opts.corner_hz, &opts.terms)?;
    if opts.order == 0 || opts.order > 16 {
        return Err(BaselineError::BadSetting {
            message: format!("filter order {}", opts.order),
            help: "choose an order from 1 to 16 (4 is usual)".into(),
        });
    }
    if opts.decimation == Some(0) || !(opts.rest >= 0.0 && opts.rest.is_finite()) {
        return Err(BaselineError::BadSetting {
            message: format!(
                "decimation {:?}, rest threshold {}",
                opts.decimation, opts.rest
            ),
            help: "the decimation is at least 1 and the rest threshold a finite, non-negative velocity".into(),
        });
    }
    let (x, u) = (column(rec, position)?, column(rec, force)?);
    let ts = rec.ts;
    let memory = memory_samples(opts.order, opts.corner_hz, ts).ceil() as usize;
    let dec = opts
        .decimation
        .unwrap_or_else(|| ((0.5 / ts / opts.corner_hz).floor() as usize).max(1));
    let filter = Butterworth::lowpass(opts.order, opts.corner_hz, ts);
    let (mut xf, mut uf) = (Vec::new(), Vec::new());
    filter.filtfilt(x, 2 * memory, &mut xf);
    filter.filtfilt(u, 2 * memory, &mut uf);
    let n = x.len();
    let edge = memory.max(1);
    let p = opts.terms.len();
    // Candidate rows, then the design matrix of those kept.
    let rows: Vec<usize> = (edge..n.saturating_sub(edge))
        .step_by(dec)
        .filter(|&k| ((xf[k + 1] - xf[k - 1]) / (2.0 * ts)).abs() >= opts.rest)
        .collect();
    let mut a = DMatrix::<f64>::zeros(rows.len(), p);
    let mut y = DVector::<f64>::zeros(rows.len());
    for (r, &k) in rows.iter().enumerate() {
        let v = (xf[k + 1] - xf[k - 1]) / (2.0 * ts);
        let acc = (xf[k + 1] - 2.0 * xf[k] + xf[k - 1]) / (ts * ts);
        for (j, t) in opts.terms.iter().enumerate() {
            a[(r, j)] = match t {
                Term::Acceleration => acc,
                Term::Velocity => v,
                Term::SignVelocity => sign(v),
                Term::Constant => 1.0,
                Term::Position => xf[k],
            };
        }
        y[r] = uf[k];
    }
    let lag = (2 * memory).div_ceil(dec);
    ols::fit(&opts.terms, a, y, lag)
}

/// `sign(v)`, zero at zero.
pub(super) fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}
