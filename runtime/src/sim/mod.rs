//! Simulation of a [`ModelIr`] under random excitation, or driven by measured inputs.
//!
//! # What is simulated
//!
//! - **Parameters**: known values, and the nominal value of every unknown parameter (an
//!   unknown parameter without a nominal value is an error that names it).
//! - **Excitation** (Schiehlen & Krause eq. 2; docs/method.md, References): each input
//!   with an `excite` line is the output of its form filter driven by white noise of the
//!   level's intensity; see [`excite`] for the exact discretisation. Inputs without an `excite` line are identically zero. Level `k`
//!   of every excited input is simulated together as experiment `k`. An `excite … moves(…)`
//!   line drives its input or reference by planned point-to-point moves instead, repeated
//!   in cycles from the first recorded sample and evaluated in closed form at every step of
//!   the input grid; see [`planned`].
//! - **Mechanics**: `ẍ = −M⁻¹ r(x, v, u)` from the equations `Σ coef·basis = 0`, integrated
//!   by classical RK4 with `substeps` fixed steps per sample interval, starting at rest at
//!   the origin; the first `burn_in` seconds are discarded so the record is (close to)
//!   stationary.
//! - **Input between samples**: the form filter is advanced exactly on a grid of
//!   `h = Ts / input_oversample` and the input is interpolated *linearly* between grid
//!   points inside the RK4 sub-steps (first-order hold), with `⌈substeps / input_oversample⌉`
//!   RK4 steps per grid interval. With `input_oversample = 1` (the default) the grid is the
//!   sample grid: the identification discretises its filters for exactly this input, so
//!   its instruments carry no hold-model mismatch; but a polyline has a kink at every
//!   sample, which the trapezoid rule of the moments integrates with an error of order
//!   `(λTₛ)²/12` (the noise-free bias of docs/method.md §3, shown in `input_path_tests`:
//!   it vanishes with a smooth input drawn on a finer grid). With a finer grid the input has content
//!   between samples, as a physical input does, and the record holds point samples of it
//!   (no anti-alias averaging); the intensity keeps its meaning, so a low-pass input has the
//!   same variance at the samples (test `oversampling_keeps_the_input_statistics_at_the_samples`)
//!   and departs from the line through them by the variance of its Ornstein–Uhlenbeck bridge
//!   (3.7 % of its variance for corner 10 rad/s, Ts = 0.01 s, test
//!   `input_between_samples_has_the_variance_of_the_form_filter`). A `White` form filter
//!   draws one value of variance `level²/h` per grid point.
//! - **Quantisation**: with `quantise = Some(q)` every recorded position is rounded to a
//!   multiple of `q` after the measurement noise; velocities and inputs are not. Which
//!   signals are recorded is the model's `measure` list.
//! - **Closed loop**: a model's `control` laws compute their inputs from the state and the
//!   references (excited like inputs, recorded as columns) on the fine grid with a
//!   zero-order hold; driven runs read the references from the data (see `law`).
//!   Alternatively [`SimConfig::control`] (`simulate --pd`), a PD position controller
//!   with an encoder-difference velocity, produces one input from a random reference or
//!   planned moves ([`ReferenceSpec::planned`]); the record then gets that reference as
//!   the extra last column `<body>.x_ref`. See [`control`].
//! - **Measurement noise**: white Gaussian, standard deviation `noise · std(signal)` per
//!   measured signal (std of the clean record of that level), from an RNG stream separate
//!   from the excitation, so switching noise on or off leaves the clean trajectory intact.
//! - **Streaming**: [`simulate_into`] hands each level to a [`SampleSink`] chunk by chunk
//!   (a CSV writer for `dynid simulate`), so memory does not grow with the duration; with
//!   noise the clean columns pass through temporary files first (see `stream`). The
//!   in-memory [`simulate`] is the same code with a collecting sink, and both give the same
//!   bits.
//! - **Determinism**: the random streams (excitation, noise, reference) of level `k` are
//!   seeded from `(seed, k, stream)` only, so results are bit-identical whatever the number
//!   of threads.
//!
//! # Integration error
//!
//! Classical RK4 has a local error of order `h⁵`; a Coulomb term makes it first order in
//! the step, since RK4 steps across velocity reversals blindly. [`DEFAULT_SUBSTEPS`] keeps
//! the error on the SDOF benchmark well below the identification floors of the method
//! (≥ 1e-3 relative): the measurement, and the command that prints it, are in
//! docs/performance.md ("Measurements behind defaults").
//!
//! # Divergence
//!
//! A state entry that is not finite or exceeds `1e6 · (1 + largest input std)` stops the
//! run with [`SimError::Diverged`], naming the level and time. A bounded but runaway motion
//! (dominant frequency above ≈ 1.5/Ts, fewer than about four samples per period) is
//! [`SimError::UnderResolved`]: such a record aliases and cannot be trusted.

