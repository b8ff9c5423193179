//! Closed-loop simulation: a digital PD position controller produces one input's force.
//!
//! # The law
//!
//! `u = kp (r − x̂) + kd (ṙ − v̂) + kf ṙ`, with `r`, `ṙ` the reference position and velocity
//! and `x̂`, `v̂` what the drive measures of the controlled body:
//!
//! - `x̂` is the position, rounded to the encoder resolution when
//!   [`SimConfig::quantise`](super::SimConfig::quantise) is set (measurement noise is
//!   added to the record afterwards and never enters the loop);
//! - `v̂` is, by default, the backward difference of that position over one sample
//!   interval `Tₛ` (the last `input_oversample` fine steps), as
//!   an encoder-based drive computes it ([`VelocitySource::Difference`]); with
//!   [`VelocitySource::Tachometer`] it is the true velocity (an analog tachometer).
//!
//! The controller runs on the simulation's fine grid, `h = Ts / input_oversample`: it
//! samples the state at the start of each step and holds its output over the step (zero-
//! order hold), as a digital drive does. The recorded input is the controller's output at
//! the sample instant.
//!
//! # The reference
//!
//! A smooth random trajectory: white noise through a second-order Butterworth low-pass
//! (natural frequency `corner`, damping ratio `1/√2`), whose state is `(r, ṙ)` — position
//! and velocity are continuous, the acceleration is not. It is advanced with the exact
//! discretisation of the form filters on the fine grid, from its own random stream, and
//! scaled so that the stationary RMS of `r` is `rms × level` for experiment `level`; the
//! RMS of `ṙ` is then `corner` times that. With [`ReferenceSpec::smooth`] the trajectory
//! passes through a further first-order lag at the same corner (advanced exactly for a
//! linear input over each fine step), so `ṙ` and `r̈` are continuous. The record carries
//! `r` as the column `<body>.x_ref`, after the measured signals.
//!
//! With [`ReferenceSpec::planned`] the reference is instead a planned trajectory of
//! point-to-point moves with dwells, repeated in cycles ([`super::planned`]); the
//! controller reads its exact position and velocity at every fine step, the level scales
//! the speed of the moves, and the random settings are not used.
//!
//! Why smoothness matters: the derivative-gain part `kd ṙ` of the force inherits the
//! roughness of `ṙ`. With the plain second-order reference `ṙ` is a random walk between
//! samples, so the force carries content between samples that no sampled record shows;
//! on the standard servo axis ([`super::test_models::ServoAxis`], controller at 10 kHz,
//! 1 kHz record) it biased the identified viscous and Coulomb friction by −15 % and
//! +20 % (`tests/servo.rs` with `smooth = false`).

use super::excite::Excitation;
use super::planned::Moves;
use dynid_ir::ir::FormFilter;
use serde::{Deserialize, Serialize};

/// Damping ratio of the reference's low-pass (Butterworth).
const REFERENCE_DAMPING: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// A PD position controller closing the loop around one body through one input.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PdControl {
    /// The input the controller drives (its form filter, if any, is not used).
    pub input: String,
    /// The body whose position is controlled.
    pub body: String,
    /// Position gain (force per position unit).
    pub kp: f64,
    /// Velocity gain (force per velocity unit).
    pub kd: f64,
    /// Velocity feed-forward gain on `ṙ` (e.g. to compensate viscous friction); 0 for none.
    #[serde(default)]
    pub kf: f64,
    /// Where the velocity the law uses comes from.
    #[serde(default)]
    pub velocity: VelocitySource,
    pub reference: ReferenceSpec,
}

/// The velocity a controller feeds back.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocitySource {
    /// Backward difference of the (quantised) position over one sample interval (a
    /// difference over one fine step of a 1 µm encoder at 10 kHz is ±0.01 m/s of noise).
    #[default]
    Difference,
    /// The true velocity.
    Tachometer,
}

/// The reference trajectory: low-pass filtered white noise, or planned moves (see the
/// module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceSpec {
    /// Stationary RMS of the reference position at level 1.
    pub rms: f64,
    /// Natural frequency of the Butterworth low-pass in rad/s.
    pub corner: f64,
    /// Pass the trajectory through a further first-order lag at `corner` (a third-order
    /// trajectory): velocity and acceleration are then continuous, as a trajectory
    /// planner's are, and only the jerk is random. Without it the reference velocity is a
    /// random walk at high frequencies, and so is the derivative-gain part of the force
    /// (see the module doc). `rms` is that of the trajectory before the lag.
    #[serde(default)]
    pub smooth: bool,
    /// A planned trajectory instead of the random one: point-to-point moves with dwells,
    /// repeated in cycles from the start of the record ([`super::planned`]); level `L` of
    /// the controlled input runs the moves `L` times as fast. `rms`, `corner` and `smooth`
    /// then do not apply.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planned: Option<Moves>,
}

impl ReferenceSpec {
    /// A planned reference of `moves` (see [`ReferenceSpec::planned`]).
    pub fn planned(moves: Moves) -> Self {
        ReferenceSpec {
            rms: 0.0,
            corner: 1.0,
            smooth: false,
            planned: Some(moves),
        }
    }

