//! One level of an excited run: the samplers of its inputs and references started from the
//! level's random stream, the integration on the fine input grid with the controller or the
//! model's control laws in the loop, and the recorded columns streamed to the level's sink.

use super::config::{sample_counts, stream_seed, SimConfig, Stream};
use super::control::Controller;
use super::driven::signal_value;
use super::error::SimError;
use super::excitation::TestSignal;
use super::excite::Excitation;
use super::guard::{check_divergence, divergence_limit, Resolution};
use super::law;
use super::mech::{Mechanics, Rk4};
use super::plan::{ControlPlan, ExcitationPlan};
use super::stream::{ColumnFinish, LevelWriter, SampleSink};
use dynid_ir::ir::{FormFilter, ModelIr, SignalKind};
use rand::rngs::StdRng;
use rand::SeedableRng;

/// Name of the reference column of a controlled body.
pub fn reference_column(body: &str) -> String {
    format!("{body}.x_ref")
}

/// How many samples pass between two progress reports.
const PROGRESS_CHUNK: usize = 8192;

/// Simulate level `level` of `plan` into `sink`: burn-in, then `n` recorded samples, each
/// interval integrated on the fine input grid, with the guards checked once a sample.
///
/// Longer than most functions here: the loop body is the simulation's inner loop (controller,
/// control laws, recording, excitation steps, hold, RK4), and its state (samplers, inputs at
/// both ends of the step, the integrator) is shared by every stage; split apart, each piece
/// would take most of that state as arguments.
pub(super) fn simulate_level(
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
    let mut control = plan
        .control
        .as_ref()
        .map(|c| start_controller(c, cfg, level, n_burn));
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
    let (names, finish) = columns(ir, plan, cfg);
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

/// The reference excitation and controller of a closed-loop run at `level`, with the
/// reference's random stream.
fn start_controller(
    c: &ControlPlan,
    cfg: &SimConfig,
    level: usize,
    n_burn: usize,
) -> (Controller, StdRng) {
    let fine = cfg.input_oversample;
    let h = cfg.sample / fine as f64;
    let mut reference = c
        .spec
        .reference
        .excitation(c.scales[level], cfg.sample, fine, n_burn)
        .expect("invariant: checked when planning");
    let mut rng = StdRng::seed_from_u64(stream_seed(cfg.seed, level, Stream::Reference));
    reference.start(&mut rng);
    let ctl = Controller::new(&c.spec, c.input, c.body, cfg.quantise, h, fine, reference);
    (ctl, rng)
}

/// The recorded columns of a level: the measured signals in IR order, and how each is
/// finished (noise, quantisation); a PD run adds its exact reference as the last column.
fn columns(
    ir: &ModelIr,
    plan: &ExcitationPlan,
    cfg: &SimConfig,
) -> (Vec<String>, Vec<ColumnFinish>) {
    let measured = ir.measured_signals();
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
    (names, finish)
}
