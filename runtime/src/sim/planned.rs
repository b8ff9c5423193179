//! Planned trajectories: point-to-point moves with smooth velocity profiles, dwells at rest
//! and a cycle repeated sample for sample — how machine-tool and robot axes are excited.
//!
//! # The cycle
//!
//! Six moves of length `distance`, out (`0 → distance`) and back (`distance → 0`) at the
//! top speeds `speed`, `speed/2` and `speed/4`, each move after `dwell` seconds at rest at
//! its start. The cycle is then padded at rest to a whole number of sample intervals, so
//! that every cycle puts its samples at the same points of the profile: the cycles of a
//! record are identical sample by sample. A record starts with a cycle (at rest: the first
//! dwell); before it (the burn-in of a simulation) the trajectory rests at 0.
//!
//! # The velocity profile of a move
//!
//! A trapezoid whose corners are blended by sine-squared acceleration pulses: over the
//! speed-up phase of length `Ta = 2V/A` the acceleration is `a(τ) = A sin²(πτ/Ta)`, so
//!
//! ```text
//! v(τ) = A (τ/2 − Ta/(4π) sin(2πτ/Ta)),     x(τ) = A (τ²/4 − Ta²/(4π²) sin²(πτ/Ta)),
//! ```
//!
//! reaching `v = V` and `x = V²/A` at `τ = Ta`; then the move cruises at `V` and slows down
//! by the mirror image. Acceleration and jerk are continuous (the jerk is
//! `A π/Ta sin(2πτ/Ta)`, zero at the ends of the pulse); the peak acceleration is `A`, the
//! mean over a pulse `A/2`. A move of length `d` at top speed `V` lasts `d/V + 2V/A` and
//! needs `d ≥ 2V²/A` (no cruise at equality); the fastest move is checked, the slower ones
//! then fit too.
//!
//! # Levels
//!
//! Level `L` runs every move `L` times as fast: top speeds `L·V`, peak accelerations
//! `L²·A`, move durations `/L`; the path and the dwells stay. Level 0 rests at 0.
//!
//! # Exactness between samples
//!
//! The profile is a closed form of the time, evaluated at each point where the simulator
//! reads it — every step `h = Ts / input_oversample` of the fine grid, at a time computed
//! from the integer sample and step indices modulo the cycle, never accumulated. A control law or PD controller samples
//! its reference there and holds its output over the step (a digital drive), so the loop
//! sees the exact profile. An *input* driven by `moves` is, like every input, interpolated
//! linearly between grid points inside the RK4 sub-steps (first-order hold).

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Fractions of `speed` of the moves of a cycle; each is used out and back.
const SPEED_FRACTIONS: [f64; 3] = [1.0, 0.5, 0.25];

/// Moves per cycle.
pub const MOVES_PER_CYCLE: usize = 2 * SPEED_FRACTIONS.len();

/// Most samples of one cycle (beyond, a cycle outlasts any record the simulator accepts).
const MAX_CYCLE_STEPS: f64 = 1e12;

/// Planned point-to-point moves (see the module doc): what `excite X: moves(...)` and a
/// planned [`super::ReferenceSpec`] describe.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Moves {
    /// Length of every move, in position units (out `0 → distance`, back `distance → 0`).
    pub distance: f64,
    /// Top speed of the fastest moves at level 1; the others run at a half and a quarter.
    pub speed: f64,
    /// Peak acceleration of every move at level 1.
    pub accel: f64,
    /// Seconds at rest before each move.
    pub dwell: f64,
}

/// Position, velocity and acceleration of a trajectory at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setpoint {
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
}

impl Moves {
    /// The moves of the servo axis's planned records
    /// ([`super::test_models::ServoAxis::planned`]): 10 cm at 0.4, 0.2 and 0.1 m/s,
    /// 4 m/s², 0.33 s dwells; a cycle lasts 6.18 s (four in a 25 s record), a third of it
    /// at rest.
    pub fn servo_standard() -> Self {
        Moves {
            distance: 0.1,
            speed: 0.4,
            accel: 4.0,
            dwell: 0.33,
        }
    }