mod config;
pub mod control;
mod driven;
mod error;
pub mod excitation;
pub(crate) mod excite;
mod guard;
mod law;
mod level;
pub(crate) mod mech;
mod output;
mod plan;
pub mod planned;
mod stream;
#[doc(hidden)]
#[cfg(any(test, feature = "test-support"))]
pub mod test_models;

pub use config::{check_steps, integration_steps, SimConfig};
pub use control::{PdControl, ReferenceSpec, VelocitySource};
pub use driven::{simulate_driven, simulate_driven_from, Start, FREE_RUN_START};
pub use excitation::{Grid, Phases, SweepLaw, TestSignal};
pub use planned::{Moves, Setpoint, Trajectory};

use config::{check_config, config_error, sample_counts};
pub use error::SimError;
pub use output::{level_file_names, write_csv, CsvSink, Truth};
pub use stream::SampleSink;

use crate::record::Record;
use dynid_ir::ir::{ModelIr, ParamKind};
pub use level::reference_column;
use level::simulate_level;
use mech::Mechanics;
use plan::ExcitationPlan;
use rayon::prelude::*;

/// Default RK4 sub-steps per sample interval (see the module doc for the measured error).
pub const DEFAULT_SUBSTEPS: usize = 20;

/// The simulated records, one per level, and what was simulated.
#[derive(Clone, Debug)]
pub struct SimOutput {
    /// One record per level, columns = measured signals in IR signal order.
    pub records: Vec<Record>,
    /// Everything needed to reproduce the run and to score an identification.
    pub truth: Truth,
}

/// Simulate every excitation level of `ir` (levels run in parallel).
pub fn simulate(ir: &ModelIr, cfg: &SimConfig) -> Result<SimOutput, SimError> {
    simulate_with_progress(ir, cfg, &|_| {})
}

