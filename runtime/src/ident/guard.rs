//! A guard against estimates the data do not support although every number is finite: a
//! residual the model cannot explain is reported with its likely cause, so that a wrong
//! model or a damaged record never passes as an identification.
//!
//! Two symptoms are checked, from what identification has already computed:
//!
//! - **A large relative residual**: an equation whose weighted rows leave more than
//!   [`RESIDUAL_WARN`] of their norm unexplained at every level (`‖W (C p̂ − c)‖ / ‖W c‖`,
//!   [`EquationResidual`]). A model that holds leaves what noise, the record's end effects
//!   and estimated velocities leave: at most 0.01 on the clean and 5 %-noisy records of
//!   `guard_is_quiet_on_clean_and_noisy_records` (tests/silent_nonsense.rs), but up to
//!   0.49 at one level of short records that hold little information (a free mass over
//!   25 s, `tests/short_records.rs`; 0.11–0.49 over its three levels) and 0.16–0.28 for a
//!   closed-loop axis over 20 s (`tests/codegen_parity.rs`). A defect of the model shows at
//!   every level (0.37–0.41 for a mass fixed at half its value, 0.54–0.64 for a missing
//!   body, 0.84–0.98 for a sensor offset, in the same tests), so the smallest residual
//!   over the levels is what is judged. On records whose every accelerometer is noisy
//!   (estimated noise of [`NOISY_ACCELERATION`] of its spread or more), not
//!   where at every level the residual is what the noise of the data alone would leave
//!   ([`EquationResidual::noise`]): at most [`NOISE_MARGIN`] times that and not below a
//!   [`NOISE_BELOW`]th of it. There many instrument rows are mostly noise, and a model that
//!   holds left 2.5–5.2 times the input's norm on the shaker's body of a five-body
//!   structure at 5 % noise (noise alone: 1.7–4.4, printed by
//!   `noisy_accelerations_are_no_missing_body` in `tests/accel_structure.rs`), which read
//!   as a missing body. A residual
//!   far below its noise is no such excuse: the estimate then cancels within the whole
//!   record what it does not within its windows (the three-body model of the same
//!   records: 0.6–1.1 against noise of 100–1000, measured once with the CLI). Nor is the
//!   excuse taken elsewhere: the windows' scatter at a wrong estimate carries the misfit
//!   too (the servo axis with its constant force withheld, one record of 25 s: residual
//!   0.88, noise alone 2.4, measured once on the records of
//!   `identify_warns_of_a_withheld_constant_force` in `tests/servo_offset.rs`, which
//!   fails when that warning is lost).
//! - **Levels that disagree**: a pooled estimate outside every level's own estimate by more
//!   than [`LEVEL_SPREAD_T`] of that level's standard errors. Pooling averages the levels'
//!   equations, so for a model that holds it lies among them; outside all of them, no
//!   single set of parameters describes the levels.
//!
//! Two levels with the same record (the same length and, to the last bit, the same mean,
//! spread and noise of every signal) are reported too: the record counts twice.
//!
//! Either symptom of a misfit starts one probe: the model with an unknown constant force on every body,
//! measured again on the same data. A constant offset `x0` of a position sensor enters the
//! equation of a body held by a spring `k` as the constant force `k·x0` (a constant added
//! to `x` is a constant in `k·x`), which no other term can take up: the model then fits the
//! offset with the wrong stiffness and damping and leaves a large residual. When the probe
//! explains the data (its residuals below [`RESIDUAL_WARN`] and at most
//! [`PROBE_SHRINK`] of the model's), the likely cause is a sensor offset (or an unmodelled
//! constant force: gravity, a preload, an amplifier bias). Otherwise, where the equation's
//! mass is fixed in the model, a second probe identifies it: when that explains the data,
//! the fixed mass is likely wrong. Else a body or an element that the data show is missing.

use super::measure::measure;
use super::measurement::Measurement;
use super::types::{
    EquationResidual, FitCheck, FitWarning, Identification, IdentifyOptions, LevelInfo, LikelyCause,
};
use crate::data::LevelSource;
use crate::tape::Tape;
use dynid_ir::edit::NewTerm;
use dynid_ir::ir::{Coef, ModelIr, ParamId, ParamIr, ParamKind, SignalIr, SignalKind};

/// Relative residual of an equation above which, at every level, the model does not
/// explain the data (see the module doc for the figures it is set from).
pub const RESIDUAL_WARN: f64 = 0.25;

/// A residual at most this many times what noise alone would leave
/// ([`EquationResidual::noise`]) is noise's: a factor two in the residual's norm is four in
/// its square, the sum of many rows' squared residuals whose mean is one where the model
/// holds.
pub const NOISE_MARGIN: f64 = 2.0;