    /// `Err(reason)` naming the argument when the moves cannot be planned: a distance, speed
    /// or acceleration that is not a finite positive number, a negative or infinite dwell,
    /// or a speed that the fastest move cannot reach.
    pub fn check(&self) -> Result<(), String> {
        for (name, v) in [
            ("distance", self.distance),
            ("speed", self.speed),
            ("accel", self.accel),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("`{name}` {v} must be a finite positive number"));
            }
        }
        if !(self.dwell.is_finite() && self.dwell >= 0.0) {
            return Err(format!(
                "`dwell` {} must be a finite number of seconds, zero or more",
                self.dwell
            ));
        }
        let needed = 2.0 * self.speed * self.speed / self.accel;
        if needed > self.distance {
            return Err(format!(
                "`speed` {} is not reached in a move of `distance` {} at `accel` {} (speeding up and slowing down take 2 speed² / accel = {})",
                self.speed,
                self.distance,
                self.accel,
                dynid_ir::num::sig(needed, 4, false)
            ));
        }
        Ok(())
    }

    /// The trajectory of level `level` sampled every `sample` seconds (the cycle is padded
    /// to whole samples). `Err(reason)` as [`Moves::check`], or for a bad level or interval
    /// or a cycle of more than 10¹² samples.
    pub fn trajectory(&self, level: f64, sample: f64) -> Result<Trajectory, String> {
        self.check()?;
        if !(level.is_finite() && level >= 0.0) {
            return Err(format!("level {level} is not a finite non-negative number"));
        }
        if !(sample.is_finite() && sample > 0.0) {
            return Err(format!("sample interval {sample} s is not positive"));
        }
        if level == 0.0 {
            return Ok(Trajectory {
                moves: Vec::new(),
                distance: self.distance,
                period: sample,
                samples: 1,
                rest: sample,
            });
        }
        let accel = self.accel * level * level;
        let mut moves = Vec::with_capacity(MOVES_PER_CYCLE);
        let mut t = 0.0;
        for (k, f) in SPEED_FRACTIONS
            .iter()
            .flat_map(|f| [f, f])
            .copied()
            .enumerate()
        {
            let speed = self.speed * f * level;
            let ramp = 2.0 * speed / accel;
            let duration = self.distance / speed + ramp;
            t += self.dwell;
            moves.push(Move {
                start: t,
                duration,
                speed,
                accel,
                ramp,
                outward: k % 2 == 0,
            });
            t += duration;
        }
        // Whole samples; a cycle that is a whole number of samples up to rounding is not
        // padded by one more.
        let exact = t / sample;
        let samples = if (exact - exact.round()).abs() <= 1e-9 * exact {
            exact.round()
        } else {
            exact.ceil()
        };
        if !(samples.is_finite() && samples <= MAX_CYCLE_STEPS) {
            return Err(format!(
                "a cycle of the moves at level {level} lasts {} s, over 10¹² samples of {sample} s",
                dynid_ir::num::sig(t, 4, false)
            ));
        }
        let samples = (samples as usize).max(1);
        let period = samples as f64 * sample;
        let moving: f64 = moves.iter().map(|m| m.duration).sum();
        Ok(Trajectory {
            moves,
            distance: self.distance,
            period,
            samples,
            rest: period - moving,
        })
    }
}

/// One move of a cycle: starts at `start` (seconds into the cycle), lasts `duration`.
#[derive(Clone, Copy, Debug)]
struct Move {
    start: f64,
    duration: f64,
    speed: f64,
    accel: f64,
    /// Length of each acceleration pulse, `2 speed / accel`.
    ramp: f64,
    /// Out `0 → distance` (else back).
    outward: bool,
}

impl Move {
    /// `(x, v, a)` of a forward move of `distance` at `tau` seconds into it.
    #[inline]
    fn local(&self, tau: f64, distance: f64) -> (f64, f64, f64) {
        let (a, ta) = (self.accel, self.ramp);
        // The speed-up pulse at `tau` in [0, ta].
        let pulse = |tau: f64| {
            let s = (PI * tau / ta).sin();
            (
                a * (0.25 * tau * tau - ta * ta / (4.0 * PI * PI) * s * s),
                a * (0.5 * tau - ta / (4.0 * PI) * (2.0 * PI * tau / ta).sin()),
                a * s * s,
            )
        };
        if tau < ta {
            pulse(tau)
        } else if tau <= self.duration - ta {
            (
                self.speed * self.speed / a + self.speed * (tau - ta),
                self.speed,
                0.0,
            )
        } else {
            let (x, v, acc) = pulse((self.duration - tau).max(0.0));
            (distance - x, v, -acc)
        }
    }
}

