//! The settings of a simulation run, their checks, and the seeds of its random streams.

use super::*;

/// Settings of a simulation run.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    /// White-noise intensities, one per experiment, applied to every excited input;
    /// `None` uses the levels of the model's `excite` lines.
    pub levels: Option<Vec<f64>>,
    /// Recorded duration per level in seconds (after the burn-in).
    pub duration: f64,
    /// Sample interval `Ts` in seconds.
    pub sample: f64,
    /// Base seed; every level derives its own streams from it.
    pub seed: u64,
    /// Measurement noise as a fraction of each signal's standard deviation.
    pub noise: f64,
    /// Whether measured inputs get measurement noise too (positions and velocities always do).
    pub noise_on_inputs: bool,
    /// RK4 steps per sample interval.
    pub substeps: usize,
    /// Seconds simulated and discarded before recording starts.
    pub burn_in: f64,
    /// Steps of the input processes per sample interval (see the module doc); 1 = the
    /// inputs are simulated at the sample rate and interpolated linearly in between.
    pub input_oversample: usize,
    /// Encoder resolution: every recorded position is rounded to a multiple of it (after
    /// the measurement noise), and a controller sees the rounded position.
    pub quantise: Option<f64>,
    /// A PD position controller producing one input (closed loop), see [`control`].
    pub control: Option<PdControl>,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            levels: None,
            duration: 2000.0,
            sample: 0.01,
            seed: 1,
            noise: 0.0,
            noise_on_inputs: true,
            substeps: DEFAULT_SUBSTEPS,
            burn_in: 100.0,
            input_oversample: 1,
            quantise: None,
            control: None,
        }
    }
}

/// Most samples (burn-in included) of one simulated level. Simulation streams (memory does
/// not grow with the duration), but 2·10⁸ samples are over 10 GB of CSV per level (about
/// 65 bytes per sample for a model with three recorded signals: 3 × 2·10⁶ samples of
/// `sdof_linear` with noise wrote 400 MB) and hours of integration: a larger request is
/// almost surely a mistyped duration or interval.
pub const MAX_SAMPLES: f64 = 2e8;

pub(super) fn check_config(cfg: &SimConfig) -> Result<(), SimError> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !positive(cfg.sample) {
        return Err(config_error(
            &format!("sample interval {} s", cfg.sample),
            "give a positive sample interval, e.g. `--sample 0.01`",
        ));
    }
    if !positive(cfg.duration) || cfg.duration < 2.0 * cfg.sample {
        return Err(config_error(
            &format!("duration {} s", cfg.duration),
            "give a duration of at least two sample intervals, e.g. `--duration 2000`",
        ));
    }
    // Refuse absurd sizes up front, before hours of work and a full disk.
    let samples = (cfg.burn_in.max(0.0) + cfg.duration) / cfg.sample;
    if samples.is_nan() || samples > MAX_SAMPLES {
        return Err(config_error(
            &format!(
                "{:.3e} samples per level ({} s at {} s)",
                samples,
                dynid_ir::num::sig(cfg.duration, 4, false),
                dynid_ir::num::sig(cfg.sample, 4, false)
            ),
            &format!(
                "a level has at most {MAX_SAMPLES:.0e} samples (over 10 GB of CSV); shorten `--duration` or lengthen `--sample`"
            ),
        ));
    }
    if !(cfg.burn_in.is_finite() && cfg.burn_in >= 0.0) {
        return Err(config_error(
            &format!("burn-in {} s", cfg.burn_in),
            "the burn-in must be zero or positive",
        ));
    }
    if !(cfg.noise.is_finite() && cfg.noise >= 0.0) {
        return Err(config_error(
            &format!("noise fraction {}", cfg.noise),
            "the noise is a fraction of each signal's std, e.g. `--noise 0.05` for 5 %",
        ));
    }
    if cfg.substeps == 0 {
        return Err(config_error(
            "0 sub-steps",
            "use at least 1 sub-step per sample",
        ));
    }
    if cfg.input_oversample == 0 {
        return Err(config_error(
            "input oversampling 0",
            "simulate the inputs with at least 1 step per sample interval (`--input-oversample 1` is the default)",
        ));
    }
    if let Some(q) = cfg.quantise {
        // A subnormal resolution makes `x / q` overflow and a quantised position infinite.
        if !positive(q) || q < f64::MIN_POSITIVE {
            return Err(config_error(
                &format!("position resolution {q}"),
                "the quantisation step is a positive encoder resolution in position units (a normal number, at least 2.2e-308), e.g. `--quantise 1e-6`",
            ));
        }
    }
    if let Some(l) = &cfg.levels {
        if let Some(bad) = l.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return Err(config_error(
                &format!("level {bad}"),
                "levels are white-noise intensities: finite and non-negative",
            ));
        }
    }
    Ok(())
}

/// RK4 steps of the mechanical model in a run of `cfg` over `n_levels` levels, burn-in
/// included (the input processes take `input_oversample` steps per sample besides).
pub fn integration_steps(cfg: &SimConfig, n_levels: usize) -> f64 {
    let fine = cfg.input_oversample.max(1) as f64;
    let per_sample = fine * (cfg.substeps as f64 / fine).ceil();
    (cfg.burn_in.max(0.0) + cfg.duration) / cfg.sample * per_sample * n_levels as f64
}

/// Refuse a run of `steps` RK4 steps above [`crate::limits::MAX_STEPS`] unless `allow`;
/// `what` names the run (`3 levels of 2.1e5 samples × 1000000 sub-steps`), `flag` the
/// option that allows it.
pub fn check_steps(steps: f64, what: &str, flag: &str, allow: bool) -> Result<(), SimError> {
    if allow || steps <= crate::limits::MAX_STEPS {
        return Ok(());
    }
    Err(SimError::TooLong {
        what: what.to_string(),
        estimate: crate::limits::steps_in_words(steps),
        help: format!(
            "runs above {:.0e} RK4 steps ({}) are refused as a likely mistyped setting: \
             lower the sub-steps, oversampling, duration or levels, or give `{flag}` to run it anyway",
            crate::limits::MAX_STEPS,
            crate::limits::duration_in_words(crate::limits::MAX_STEPS / crate::limits::STEPS_PER_SECOND)
        ),
    })
}

pub(super) fn config_error(what: &str, help: &str) -> SimError {
    SimError::InvalidConfig {
        what: what.into(),
        help: help.into(),
    }
}

/// `(burn-in samples, recorded samples)`.
pub(super) fn sample_counts(cfg: &SimConfig) -> (usize, usize) {
    (
        (cfg.burn_in / cfg.sample).round() as usize,
        (cfg.duration / cfg.sample).round() as usize,
    )
}

#[derive(Clone, Copy)]
pub(super) enum Stream {
    Excitation = 0,
    Noise = 1,
    Reference = 2,
}

/// Seed of one random stream of one level; a strong mix so nearby seeds and levels give
/// unrelated streams.
pub(super) fn stream_seed(base: u64, level: usize, stream: Stream) -> u64 {
    splitmix64(splitmix64(base) ^ splitmix64(((level as u64) << 8) | stream as u64))
}

pub(super) fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