    /// The generator of this reference at level `scale`, on the fine grid of `fine` steps
    /// per sample interval `sample`, the record starting after `burn_in` samples.
    pub(crate) fn excitation(
        &self,
        scale: f64,
        sample: f64,
        fine: usize,
        burn_in: usize,
    ) -> Result<Excitation, String> {
        match &self.planned {
            Some(m) => Excitation::new(
                &FormFilter::Moves {
                    distance: m.distance,
                    speed: m.speed,
                    accel: m.accel,
                    dwell: m.dwell,
                },
                scale,
                sample,
                fine,
                burn_in,
            ),
            None => Excitation::new(&self.filter(), self.intensity(scale), sample, fine, burn_in),
        }
    }

    /// A scale of the reference position at level `scale`, for the divergence check.
    pub(crate) fn position_scale(&self, scale: f64) -> f64 {
        match &self.planned {
            Some(m) => m.distance,
            None => self.rms * scale.abs(),
        }
    }

    /// The form filter that generates the reference.
    pub(crate) fn filter(&self) -> FormFilter {
        FormFilter::SecondOrder {
            freq: self.corner,
            damping: REFERENCE_DAMPING,
        }
    }

    /// White-noise intensity giving a stationary RMS of `rms × scale`:
    /// `var(r) = level² / (4 ζ ω³)` for the second-order filter.
    pub(crate) fn intensity(&self, scale: f64) -> f64 {
        self.rms * scale * (4.0 * REFERENCE_DAMPING * self.corner.powi(3)).sqrt()
    }
}

/// The controller of one run, with its reference generator and velocity memory.
pub(crate) struct Controller {
    pub(crate) input: usize,
    pub(crate) body: usize,
    kp: f64,
    kd: f64,
    kf: f64,
    velocity: VelocitySource,
    quantum: Option<f64>,
    h: f64,
    pub(crate) reference: Excitation,
    /// Quantised positions of the last fine steps, for the difference over `Tₛ`.
    history: std::collections::VecDeque<f64>,
    /// Fine steps per sample interval.
    window: usize,
    /// Lag of the smoothed trajectory: `(corner, e^{−corner h})` and its state.
    lag: Option<(f64, f64)>,
    lagged: f64,
}

impl Controller {
    /// `reference` must already be discretised for the step `h`.
    pub(crate) fn new(
        spec: &PdControl,
        input: usize,
        body: usize,
        quantum: Option<f64>,
        h: f64,
        window: usize,
        reference: Excitation,
    ) -> Self {
        Controller {
            input,
            body,
            kp: spec.kp,
            kd: spec.kd,
            kf: spec.kf,
            velocity: spec.velocity,
            quantum,
            h,
            lagged: reference.output(),
            reference,
            history: std::collections::VecDeque::with_capacity(window + 1),
            window: window.max(1),
            lag: (spec.reference.smooth && spec.reference.planned.is_none())
                .then(|| (spec.reference.corner, (-spec.reference.corner * h).exp())),
        }
    }

    /// The reference trajectory's position and velocity now.
    #[inline]
    pub(crate) fn reference(&self) -> (f64, f64) {
        match self.lag {
            Some((c, _)) => (self.lagged, c * (self.reference.output() - self.lagged)),
            None => (self.reference.output(), self.reference.derivative()),
        }
    }

    /// Advance the reference by one fine step.
    #[inline]
    pub(crate) fn step_reference(&mut self, rng: &mut impl rand::Rng) {
        let r0 = self.reference.output();
        self.reference.step(rng);
        if let Some((c, e)) = self.lag {
            // Exact for an input linear over the step.
            let r1 = self.reference.output();
            let ch = c * self.h;
            self.lagged = e * self.lagged + (1.0 - e) * r0 + (r1 - r0) * (1.0 - (1.0 - e) / ch);
        }
    }

    /// The controller output for true position `x` and velocity `v` at the current step.
    #[inline]
    pub(crate) fn output(&mut self, x: f64, v: f64) -> f64 {
        let xm = quantise(x, self.quantum);
        let vm = match self.velocity {
            VelocitySource::Tachometer => v,
            VelocitySource::Difference => match self.history.front() {
                Some(&old) => (xm - old) / (self.history.len() as f64 * self.h),
                None => 0.0,
            },
        };
        if self.history.len() == self.window {
            self.history.pop_front();
        }
        self.history.push_back(xm);
        let (r, rd) = self.reference();
        self.kp * (r - xm) + self.kd * (rd - vm) + self.kf * rd
    }
}

/// `x` rounded to the nearest multiple of `q` (unchanged without a resolution).
#[inline]
pub(crate) fn quantise(x: f64, q: Option<f64>) -> f64 {
    match q {
        // A multiple beyond the range of a double (a resolution tiny against the value)
        // leaves the value as it is: it is then already a multiple to double precision.
        Some(q) => {
            let n = (x / q).round();
            if n.is_finite() {
                q * n
            } else {
                x
            }
        }
        None => x,
    }
}
