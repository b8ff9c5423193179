//! Regression of the filtered equation (SVF-LS).
//!
//! The causal fourth-order Butterworth state-variable filter `L` ([`StateVariableFilter`],
//! corner [`SvfOptions::corner_hz`]) applied to the position gives `L x`, `(L x)'` and
//! `(L x)''` as its states; applied to the force, `L u`. The equation filtered by `L`,
//!
//! ```text
//! m (L x)'' + fv (L x)' + fc L[sign(x')] + f0 L[1] = L u,
//! ```
//!
//! is regressed sample by sample. `sign(x')` is built from the filtered velocity `(L x)'`
//! read [`StateVariableFilter::delay`] later (the filter's group delay at low frequencies,
//! 42 samples at 10 Hz and 1 kHz), so that its switching instants are those of the
//! velocity rather than of its delayed copy, and is then filtered by `L` like every other
//! column; [`SvfOptions::align_sign`] turns the alignment off. Rows from the start until
//! the filter has forgotten its state at rest to 10⁻⁸ (four memories), and the last
//! aligned delay, are left out. The Newey–West lag is twice the filter's memory: the
//! filtered residual is correlated over the support of the autocorrelation of `L`'s
//! impulse response. By default no row is dropped at rest: a row of the filtered equation
//! mixes samples over the filter's memory. [`SvfOptions::rest`] drops every row whose
//! memory holds a sample where the aligned filtered velocity is below the threshold (the
//! rests of a planned trajectory, and the zero crossings of a random one).
//!
//! [`SvfOptions::position_noise_var`] compensates errors in the variables: white position
//! noise of variance `σ²` adds `rows · σ² · Σₖ hᵢ[k] hⱼ[k]` to the normal matrix of the
//! columns `(L x)⁽ⁱ⁾` (`hᵢ` the impulse response of state `i`), which is taken out
//! ([`super::ols`], bias-compensated least squares). Measured on the servo axis (bench
//! `servo_precision`), the encoder's rounding is not what biases the mass there.

use super::filter::StateVariableFilter;
use super::idim::sign;
use super::{check, column, ols, BaselineError, Fit, Term};
use crate::record::Record;
use nalgebra::{DMatrix, DVector};

/// Settings of [`svf_ls`].
#[derive(Clone, Debug, PartialEq)]
pub struct SvfOptions {
    /// Corner of the state-variable filter in Hz.
    pub corner_hz: f64,
    /// Build `sign(x')` from the filtered velocity advanced by the filter's group delay
    /// (default); `false` uses it as it comes out of the causal filter.
    pub align_sign: bool,
    /// The basis columns.
    pub terms: Vec<Term>,
    /// Drop the rows whose aligned filtered velocity was below this speed (m/s) at any
    /// sample of the filter's memory before them (0: keep every row).
    pub rest: f64,
    /// White noise variance of the position (m²): the part of the normal matrix that it
    /// adds to the filtered position's columns is taken out (0: no compensation).
    pub position_noise_var: f64,
}

impl SvfOptions {
    /// Corner `corner_hz`, aligned sign, [`super::SERVO_TERMS`].
    pub fn at(corner_hz: f64) -> SvfOptions {
        SvfOptions {
            corner_hz,
            align_sign: true,
            terms: super::SERVO_TERMS.to_vec(),
            rest: 0.0,
            position_noise_var: 0.0,
        }
    }
}

/// SVF-LS of the columns `position` and `force` of `rec` (see the module doc).
pub fn svf_ls(
    rec: &Record,
    position: &str,
    force: &str,
    opts: &SvfOptions,
) -> Result<Fit, BaselineError> {
    check(rec, opts.corner_hz, &opts.terms)?;
    let (x, u) = (column(rec, position)?, column(rec, force)?);
    let ts = rec.ts;
    let f = StateVariableFilter::new(opts.corner_hz, ts);
    let n = x.len();
    let (mut x0, mut x1, mut x2) = (Vec::new(), Vec::new(), Vec::new());
    f.run(x, &mut [&mut x0, &mut x1, &mut x2]);
    let mut uf = Vec::new();
    f.run(u, &mut [&mut uf]);
    let shift = if opts.align_sign {
        (f.delay() / ts).round() as usize
    } else {
        0
    };
    let mut signs = Vec::new();
    let mut sf = Vec::new();
    if opts.terms.contains(&Term::SignVelocity) {
        signs.extend((0..n).map(|k| sign(x1[(k + shift).min(n - 1)])));
        f.run(&signs, &mut [&mut sf]);
    }
    let mut ones = Vec::new();
    if opts.terms.contains(&Term::Constant) {
        f.run(&vec![1.0; n], &mut [&mut ones]);
    }
    let memory = f.memory(ts).ceil() as usize;
    let first = 4 * memory;
    let last = n.saturating_sub(shift);
    // Rows kept: none whose memory holds a sample at rest.
    let mut since_rest = memory + 1;
    let kept: Vec<usize> = (0..last)
        .filter(|&k| {
            if opts.rest > 0.0 && x1[(k + shift).min(n - 1)].abs() < opts.rest {
                since_rest = 0;
            } else {
                since_rest += 1;
            }
            k >= first && since_rest > memory
        })
        .collect();
    let rows = kept.len();
    let p = opts.terms.len();
    let mut a = DMatrix::<f64>::zeros(rows, p);
    let mut y = DVector::<f64>::zeros(rows);
    for (r, &k) in kept.iter().enumerate() {
        for (j, t) in opts.terms.iter().enumerate() {
            a[(r, j)] = match t {
                Term::Acceleration => x2[k],
                Term::Velocity => x1[k],
                Term::SignVelocity => sf[k],
                Term::Constant => ones[k],
                Term::Position => x0[k],
            };
        }
        y[r] = uf[k];
    }
    let noise = (opts.position_noise_var > 0.0).then(|| {
        // Impulse responses of (L x), (L x)', (L x)'' to one sample of position noise;
        // white noise adds rows · σ² · Σₖ hᵢ hⱼ to the normal matrix.
        let len = 8 * memory + 8;
        let mut imp = vec![0.0; len];
        imp[1] = 1.0;
        let (mut h0, mut h1, mut h2) = (Vec::new(), Vec::new(), Vec::new());
        f.run(&imp, &mut [&mut h0, &mut h1, &mut h2]);
        let h = |t: &Term| -> Option<&Vec<f64>> {
            match t {
                Term::Acceleration => Some(&h2),
                Term::Velocity => Some(&h1),
                Term::Position => Some(&h0),
                _ => None,
            }
        };
        let mut d = DMatrix::<f64>::zeros(p, p);
        for (i, ti) in opts.terms.iter().enumerate() {
            for (j, tj) in opts.terms.iter().enumerate() {
                if let (Some(hi), Some(hj)) = (h(ti), h(tj)) {
                    d[(i, j)] = rows as f64
                        * opts.position_noise_var
                        * hi.iter().zip(hj).map(|(a, b)| a * b).sum::<f64>();
                }
            }
        }
        d
    });
    ols::fit_compensated(&opts.terms, a, y, 2 * memory, noise.as_ref())
}