/// [`simulate`], calling `progress(n)` after every `n` further samples (burn-in included)
/// of any level; the total is `levels × round((burn_in + duration) / sample)`.
pub fn simulate_with_progress(
    ir: &ModelIr,
    cfg: &SimConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<SimOutput, SimError> {
    let n = level_count(ir, cfg)?;
    let mut records: Vec<Record> = (0..n).map(|_| Record::default()).collect();
    let mut sinks: Vec<&mut dyn SampleSink> = records
        .iter_mut()
        .map(|r| r as &mut dyn SampleSink)
        .collect();
    let truth = simulate_into(ir, cfg, progress, &mut sinks)?;
    Ok(SimOutput { records, truth })
}

/// Number of experiments (levels) `cfg` simulates for `ir`: one sink each for
/// [`simulate_into`].
pub fn level_count(ir: &ModelIr, cfg: &SimConfig) -> Result<usize, SimError> {
    check_config(cfg)?;
    Ok(ExcitationPlan::new(ir, cfg)?.n_levels)
}

/// Simulate every excitation level into its sink (`sinks[k]` receives level `k`; levels
/// run in parallel), streaming: memory does not grow with the duration. Returns what was
/// simulated. Calls `progress(n)` as [`simulate_with_progress`] does.
pub fn simulate_into(
    ir: &ModelIr,
    cfg: &SimConfig,
    progress: &(dyn Fn(u64) + Sync),
    sinks: &mut [&mut dyn SampleSink],
) -> Result<Truth, SimError> {
    simulate_signal_into(ir, cfg, None, progress, sinks)
}

/// [`simulate_into`] with every excited input driven by `signal` (a multisine or sweep,
/// see [`excitation`]) at the levels of the run instead of its form filter; `None` is
/// [`simulate_into`]. The truth records the signal.
pub fn simulate_signal_into(
    ir: &ModelIr,
    cfg: &SimConfig,
    signal: Option<&TestSignal>,
    progress: &(dyn Fn(u64) + Sync),
    sinks: &mut [&mut dyn SampleSink],
) -> Result<Truth, SimError> {
    check_config(cfg)?;
    if let Some(sig) = signal {
        let (_, n) = sample_counts(cfg);
        sig.check(n, cfg.sample, cfg.input_oversample)
            .map_err(|(what, help)| config_error(&what, &help))?;
    }
    let params = parameter_values(ir)?;
    let mut plan = ExcitationPlan::new(ir, cfg)?;
    plan.signal = signal.copied();
    let mech = Mechanics::new(ir, &params)?;
    assert_eq!(
        sinks.len(),
        plan.n_levels,
        "invariant: one sink per level (`level_count`)"
    );
    crate::first_error_in_order(
        sinks
            .par_iter_mut()
            .enumerate()
            .map(|(k, sink)| simulate_level(ir, &mech, &plan, cfg, k, progress, &mut **sink)),
    )?;
    let mut truth = Truth::new(ir, cfg, &params, &plan.level_table(ir), &plan.levels);
    truth.signal = signal.copied();
    Ok(truth)
}

/// [`simulate`] with every excited input driven by `signal` (see [`simulate_signal_into`]).
pub fn simulate_signal(
    ir: &ModelIr,
    cfg: &SimConfig,
    signal: &TestSignal,
) -> Result<SimOutput, SimError> {
    let n = level_count(ir, cfg)?;
    let mut records: Vec<Record> = (0..n).map(|_| Record::default()).collect();
    let mut sinks: Vec<&mut dyn SampleSink> = records
        .iter_mut()
        .map(|r| r as &mut dyn SampleSink)
        .collect();
    let truth = simulate_signal_into(ir, cfg, Some(signal), &|_| {}, &mut sinks)?;
    Ok(SimOutput { records, truth })
}

/// Total number of samples [`simulate_with_progress`] reports for `cfg` and `n_levels`.
pub fn total_samples(cfg: &SimConfig, n_levels: usize) -> u64 {
    let (n_burn, n) = sample_counts(cfg);
    (n_burn as u64)
        .saturating_add(n as u64)
        .saturating_mul(n_levels as u64)
}

/// Value of every parameter (index = `ParamId`): the known value or the nominal one.
/// Unknown parameters without a nominal value are an error naming all of them.
pub fn parameter_values(ir: &ModelIr) -> Result<Vec<f64>, SimError> {
    let missing: Vec<String> = ir
        .params
        .iter()
        .filter(|p| p.nominal().is_none())
        .map(|p| p.name.clone())
        .collect();
    if !missing.is_empty() {
        return Err(SimError::MissingNominal {
            model: ir.name.clone(),
            names: missing,
        });
    }
    Ok(ir
        .params
        .iter()
        .map(|p| match p.kind {
            ParamKind::Known(v) => v,
            ParamKind::Unknown { nominal } => nominal.unwrap_or(f64::NAN),
        })
        .collect())
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod input_path_tests;
