//! The plan of a run, made once before any level is simulated: which signal each input and
//! reference follows (its form filter and intensity per level, a planned-move law, or a
//! controller's output) and the resolved PD controller of `simulate --pd`. Every filter and
//! reference is discretised here once, so a bad one fails before any work is done.

use super::config::{config_error, sample_counts, SimConfig};
use super::control::PdControl;
use super::error::SimError;
use super::excitation::TestSignal;
use super::excite::Excitation;
use super::law;
use dynid_ir::ir::{FormFilter, ModelIr};

/// Per-input excitation: the form filter (if excited) and the intensity at every level.
pub(super) struct ExcitationPlan {
    pub(super) n_levels: usize,
    /// Reported levels: the override, or the first excitation's intensities.
    pub(super) levels: Vec<f64>,
    /// `filters[input] = Some((filter, intensities per level))`; `None` for inputs without
    /// an excitation and for controlled inputs.
    pub(super) filters: Vec<Option<(FormFilter, Vec<f64>)>>,
    /// The same for each reference of the model's control laws (`None`: held at 0).
    pub(super) references: Vec<Option<(FormFilter, Vec<f64>)>>,
    pub(super) control: Option<ControlPlan>,
    /// The multisine or sweep replacing the inputs' form filters.
    pub(super) signal: Option<TestSignal>,
}

/// The resolved controller of a closed-loop run.
pub(super) struct ControlPlan {
    pub(super) spec: PdControl,
    pub(super) input: usize,
    pub(super) body: usize,
    /// Scale of the reference RMS per level: the controlled input's levels (override or
    /// `excite` line), else 1.
    pub(super) scales: Vec<f64>,
}

/// An excited signal of the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Slot {
    Input(usize),
    Reference(usize),
}

/// One `excite` line of the model: the signal's name and slot, its form filter and levels.
struct Excited<'a> {
    name: String,
    slot: Slot,
    filter: &'a FormFilter,
    levels: &'a Vec<f64>,
}

impl ExcitationPlan {
    /// The plan of `cfg` for `ir`: every excited signal's filter and levels (the override,
    /// or the `excite` lines, which must agree in count), discretised once to fail early,
    /// and the controller of `--pd` with its reference checked at every level.
    pub(super) fn new(ir: &ModelIr, cfg: &SimConfig) -> Result<Self, SimError> {
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
        let excited = excited_signals(ir);
        let first = excited.first();
        let mut seen = std::collections::HashSet::new();
        for ex in &excited {
            if !seen.insert(ex.slot) {
                return Err(SimError::ExcitedTwice {
                    input: ex.name.clone(),
                });
            }
            let levels = signal_levels(cfg, first, ex)?;
            if let Slot::Input(i) = ex.slot {
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
                Excitation::new(ex.filter, l, cfg.sample, fine, n_burn).map_err(|reason| {
                    SimError::BadFormFilter {
                        input: ex.name.clone(),
                        reason,
                    }
                })?;
            }
            match ex.slot {
                Slot::Input(i) => filters[i] = Some((ex.filter.clone(), levels)),
                Slot::Reference(k) => references[k] = Some((ex.filter.clone(), levels)),
            }
        }
        let levels = cfg
            .levels
            .clone()
            .or_else(|| first.map(|f| f.levels.clone()))
            .unwrap_or_else(|| vec![1.0]);
        if levels.is_empty() {
            return Err(SimError::NoLevels);
        }
        let control = match (controlled, &cfg.control) {
            (Some((input, body)), Some(spec)) => {
                let scales = control_levels.unwrap_or_else(|| vec![1.0; levels.len()]);
                check_reference(spec, &scales, cfg)?;
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
    pub(super) fn level_table(&self, ir: &ModelIr) -> Vec<(String, FormFilter, Vec<f64>)> {
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

/// Every excited signal of the model: inputs, then references.
fn excited_signals(ir: &ModelIr) -> Vec<Excited<'_>> {
    ir.excitation
        .iter()
        .map(|ex| {
            let i = ex.input.index();
            Excited {
                name: ir.inputs[i].name.clone(),
                slot: Slot::Input(i),
                filter: &ex.filter,
                levels: &ex.levels,
            }
        })
        .chain(ir.reference_excitation.iter().map(|ex| {
            let k = ex.reference.index();
            Excited {
                name: ir.references[k].name.clone(),
                slot: Slot::Reference(k),
                filter: &ex.filter,
                levels: &ex.levels,
            }
        }))
        .collect()
}

/// The intensities of `ex` per level: the run's override, else its own `levels`, which must
/// be as many as those of the first excitation.
fn signal_levels(
    cfg: &SimConfig,
    first: Option<&Excited>,
    ex: &Excited,
) -> Result<Vec<f64>, SimError> {
    match (&cfg.levels, first) {
        (Some(l), _) => Ok(l.clone()),
        (None, Some(first)) => {
            if ex.levels.len() != first.levels.len() {
                return Err(SimError::LevelCountMismatch {
                    first: first.name.clone(),
                    n_first: first.levels.len(),
                    other: ex.name.clone(),
                    n_other: ex.levels.len(),
                });
            }
            Ok(ex.levels.clone())
        }
        (None, None) => unreachable!("an excitation exists"),
    }
}

/// Discretise the controller's reference at every level scale, so that a bad one fails
/// before any work is done.
fn check_reference(spec: &PdControl, scales: &[f64], cfg: &SimConfig) -> Result<(), SimError> {
    let n_burn = sample_counts(cfg).0;
    let r = &spec.reference;
    for &s in scales {
        r.excitation(s, cfg.sample, cfg.input_oversample, n_burn)
            .map_err(|reason| {
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
    Ok(())
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