/// A planned trajectory at one level and sample interval (see the module doc).
#[derive(Clone, Debug)]
pub struct Trajectory {
    moves: Vec<Move>,
    distance: f64,
    period: f64,
    samples: usize,
    rest: f64,
}

impl Trajectory {
    /// The set point `t` seconds into a cycle (`t` in `[0, period)`; later times are taken
    /// modulo the period, earlier ones rest at 0).
    pub fn at(&self, t: f64) -> Setpoint {
        let t = if t >= self.period { t % self.period } else { t };
        let rest = |position| Setpoint {
            position,
            velocity: 0.0,
            acceleration: 0.0,
        };
        for m in &self.moves {
            let from = if m.outward { 0.0 } else { self.distance };
            if t < m.start {
                return rest(from);
            }
            let tau = t - m.start;
            if tau < m.duration {
                let (x, v, a) = m.local(tau, self.distance);
                return if m.outward {
                    Setpoint {
                        position: x,
                        velocity: v,
                        acceleration: a,
                    }
                } else {
                    Setpoint {
                        position: self.distance - x,
                        velocity: -v,
                        acceleration: -a,
                    }
                };
            }
        }
        rest(0.0)
    }

    /// Length of a cycle in seconds: a whole number of sample intervals.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Samples per cycle.
    pub fn samples_per_cycle(&self) -> usize {
        self.samples
    }

    /// Seconds per cycle at rest (the dwells and the padding to whole samples).
    pub fn rest_per_cycle(&self) -> f64 {
        self.rest
    }

    /// `(start, duration, top speed)` of the moves of a cycle, in order (none at level 0).
    pub fn moves(&self) -> Vec<(f64, f64, f64)> {
        self.moves
            .iter()
            .map(|m| {
                (
                    m.start,
                    m.duration,
                    if m.outward { m.speed } else { -m.speed },
                )
            })
            .collect()
    }

    /// Length of every move (the trajectory stays in `[0, distance]`).
    pub fn distance(&self) -> f64 {
        self.distance
    }
}

/// A planned trajectory advanced on the simulator's fine grid: the set point of fine step
/// `j` of sample `k` of the record is the profile at `(k mod samples per cycle)·Ts + j·h`
/// (exactly `at(k·Ts)` at the samples of the first cycle, and the same bits in every
/// cycle); before the record (the burn-in) the trajectory rests at 0.
#[derive(Clone, Debug)]
pub(crate) struct PlannedSampler {
    trajectory: Trajectory,
    sample: f64,
    h: f64,
    fine: u64,
    /// Fine steps before the record starts, counted down during the burn-in.
    wait: u64,
    /// Sample within the cycle, and fine step within the sample.
    k: u64,
    j: u64,
    now: Setpoint,
}

impl PlannedSampler {
    /// `fine` steps per sample interval `sample`; the record starts after `burn_in`
    /// samples.
    pub(crate) fn new(
        moves: &Moves,
        level: f64,
        sample: f64,
        fine: usize,
        burn_in: usize,
    ) -> Result<Self, String> {
        let trajectory = moves.trajectory(level, sample)?;
        let fine = fine.max(1) as u64;
        let mut s = PlannedSampler {
            sample,
            h: sample / fine as f64,
            fine,
            wait: burn_in as u64 * fine,
            k: 0,
            j: 0,
            now: trajectory.at(0.0),
            trajectory,
        };
        s.update();
        Ok(s)
    }

    fn update(&mut self) {
        self.now = if self.wait > 0 {
            self.trajectory.at(-1.0)
        } else {
            self.trajectory
                .at(self.k as f64 * self.sample + self.j as f64 * self.h)
        };
    }

    /// Advance by one fine step.
    #[inline]
    pub(crate) fn step(&mut self) {
        if self.wait > 0 {
            self.wait -= 1;
        } else {
            self.j += 1;
            if self.j == self.fine {
                self.j = 0;
                self.k += 1;
                if self.k == self.trajectory.samples as u64 {
                    self.k = 0;
                }
            }
        }
        self.update();
    }

    /// The set point now.
    #[inline]
    pub(crate) fn setpoint(&self) -> Setpoint {
        self.now
    }

    /// A scale of the signal for the simulator's divergence check.
    pub(crate) fn scale(&self) -> f64 {
        self.trajectory.distance
    }
}

#[cfg(test)]
mod tests;
