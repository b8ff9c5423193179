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
mod law;
pub(crate) mod mech;
mod output;
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

use config::{check_config, config_error, sample_counts, stream_seed, Stream};
use driven::signal_value;
pub use error::SimError;
pub use output::{level_file_names, write_csv, CsvSink, Truth};
pub use stream::SampleSink;

use crate::describe::std_dev;
use crate::record::Record;
use control::Controller;
use dynid_ir::ir::{FormFilter, InputId, ModelIr, ParamKind, SignalKind};
use excite::Excitation;
use mech::{Mechanics, Rk4};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rayon::prelude::*;
use stream::{ColumnFinish, LevelWriter};

/// Default RK4 sub-steps per sample interval (see the module doc for the measured error).
pub const DEFAULT_SUBSTEPS: usize = 20;

/// How many samples pass between two progress reports.
const PROGRESS_CHUNK: usize = 8192;

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

/// Per-input excitation: the form filter (if excited) and the intensity at every level.
struct ExcitationPlan {
    n_levels: usize,
    /// Reported levels: the override, or the first excitation's intensities.
    levels: Vec<f64>,
    /// `filters[input] = Some((filter, intensities per level))`; `None` for inputs without
    /// an excitation and for controlled inputs.
    filters: Vec<Option<(FormFilter, Vec<f64>)>>,
    /// The same for each reference of the model's control laws (`None`: held at 0).
    references: Vec<Option<(FormFilter, Vec<f64>)>>,
    control: Option<ControlPlan>,
    /// The multisine or sweep replacing the inputs' form filters.
    signal: Option<TestSignal>,
}

/// The resolved controller of a closed-loop run.
struct ControlPlan {
    spec: PdControl,
    input: usize,
    body: usize,
    /// Scale of the reference RMS per level: the controlled input's levels (override or
    /// `excite` line), else 1.
    scales: Vec<f64>,
}