/// A residual below this fraction of what noise alone would leave is not noise's: the
/// estimate cancels over the whole record what its windows do not (a model far from the
/// data), so the windows' scatter cannot vouch for it.
pub const NOISE_BELOW: f64 = 10.0;

/// The estimated noise, as a fraction of the signal's standard deviation, from which a
/// measured acceleration counts as noisy: where every one of a record's accelerometers is,
/// a residual within [`NOISE_MARGIN`] of what noise alone would leave is the noise's (see
/// the module doc).
pub const NOISY_ACCELERATION: f64 = 0.005;

/// The measured accelerations of `ir`.
pub(super) fn measured_accelerations(ir: &ModelIr) -> impl Iterator<Item = &SignalIr> {
    ir.signals
        .iter()
        .filter(|s| s.measured && matches!(s.kind, SignalKind::Acceleration(_)))
}

/// Whether `ir` measures accelerations and every one of them carries estimated noise of
/// at least [`NOISY_ACCELERATION`] of its spread (`noise`: the fractions of the
/// identification's [`super::noise::NoiseSummary`]).
fn noisy_accelerations(ir: &ModelIr, noise: &super::noise::NoiseSummary) -> bool {
    let mut accelerations = measured_accelerations(ir).peekable();
    accelerations.peek().is_some()
        && accelerations.all(|s| {
            noise
                .fraction
                .get(&s.name)
                .is_some_and(|f| *f >= NOISY_ACCELERATION)
        })
}

/// A pooled estimate further than this many of a level's standard errors from that level's
/// estimate, at every level, means the levels disagree.
pub const LEVEL_SPREAD_T: f64 = 6.0;

/// The constant-force probe explains a residual when it leaves at most this fraction of it.
pub const PROBE_SHRINK: f64 = 0.3;

/// The smallest and the largest of an equation's residuals over the levels (`None` when
/// one is not finite).
fn range(r: &EquationResidual) -> Option<(f64, f64)> {
    if r.per_level.is_empty() || r.per_level.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(
        r.per_level
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            }),
    )
}

/// Whether the residual of `r` is not what noise alone would leave at some level: above
/// [`NOISE_MARGIN`] times it or below a [`NOISE_BELOW`]th of it (true where the noise was
/// not estimated).
fn beyond_noise(r: &EquationResidual) -> bool {
    r.noise.len() != r.per_level.len()
        || !r
            .per_level
            .iter()
            .zip(&r.noise)
            .all(|(v, n)| *v <= NOISE_MARGIN * n && *v >= n / NOISE_BELOW)
}

