//! Frequency response functions: the measured one of a record (H1 with coherence, by
//! Welch's averaged segments or, for periodic excitation, by per-period averaging at the
//! excited lines) and the one of a linear model from its `M`, `D`, `K` matrices.
//!
//! Both estimators stream: a [`H1Accumulator`] holds one segment per signal (a Welch
//! segment, or one period) and the averaged cross- and auto-spectra, never the record.
//!
//! - **Welch H1**: segments of `n` samples, Hann window, 50 % overlap, mean removed per
//!   segment; `H1 = S_uy / S_uu`, `γ² = |S_uy|² / (S_uu S_yy)`. Leakage and the window
//!   bias a lightly damped peak (the window's main lobe smooths it: a relative error of
//!   order `(Δf / (ζ f_n))²` at the peak), so the segment should be long against the
//!   decay time `1/(ζ ω_n)`.
//! - **Periodic**: segments of exactly one period, rectangular window, no overlap. For a
//!   periodic input in steady state the excited lines fall on bins and have no leakage:
//!   `H = S_uy / S_uu` over the periods is the FRF at the lines, biased only by noise on
//!   the input; the coherence measures the period-to-period scatter (noise, nonlinear
//!   distortion that is not periodic). Only the excited lines (`S_uu` above 1e-3 of its
//!   largest) are kept.
//!
//! The parts: `measured` (the streaming estimators), `model` (the linear model and its
//! FRF); this module holds the results and [`level_frfs`], which pairs them per level.

mod measured;
mod model;

pub use measured::{measured_frf, welch_segment, H1Accumulator};
pub use model::{model_frf, parameter_values, LinearModel};

use crate::data::{DataError, LevelSource};
use dynid_ir::ir::{InputId, ModelIr, SignalId, SignalKind};
use serde::Serialize;

/// Which estimator made a [`Frf`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FrfMethod {
    /// Welch H1: Hann-windowed segments of `segment` samples, 50 % overlap.
    Welch { segment: usize },
    /// Averages over whole periods of `period` samples, at the excited lines.
    Periodic { period: usize },
}

/// A measured FRF of one input to several responses.
#[derive(Clone, Debug, Serialize)]
pub struct Frf {
    pub method: FrfMethod,
    /// Segments (or periods) averaged.
    pub averages: usize,
    /// Frequencies of the kept bins in Hz.
    pub freq_hz: Vec<f64>,
    /// `h[j][k]`: response `j` over the input at `freq_hz[k]`, as `[re, im]`.
    pub h: Vec<Vec<[f64; 2]>>,
    /// `coherence[j][k]` in [0, 1].
    pub coherence: Vec<Vec<f64>>,
}

/// The FRF of one level: measured, and of the linear model fitted at that level.
#[derive(Clone, Debug, Serialize)]
pub struct LevelFrf {
    pub label: String,
    /// The input column the FRF is taken from.
    pub input: String,
    /// The response columns, in the order of `measured.h`.
    pub outputs: Vec<String>,
    /// Units of each response over the input (`m/N`, `(m/s)/N`), SI assumed.
    pub units: Vec<String>,
    pub measured: Frf,
    /// `model[j][k]`: the fitted linear model's FRF of response `j` at
    /// `measured.freq_hz[k]`, `[re, im]` (`null` where the model is singular or the
    /// level's fit lacks a parameter).
    pub model: Vec<Vec<Option<[f64; 2]>>>,
}

/// The FRF of every level: `sources[l]` streamed (see [`measured_frf`]) from the model's
/// first input whose column is measured to each measured position and velocity, and the
/// FRF of the linear model at `values[l]` (parameter values, index = `ParamId`; `None`:
/// no model curve). Empty when the model has no measured input or no measured response.
pub fn level_frfs(
    ir: &ModelIr,
    sources: &[&dyn LevelSource],
    labels: &[String],
    values: &[Option<Vec<f64>>],
    periods: Option<usize>,
) -> Result<Vec<LevelFrf>, DataError> {
    let measured = ir.measured_signals();
    let Some((input_idx, input)) = ir
        .inputs
        .iter()
        .enumerate()
        .map(|(i, _)| (i, ir.input_signal(InputId(i as u32))))
        .find(|(_, s)| measured.contains(s))
    else {
        return Ok(Vec::new());
    };
    let outputs: Vec<SignalId> = measured
        .iter()
        .copied()
        .filter(|&s| {
            matches!(
                ir.signal(s).kind,
                SignalKind::Position(_) | SignalKind::Velocity(_)
            )
        })
        .collect();
    if outputs.is_empty() {
        return Ok(Vec::new());
    }
    let units: Vec<String> = outputs
        .iter()
        .map(|&s| match ir.signal(s).kind {
            SignalKind::Velocity(_) => "(m/s)/N".to_string(),
            _ => "m/N".to_string(),
        })
        .collect();
    let mut out = Vec::with_capacity(sources.len());
    for (l, src) in sources.iter().enumerate() {
        let Some(measured) = measured_frf(*src, input, &outputs, periods)? else {
            continue;
        };
        let model = match values.get(l).and_then(|v| v.as_ref()) {
            Some(v) => model_frf(
                ir,
                &LinearModel::new(ir, v),
                input_idx,
                &outputs,
                &measured.freq_hz,
            ),
            None => vec![vec![None; measured.freq_hz.len()]; outputs.len()],
        };
        out.push(LevelFrf {
            label: labels
                .get(l)
                .cloned()
                .unwrap_or_else(|| format!("level {}", l + 1)),
            input: ir.signal(input).name.clone(),
            outputs: outputs.iter().map(|&s| ir.signal(s).name.clone()).collect(),
            units: units.clone(),
            measured,
            model,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