impl ExcitationPlan {
    fn new(ir: &ModelIr, cfg: &SimConfig) -> Result<Self, SimError> {
        let controlled = cfg
            .control
            .as_ref()
            .map(|c| resolve_control(ir, c))
            .transpose()?;
        if ir.excitation.is_empty() && ir.reference_excitation.is_empty() && controlled.is_none() {
            return Err(SimError::NoExcitation {
                model: ir.name.clone(),
            });
        }
        if controlled.is_some() && !ir.controls.is_empty() {
            return Err(config_error(
                "the model has its own control law and a PD controller was asked for as well",
                "drop the PD controller (`--pd`): the model's `control` line closes the loop",
            ));
        }
        let fine = cfg.input_oversample;
        let n_burn = sample_counts(cfg).0;
        let by_law = law::controlled(ir);
        let mut filters: Vec<Option<(FormFilter, Vec<f64>)>> = vec![None; ir.inputs.len()];
        let mut references: Vec<Option<(FormFilter, Vec<f64>)>> = vec![None; ir.references.len()];
        let mut control_levels = None;
        // Every excited signal, as (name, slot, filter, levels): inputs, then references.
        let excited: Vec<(String, Slot, &FormFilter, &Vec<f64>)> = ir
            .excitation
            .iter()
            .map(|ex| {
                let i = ex.input.index();
                (
                    ir.inputs[i].name.clone(),
                    Slot::Input(i),
                    &ex.filter,
                    &ex.levels,
                )
            })
            .chain(ir.reference_excitation.iter().map(|ex| {
                let k = ex.reference.index();
                (
                    ir.references[k].name.clone(),
                    Slot::Reference(k),
                    &ex.filter,
                    &ex.levels,
                )
            }))
            .collect();
        let first = excited.first();
        let mut seen = std::collections::HashSet::new();
        for (name, slot, filter, ex_levels) in &excited {
            if !seen.insert(*slot) {
                return Err(SimError::ExcitedTwice {
                    input: name.clone(),
                });
            }
            let levels = match (&cfg.levels, first) {
                (Some(l), _) => l.clone(),
                (None, Some(first)) => {
                    if ex_levels.len() != first.3.len() {
                        return Err(SimError::LevelCountMismatch {
                            first: first.0.clone(),
                            n_first: first.3.len(),
                            other: name.clone(),
                            n_other: ex_levels.len(),
                        });
                    }
                    (*ex_levels).clone()
                }
                (None, None) => unreachable!("an excitation exists"),
            };
            if let Slot::Input(i) = *slot {
                if controlled.map(|c| c.0) == Some(i) {
                    control_levels = Some(levels);
                    continue;
                }
                if by_law[i] {
                    // Computed by its law; an excitation read from JSON is not used.
                    continue;
                }
            }
            // Discretise once up front so a bad filter fails before any work is done.
            for &l in &levels {
                Excitation::new(filter, l, cfg.sample, fine, n_burn).map_err(|reason| {
                    SimError::BadFormFilter {
                        input: name.clone(),
                        reason,
                    }
                })?;
            }
            match *slot {
                Slot::Input(i) => filters[i] = Some(((*filter).clone(), levels)),
                Slot::Reference(k) => references[k] = Some(((*filter).clone(), levels)),
            }
        }
        let levels = cfg
            .levels
            .clone()
            .or_else(|| first.map(|f| f.3.clone()))
            .unwrap_or_else(|| vec![1.0]);
        if levels.is_empty() {
            return Err(SimError::NoLevels);
        }
        let control = match (controlled, &cfg.control) {
            (Some((input, body)), Some(spec)) => {
                let scales = control_levels.unwrap_or_else(|| vec![1.0; levels.len()]);
                for &s in &scales {
                    let r = &spec.reference;
                    r.excitation(s, cfg.sample, fine, n_burn).map_err(|reason| {
                        config_error(
                            &format!("the reference of the controller: {reason}"),
                            if r.planned.is_some() {
                                "give the planned moves a positive distance, speed and acceleration, a dwell of zero or more, a speed the moves can reach (distance ≥ 2 speed² / accel), and non-negative levels"
                            } else {
                                "give the reference a positive corner frequency and a finite, non-negative RMS"
                            },
                        )
                    })?;
                }
                Some(ControlPlan {
                    spec: spec.clone(),
                    input,
                    body,
                    scales,
                })
            }
            _ => None,
        };
        Ok(ExcitationPlan {
            n_levels: levels.len(),
            levels,
            filters,
            references,
            control,
            signal: None,
        })
    }

    /// `(name, filter, intensities)` of every input and reference driven by its form
    /// filter.
    fn level_table(&self, ir: &ModelIr) -> Vec<(String, FormFilter, Vec<f64>)> {
        let table = |names: Vec<&String>, f: &[Option<(FormFilter, Vec<f64>)>]| {
            f.iter()
                .zip(names)
                .filter_map(|(f, name)| {
                    f.as_ref()
                        .map(|(f, l)| (name.clone(), f.clone(), l.clone()))
                })
                .collect::<Vec<_>>()
        };
        let mut out = table(ir.inputs.iter().map(|i| &i.name).collect(), &self.filters);
        out.extend(table(
            ir.references.iter().map(|r| &r.name).collect(),
            &self.references,
        ));
        out
    }
}

/// An excited signal of the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Slot {
    Input(usize),
    Reference(usize),
}