/// The largest residual of any equation at any level.
fn worst(id: &Identification) -> f64 {
    id.residual
        .iter()
        .flat_map(|r| r.per_level.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
}

/// The warnings of the pooled identification `id` from the moments `m` of `levels`.
///
/// Long: the symptoms and the probes that name a cause share the residuals and the probe
/// identifications, each computed once, in the order of the module documentation.
pub(crate) fn check(
    m: &Measurement<'_>,
    id: &Identification,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Vec<FitWarning> {
    let mut out = duplicates(id);
    // Where every accelerometer is noisy, a residual may be the noise's (see the module
    // doc); elsewhere the windows' scatter at a wrong estimate carries the misfit too.
    let noisy = noisy_accelerations(m.ir, &id.noise);
    let large: Vec<(&EquationResidual, f64, f64)> = id
        .residual
        .iter()
        .filter_map(|r| range(r).map(|(lo, hi)| (r, lo, hi)))
        .filter(|(r, lo, _)| *lo > RESIDUAL_WARN && (!noisy || beyond_noise(r)))
        .collect();
    let disagree = levels_disagree(m, id);
    if large.is_empty() && disagree.is_empty() {
        return out;
    }
    let offset = offset_probe(m.ir, id, levels, opts);
    for (r, lo, hi) in large {
        let body = m.ir.bodies.iter().find(|b| b.name == r.equation);
        let fixed_mass = body.and_then(|b| match b.mass.param {
            None => Some(b.mass.scale),
            Some(p) if !m.ir.params[p.index()].is_unknown() => {
                m.ir.params[p.index()].nominal().map(|x| x * b.mass.scale)
            }
            Some(_) => None,
        });
        let (lo_pc, hi_pc) = (format!("{:.0}", 100.0 * lo), format!("{:.0}", 100.0 * hi));
        let share = if r.per_level.len() > 1 && lo_pc != hi_pc {
            format!("{lo_pc}–{hi_pc} % of its filtered data unexplained at every level")
        } else if r.per_level.len() > 1 {
            format!("{hi_pc} % of its filtered data unexplained at every level")
        } else {
            format!("{hi_pc} % of its filtered data unexplained")
        };
        let seen = format!(
            "the equation of `{}` leaves {share} (a model that holds leaves a few per cent)",
            r.equation,
        );
        let freed = match (&offset, fixed_mass) {
            (None, Some(_)) => mass_probe(m.ir, &r.equation, levels, opts),
            _ => None,
        };
        let (cause, why) = match (&offset, fixed_mass, freed) {
            (Some(o), _, _) => (o.cause(), o.advice(Some(&r.equation))),
            (None, Some(mass), Some((value, after))) => (
                LikelyCause::WrongMass,
                format!(
                    "the mass of `{}` is fixed at {} in the model, and identified it comes out \
                     {} with a residual of {:.1} %: the fixed mass is likely wrong (or the \
                     force scale: the input's units or gain) — check it, or declare it \
                     unknown (`body {} ~ {}`)",
                    r.equation,
                    dynid_ir::num::sig(mass, 4, false),
                    dynid_ir::num::sig(value, 4, false),
                    100.0 * after,
                    r.equation,
                    dynid_ir::num::sig(value, 4, false),
                ),
            ),
            _ => (
                LikelyCause::MissingBody,
                "the model lacks a force the data show: most likely a missing body (the \
                 record comes from a system with more degrees of freedom) or a missing \
                 element; the estimates are not those of the system — compare the model's \
                 structure with the rig (`dynid diagnose` searches for missing effects)"
                    .to_string(),
            ),
        };
        out.push(FitWarning {
            check: FitCheck::LargeResidual,
            cause,
            subject: r.equation.clone(),
            value: lo,
            message: format!("{seen}: {why}"),
        });
    }
    for (name, pooled, nearest, t) in disagree {
        let (cause, why) = match &offset {
            Some(o) => (o.cause(), o.advice(None)),
            None => (
                LikelyCause::LevelsInconsistent,
                "no single set of parameters describes the levels: a level from another \
                 set-up or in other units, or an effect that changes with the amplitude and \
                 is missing from the model (`dynid detect` tests for one)"
                    .to_string(),
            ),
        };
        out.push(FitWarning {
            check: FitCheck::LevelsDisagree,
            cause,
            message: format!(
                "the pooled estimate of `{name}` ({}) lies outside every level's own (nearest \
                 {}, {t:.0} of its standard errors away): {why}",
                dynid_ir::num::sig(pooled, 4, false),
                dynid_ir::num::sig(nearest, 4, false),
            ),
            subject: name,
            value: t,
        });
    }
    out
}

/// Levels that are one record given twice: the same length, sample interval, and the same
/// first-pass mean, spread and noise of every signal, to the last bit (distinct records
/// never agree in all of them).
fn duplicates(id: &Identification) -> Vec<FitWarning> {
    let same = |a: &LevelInfo, b: &LevelInfo| {
        a.samples == b.samples
            && a.ts == b.ts
            && a.mean == b.mean
            && a.std == b.std
            && a.noise == b.noise
    };
    let mut out = Vec::new();
    for (j, b) in id.levels.iter().enumerate() {
        if let Some(a) = id.levels[..j].iter().find(|a| same(a, b)) {
            out.push(FitWarning {
                check: FitCheck::DuplicateLevel,
                cause: LikelyCause::SameRecordTwice,
                subject: b.origin.clone(),
                value: 0.0,
                message: format!(
                    "{} holds the same record as {}: it counts twice, so the standard errors \
                     come out √2 too small — give each level once",
                    b.origin, a.origin
                ),
            });
        }
    }
    out
}

/// Parameters whose pooled estimate lies outside every level's own: `(name, pooled,
/// nearest level's value, distance in that level's standard errors)`.
fn levels_disagree(m: &Measurement<'_>, id: &Identification) -> Vec<(String, f64, f64, f64)> {
    let n = m.levels().len();
    if n < 2 {
        return Vec::new();
    }
    let per_level: Vec<Identification> = (0..n).map(|i| m.identify_level(i)).collect();
    id.params
        .iter()
        .filter(|p| p.value.is_finite())
        .filter_map(|p| {
            let own: Vec<(f64, f64)> = per_level
                .iter()
                .map(|l| l.param(&p.name).map(|e| (e.value, e.stderr)))
                .collect::<Option<Vec<_>>>()?;
            if own.iter().any(|(v, s)| !(v.is_finite() && s.is_finite())) {
                return None;
            }
            let (lo, hi) = own
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (v, _)| {
                    (a.min(*v), b.max(*v))
                });
            if (lo..=hi).contains(&p.value) {
                return None;
            }
            let (near, t) = own
                .iter()
                .map(|(v, s)| (*v, (p.value - v).abs() / s.max(f64::MIN_POSITIVE)))
                .min_by(|a, b| a.1.total_cmp(&b.1))?;
            (t > LEVEL_SPREAD_T).then(|| (p.name.clone(), p.value, near, t))
        })
        .collect()
}

/// What the constant-force probe found: the largest residual with a constant force on
/// every body, and the measured position whose mean lies furthest from zero.
struct Offset {
    residual: f64,
    /// `(signal, mean, mean / std)` over the levels.
    position: Option<(String, f64, f64)>,
    /// The probe's constant force on each body, `(body, f0, its standard error)`, as
    /// `force off (ground, body) = f0` writes it (in N).
    forces: Vec<(String, f64, f64)>,
    /// Whether a force of the model depends on a position (a spring, a nonlinear
    /// stiffness): only then can a zero offset of a position sensor act as a constant force.
    position_dependent: bool,
}

impl Offset {
    fn cause(&self) -> LikelyCause {
        if self.position_dependent {
            LikelyCause::SensorOffset
        } else {
            LikelyCause::ConstantForce
        }
    }

    /// What to do, for the equation of `body` where there is one.
    fn advice(&self, body: Option<&str>) -> String {
        let pos = match &self.position {
            Some((s, mean, z)) => format!(
                " (`{s}` has mean {}, {z:.1} standard deviations from zero)",
                dynid_ir::num::sig(*mean, 3, false)
            ),
            None => String::new(),
        };
        // The constant force on the equation's body, else on every body.
        let sized: Vec<String> = self
            .forces
            .iter()
            .filter(|(b, ..)| body.is_none_or(|e| e == b))
            .map(|(b, f, se)| {
                format!(
                    "{} ± {} N on `{b}`",
                    dynid_ir::num::sig(*f, 3, false),
                    dynid_ir::num::sig(*se, 2, false)
                )
            })
            .collect();
        let sized = if sized.is_empty() {
            String::new()
        } else {
            format!(" (identified: {})", sized.join(", "))
        };
        let f0 = match self
            .forces
            .iter()
            .find(|(b, ..)| body.is_none_or(|e| e == b))
        {
            Some((_, f, _)) => format!(" ~ {}", dynid_ir::num::sig(*f, 3, false)),
            None => String::new(),
        };
        if !self.position_dependent {
            // No force depends on a position: a zero offset of a position sensor enters no
            // equation, so the constant force is a force.
            return format!(
                "with a constant force on every body{sized} the residual falls to {:.1} %: \
                 the data carry a mean force the model cannot produce, so the likely cause \
                 is an unmodelled constant force (gravity on an inclined axis, a cable, an \
                 amplifier's bias) — add it to the model (`force off (ground, {}) = \
                 f0{f0}`); the other estimates are biased until then",
                100.0 * self.residual,
                body.unwrap_or("BODY")
            );
        }
        format!(
            "with a constant force on every body{sized} the residual falls to {:.1} %, so \
             the likely cause is a zero offset of a position sensor{pos} or an unmodelled \
             constant force (gravity, a preload, an amplifier bias) — subtract the sensor's \
             reading at rest from its column, or add a constant force to the model \
             (`force off (ground, {}) = f0{f0}`), which takes up an offset `x0` of a body \
             held by a spring `k` as `f0 = −k·x0`",
            100.0 * self.residual,
            body.unwrap_or("BODY")
        )
    }
}

/// Identify the model with the fixed mass of body `body` made unknown: `(its estimate, the
/// largest residual left)` when that explains the residual (below [`RESIDUAL_WARN`]).
fn mass_probe(
    ir: &ModelIr,
    body: &str,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Option<(f64, f64)> {
    let mut probe = ir.clone();
    let b = probe.bodies.iter().position(|b| b.name == body)?;
    let name = match probe.bodies[b].mass.param {
        Some(p) => {
            let q = &mut probe.params[p.index()];
            let v = q.nominal()?;
            q.kind = ParamKind::Unknown { nominal: Some(v) };
            q.name.clone()
        }
        None => {
            let name = probe.fresh_name(&format!("{body}_mass_probe"));
            let pid = ParamId(probe.params.len() as u32);
            let scale = probe.bodies[b].mass.scale;
            probe.params.push(ParamIr {
                name: name.clone(),
                kind: ParamKind::Unknown {
                    nominal: Some(scale),
                },
            });
            probe.spans.params.push(probe.spans.model);
            probe.bodies[b].mass = Coef::param(pid);
            name
        }
    };
    probe.equations = dynid_ir::edit::assemble_equations(&probe);
    let tape = Tape::compile(&probe, &probe.eval_roots());
    let fit = measure(&probe, &tape, levels, opts).ok()?.identify_pooled();
    let value = fit.param(&name)?.value * probe.bodies[b].mass.scale;
    let after = worst(&fit);
    (after <= RESIDUAL_WARN && value.is_finite()).then_some((value, after))
}

/// Identify the model with an unknown constant force on every body; `Some` when that
/// explains the residual (see the module doc).
fn offset_probe(
    ir: &ModelIr,
    id: &Identification,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Option<Offset> {
    let before = worst(id);
    let mut probe = ir.clone();
    let one = |a: &mut dynid_ir::ir::ExprArena, _, _| a.constant(1.0);
    let mut params: Vec<(String, String)> = Vec::with_capacity(ir.bodies.len());
    for b in &ir.bodies {
        let name = probe.fresh_name("offset_probe");
        let param = probe.fresh_name("f_offset_probe");
        params.push((b.name.clone(), param.clone()));
        probe
            .add_force(
                &name,
                ("ground", &b.name),
                &[NewTerm {
                    param: &param,
                    nominal: None,
                    basis: &one,
                }],
            )
            .ok()?;
    }
    let tape = Tape::compile(&probe, &probe.eval_roots());
    let fit = measure(&probe, &tape, levels, opts).ok()?.identify_pooled();
    let after = worst(&fit);
    if !(after <= RESIDUAL_WARN && after <= PROBE_SHRINK * before) {
        return None;
    }
    let position = ir
        .measured_signals()
        .iter()
        .map(|s| ir.signal(*s))
        .filter(|s| matches!(s.kind, SignalKind::Position(_)))
        .filter_map(|s| {
            id.levels
                .iter()
                .filter_map(|l| {
                    let (m, sd) = (*l.mean.get(&s.name)?, *l.std.get(&s.name)?);
                    (sd > 0.0).then(|| (m, m.abs() / sd))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(m, z)| (s.name.clone(), m, z))
        })
        .max_by(|a, b| a.2.total_cmp(&b.2));
    let forces = params
        .iter()
        .filter_map(|(b, p)| {
            let e = fit.param(p)?;
            (e.value.is_finite() && e.stderr.is_finite()).then(|| (b.clone(), e.value, e.stderr))
        })
        .collect();
    let position_dependent = position_dependent(ir, None);
    Some(Offset {
        residual: after,
        position,
        forces,
        position_dependent,
    })
}

/// Whether a force in the equation of `body` (of any body, for `None`) depends on a
/// position (a spring, a nonlinear stiffness): only then can a zero offset of a position
/// sensor act as a constant force.
/// A position seen only through `sin` or `cos` (a force periodic along the travel, such
/// as a guide's friction ripple or cogging) does not count: an offset shifts its phase,
/// not its mean.
pub(crate) fn position_dependent(ir: &ModelIr, body: Option<&str>) -> bool {
    ir.equations
        .iter()
        .filter(|e| body.is_none_or(|b| ir.bodies[e.body.index()].name == b))
        .flat_map(|e| &e.terms)
        .any(|t| match t.basis {
            dynid_ir::ir::Basis::Expr(x) => reads_position_outside_periodic(ir, x),
            dynid_ir::ir::Basis::Deriv { .. } => false,
        })
}

/// Whether the expression `x` reads a position other than inside a `sin` or `cos`. The
/// nodes are in topological order (operands before their use), so one forward sweep over
/// the nodes up to `x` decides it, without recursion.
fn reads_position_outside_periodic(ir: &ModelIr, x: dynid_ir::ir::ExprId) -> bool {
    use dynid_ir::ir::{ExprNode, UnaryOp};
    let mut reads = vec![false; x.index() + 1];
    for i in 0..=x.index() {
        reads[i] = match ir.exprs[i] {
            ExprNode::Const(_) => false,
            ExprNode::Signal(s) => matches!(ir.signal(s).kind, SignalKind::Position(_)),
            ExprNode::Unary(UnaryOp::Sin | UnaryOp::Cos, _) => false,
            ExprNode::Unary(_, a)
            | ExprNode::Powi(a, _)
            | ExprNode::Deadzone(a, _)
            | ExprNode::Saturate(a, _) => reads[a.index()],
            ExprNode::Binary(_, a, b) => reads[a.index()] || reads[b.index()],
        };
    }
    reads[x.index()]
}