/// `(input index, body index)` of a controller, and a check of its gains and reference.
fn resolve_control(ir: &ModelIr, c: &PdControl) -> Result<(usize, usize), SimError> {
    let input = ir
        .inputs
        .iter()
        .position(|i| i.name == c.input)
        .ok_or_else(|| {
            config_error(
                &format!(
                    "the controlled input `{}` is not an input of the model",
                    c.input
                ),
                &format!(
                    "name one of the model's inputs: {}",
                    ir.inputs
                        .iter()
                        .map(|i| format!("`{}`", i.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
        })?;
    let body = ir
        .bodies
        .iter()
        .position(|b| b.name == c.body)
        .ok_or_else(|| {
            config_error(
                &format!(
                    "the controlled body `{}` is not a body of the model",
                    c.body
                ),
                &format!(
                    "name one of the model's bodies: {}",
                    ir.bodies
                        .iter()
                        .map(|b| format!("`{}`", b.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
        })?;
    if ![c.kp, c.kd, c.kf].iter().all(|g| g.is_finite()) {
        return Err(config_error(
            &format!("controller gains kp {}, kd {}, kf {}", c.kp, c.kd, c.kf),
            "controller gains must be finite numbers",
        ));
    }
    let r = &c.reference;
    if r.planned.is_none()
        && !(r.rms.is_finite() && r.rms >= 0.0 && r.corner.is_finite() && r.corner > 0.0)
    {
        return Err(config_error(
            &format!("reference RMS {} and corner {}", r.rms, r.corner),
            "the reference needs a finite, non-negative RMS and a positive corner frequency in rad/s",
        ));
    }
    Ok((input, body))
}

/// Name of the reference column of a controlled body.
pub fn reference_column(body: &str) -> String {
    format!("{body}.x_ref")
}

fn simulate_level(
    ir: &ModelIr,
    mech: &Mechanics,
    plan: &ExcitationPlan,
    cfg: &SimConfig,
    level: usize,
    progress: &(dyn Fn(u64) + Sync),
    sink: &mut dyn SampleSink,
) -> Result<(), SimError> {
    let signal = plan.signal.as_ref();
    let fine = cfg.input_oversample;
    let h = cfg.sample / fine as f64;
    let substeps = cfg.substeps.div_ceil(fine);
    let (n_burn, n) = sample_counts(cfg);
    let mut rng = StdRng::seed_from_u64(stream_seed(cfg.seed, level, Stream::Excitation));
    let mut samplers = start_samplers(&plan.filters, level, cfg, signal, n_burn, &mut rng);
    // References are drawn after the inputs from the same stream, so a model without
    // references gives the same inputs as before they existed.
    let mut ref_samplers = start_samplers(&plan.references, level, cfg, None, n_burn, &mut rng);
    let mut laws = law::Laws::new(ir);
    let mut control = plan.control.as_ref().map(|c| {
        let r = &c.spec.reference;
        let mut reference = r
            .excitation(c.scales[level], cfg.sample, fine, n_burn)
            .expect("invariant: checked when planning");
        let mut rng = StdRng::seed_from_u64(stream_seed(cfg.seed, level, Stream::Reference));
        reference.start(&mut rng);
        let ctl = Controller::new(&c.spec, c.input, c.body, cfg.quantise, h, fine, reference);
        (ctl, rng)
    });
    let control_scale = plan.control.as_ref().map_or(0.0, |c| {
        c.spec.kp.abs() * c.spec.reference.position_scale(c.scales[level])
    });
    let limit = divergence_limit(
        samplers
            .iter()
            .chain(&ref_samplers)
            .flatten()
            .map(|s| s.output_std())
            .chain([control_scale]),
    );
    let measured = ir.measured_signals();
    let has_acc = measured
        .iter()
        .any(|&s| matches!(ir.signal(s).kind, SignalKind::Acceleration(_)));
    let mut names: Vec<String> = measured
        .iter()
        .map(|&s| ir.signal(s).name.clone())
        .collect();
    let mut finish: Vec<ColumnFinish> = measured
        .iter()
        .map(|&s| {
            let kind = &ir.signal(s).kind;
            ColumnFinish {
                // Inputs are noisy only on request; a reference (a set point) never is.
                noisy: match kind {
                    SignalKind::Input(_) => cfg.noise_on_inputs,
                    SignalKind::Reference(_) => false,
                    _ => true,
                },
                quantised: matches!(kind, SignalKind::Position(_)),
            }
        })
        .collect();
    if let Some(c) = &plan.control {
        // The reference is exact: neither noisy nor quantised.
        names.push(reference_column(&ir.bodies[c.body].name));
        finish.push(ColumnFinish {
            noisy: false,
            quantised: false,
        });
    }
    let context = || {
        format!(
            "level {} (intensity {})",
            level + 1,
            dynid_ir::num::sig(plan.levels[level], 6, false)
        )
    };
    let mut out = LevelWriter::new(
        sink,
        &names,
        cfg.sample,
        finish,
        cfg.noise,
        cfg.quantise,
        context(),
    )?;
    let mut row = vec![0.0; names.len()];
    let mut rk = Rk4::new(mech);
    let mut res = Resolution::new(mech.n_bodies);
    let read = |s: &[Option<Excitation>], u: &mut [f64]| {
        for (u, s) in u.iter_mut().zip(s) {
            *u = s.as_ref().map_or(0.0, |s| s.output());
        }
    };
    let mut u0 = vec![0.0; samplers.len()];
    let mut u1 = vec![0.0; samplers.len()];
    let mut r = vec![0.0; ref_samplers.len()];
    read(&samplers, &mut u0);
    read(&ref_samplers, &mut r);
    let mut pending = 0;
    for k in 0..n_burn + n {
        for j in 0..fine {
            if let Some((ctl, _)) = &mut control {
                let b = ctl.body;
                u0[ctl.input] = ctl.output(rk.x[b], rk.v[b]);
            }
            if let Some(laws) = &mut laws {
                if let Some(bad) = laws.apply(&rk.x, &rk.v, &r, &mut u0) {
                    let value = u0[ir.controls[bad].input.index()];
                    let time = (k * fine + j) as f64 * h;
                    let start = n_burn as f64 * cfg.sample;
                    let when = law::run_time(time, start);
                    return Err(law::law_error(ir, bad, value, context(), when));
                }
            }
            if j == 0 && k >= n_burn {
                if has_acc {
                    rk.refresh_accel(mech, &u0);
                }
                for (v, &s) in row.iter_mut().zip(&measured) {
                    *v = signal_value(ir, s, &rk, &u0, &r);
                }
                if let Some((ctl, _)) = &control {
                    row[measured.len()] = ctl.reference().0;
                }
                out.sample(row.iter().copied())?;
            }
            for s in samplers.iter_mut().flatten() {
                s.step(&mut rng);
            }
            for s in ref_samplers.iter_mut().flatten() {
                s.step(&mut rng);
            }
            read(&samplers, &mut u1);
            read(&ref_samplers, &mut r);
            if let Some((ctl, rng)) = &mut control {
                // Zero-order hold of the controller output over the step.
                u1[ctl.input] = u0[ctl.input];
                ctl.step_reference(rng);
            }
            if let Some(laws) = &laws {
                laws.hold(&u0, &mut u1);
            }
            rk.advance(mech, &u0, &u1, h, substeps);
            std::mem::swap(&mut u0, &mut u1);
        }
        let when = || law::run_time((k as f64 + 1.0) * cfg.sample, n_burn as f64 * cfg.sample);
        check_divergence(&rk, limit, context, when)?;
        if k >= n_burn {
            res.add(&rk.x);
        }
        pending += 1;
        if pending == PROGRESS_CHUNK {
            progress(pending as u64);
            res.check(ir, cfg.sample, context)?;
            pending = 0;
        }
    }
    progress(pending as u64);
    res.check(ir, cfg.sample, context)?;
    let mut rng = StdRng::seed_from_u64(stream_seed(cfg.seed, level, Stream::Noise));
    out.finish(&mut rng)
}

/// The excitations of one level (`None` where a signal is not excited), started from `rng`
/// in order; `signal` replaces every form filter.
fn start_samplers(
    plans: &[Option<(FormFilter, Vec<f64>)>],
    level: usize,
    cfg: &SimConfig,
    signal: Option<&TestSignal>,
    n_burn: usize,
    rng: &mut StdRng,
) -> Vec<Option<Excitation>> {
    let mut out: Vec<Option<Excitation>> = plans
        .iter()
        .map(|f| {
            f.as_ref().map(|(filter, levels)| {
                if let Some(sig) = signal {
                    return Excitation::signal(
                        sig,
                        levels[level],
                        cfg.sample,
                        cfg.input_oversample,
                        n_burn,
                        sample_counts(cfg).1,
                    )
                    .expect("invariant: the signal and levels were checked when planning");
                }
                Excitation::new(
                    filter,
                    levels[level],
                    cfg.sample,
                    cfg.input_oversample,
                    n_burn,
                )
                .expect("invariant: checked when planning")
            })
        })
        .collect();
    for s in out.iter_mut().flatten() {
        s.start(rng);
    }
    out
}

/// Largest `ω·Ts` (ω = dominant angular frequency of a body's motion) accepted: about four
/// samples per period. Beyond it the record aliases and the integration is untrustworthy.
const MAX_OMEGA_TS: f64 = 1.5;

/// Running moments of each body's position and its sample-to-sample change, to estimate
/// `ω·Ts ≈ std(Δx) / std(x)` without storing the trajectory.
struct Resolution {
    prev: Vec<f64>,
    sum: Vec<f64>,
    sum2: Vec<f64>,
    dsum2: Vec<f64>,
    n: usize,
}

impl Resolution {
    fn new(nb: usize) -> Self {
        Resolution {
            prev: vec![0.0; nb],
            sum: vec![0.0; nb],
            sum2: vec![0.0; nb],
            dsum2: vec![0.0; nb],
            n: 0,
        }
    }

    #[inline]
    fn add(&mut self, x: &[f64]) {
        for (i, &x) in x.iter().enumerate() {
            if self.n > 0 {
                let d = x - self.prev[i];
                self.dsum2[i] += d * d;
            }
            self.prev[i] = x;
            self.sum[i] += x;
            self.sum2[i] += x * x;
        }
        self.n += 1;
    }

    fn check(&self, ir: &ModelIr, ts: f64, context: impl Fn() -> String) -> Result<(), SimError> {
        if self.n < 2 {
            return Ok(());
        }
        let n = self.n as f64;
        for (i, body) in ir.bodies.iter().enumerate() {
            let mean = self.sum[i] / n;
            let var = (self.sum2[i] / n - mean * mean).max(0.0);
            let dvar = self.dsum2[i] / (n - 1.0);
            if dvar > MAX_OMEGA_TS * MAX_OMEGA_TS * var && dvar > 0.0 {
                return Err(SimError::UnderResolved {
                    context: context(),
                    body: body.name.clone(),
                    omega_ts: (dvar / var).sqrt(),
                    samples_per_period: 2.0 * std::f64::consts::PI * (var / dvar).sqrt(),
                    ts,
                });
            }
        }
        Ok(())
    }
}

fn check_divergence(
    rk: &Rk4,
    limit: f64,
    context: impl Fn() -> String,
    when: impl Fn() -> String,
) -> Result<(), SimError> {
    let m = rk.magnitude();
    // An infinite limit (an input of infinite intensity) must not let `inf <= inf` pass.
    if m.is_finite() && m <= limit {
        return Ok(());
    }
    Err(SimError::Diverged {
        context: context(),
        when: when(),
        what: if m.is_finite() {
            format!("state magnitude {m:.3e} exceeds {limit:.1e}")
        } else {
            "the state is no longer finite".into()
        },
    })
}

fn divergence_limit(input_stds: impl Iterator<Item = f64>) -> f64 {
    1e6 * (1.0 + input_stds.fold(0.0, f64::max))
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
