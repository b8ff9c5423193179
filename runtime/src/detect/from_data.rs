//! From measured levels to a [`DetectionInput`]: the linear model is identified separately
//! at each level, every unknown parameter is attached to its element and role, and each
//! element's intensities σ_s, σ_v are measured on the data.
//!
//! * **Grouping.** Springs, dampers and forces between the same two nodes form one
//!   element for the templates (`k1/d1 (ground, m1)`), so a Coulomb friction hiding in a
//!   spring–damper pair is explained on the damper's curve and a prestress on the spring's.
//! * **Roles.** A coefficient of exactly `s` is a stiffness, of exactly `v` a damping (the
//!   element kind decides for other linear terms); an unknown body mass is a mass; anything
//!   else is `Other` (tested for constancy, no templates).
//! * **Inertia held.** Unknown masses are held at one value for all levels, the weighted
//!   mean of their free per-level estimates (see [`level_fits`]); a nonlinear force linearises to a stiffness or damping, never to
//!   a mass, and a mass left free per level absorbs part of the stiffness drift.
//! * **Constant forces held.** An unknown constant force (`= f0`) is held at its pooled
//!   estimate in every per-level fit: an offset is no equivalent-linear parameter, and a
//!   loud level may not resolve the mean it puts into the data.
//! * **σ_s** is the standard deviation of the element's `s` expression evaluated on the
//!   streamed data. **σ_v** likewise from `v` when the velocities it needs are measured.
//!   Otherwise it comes from Rice's formula for a stationary Gaussian process: the mean
//!   rate of zero crossings of `s − ⟨s⟩` is `σ_v / (π σ_s)`, so `σ_v = π σ_s N₀ / T`. No
//!   signal is differentiated; crossings are counted with a hysteresis of ±5 % σ_s so that
//!   measurement noise does not add spurious ones. The template coefficients of damping
//!   effects scale with σ_v, so their accuracy follows that of this estimate: within
//!   ±2.5 % of the measured σ_v on a linear oscillator, up to −12 % where friction or a
//!   hardening spring makes the motion non-Gaussian (tests/detect_models.rs).
//! * **Errors.** Per-level standard errors are the identification's batch-means sandwich
//!   over `n_blocks` time blocks (the fewest of any level), so [`super::DetectOptions::se_dof`]
//!   is set to `n_blocks − 1` unless the caller chose a value.

use dynid_ir::ir::{Basis, ElementKind, ModelIr, ParamId};
use serde::Serialize;

use super::candidate::Distribution;
use super::fit::weighted_mean;
use super::types::{DetectError, DetectionInput, ElementIntensity, FromDataError, HeldParam};
use super::types::{ParamCurve, Role};
use crate::data::LevelSource;
use crate::ident::integrate::{IntegratedMotion, Target};
use crate::ident::{measure, Identification, IdentifyOptions, Measurement};
use crate::tape::{Tape, TapeScratch};

/// Hysteresis of the zero-crossing count, as a fraction of σ_s.
const CROSSING_HYSTERESIS: f64 = 0.05;

/// How an element's σ_v was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum SigmaVSource {
    /// From the measured velocities.
    Measured,
    /// From positions by Rice's zero-crossing formula.
    ZeroCrossings,
}

/// The per-level identifications next to the detection input built from them.
#[derive(Debug)]
pub struct LevelFits {
    pub input: DetectionInput,
    pub fits: Vec<Identification>,
    /// Per grouped element, in the order of `input.elements`.
    pub sigma_v_source: Vec<SigmaVSource>,
    /// Time blocks of the standard errors, fewest over the levels (their degrees of freedom
    /// are this minus one).
    pub n_blocks: usize,
    /// How the per-level fits weighted their rows ([`DetectRows`]).
    pub rows: DetectRows,
}

/// How detection's per-level fits weight their rows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DetectRows {
    /// Every row at unit norm (the instrument rows of `identify`).
    #[default]
    UnitNorm,
    /// Every row weighted by its own estimated error (the rows' estimated covariance shrunk
    /// to its diagonal, [`IdentifyOptions::diagonal_weights`]), as asked
    /// ([`IdentifyOptions::efficient`]). The diagonal, not the halfway shrinkage of
    /// `identify --weighted-rows`: the constancy test weighs each level's point by its
    /// standard error, so those must be honest; on the five-body structure of
    /// `tests/accel_structure.rs` (5 % noise, seeds 1–12) the covariance shrunk halfway
    /// left the curves of linear elements scattering with χ²/dof 2.3 about their means (measured
    /// once), the diagonal 0.91 (docs/detection.md, "Noisy accelerations").
    /// Asked for on a record that measures no acceleration (and the same rows as
    /// [`DetectRows::WeightedForAccelerations`], where the record does).
    Weighted,
    /// The rows of [`DetectRows::Weighted`], chosen by detection for a record that
    /// measures accelerations, where the rows are left open ([`crate::ident::accel_rows`]
    /// says so; `identify` chooses its weighted rows there too): on the five-body structure
    /// of `tests/accel_structure.rs` (5 % noise, seeds 1–12) the unit-norm rows shrink each
    /// level's fit by a different share, which draws spurious drift (another element than
    /// the joint flagged on 5 seeds, against none weighted) and misnames the joint (its pair
    /// of clearance and friction named on none, against 9). On the two-mass structure with
    /// friction at its coupling the weighted fits hold m2 further from the truth (1.20
    /// against 1.84 unit-norm, truth 2; seed 3, measured once) and flag the ground element,
    /// but the estimator's runs explain that drift as the friction's leak on every seed of
    /// six, either way (docs/detection.md, "Noisy accelerations").
    WeightedForAccelerations,
}

impl DetectRows {
    /// The rows detection fits each level of `ir` with under `opts`: weighted where asked
    /// ([`IdentifyOptions::efficient`]) or where the record measures accelerations and no
    /// row, corner or noise option is given ([`crate::ident::accel_rows`]); else unit norm.
    pub fn choose(ir: &ModelIr, opts: &IdentifyOptions) -> DetectRows {
        if opts.efficient {
            DetectRows::Weighted
        } else if crate::ident::accel_rows(ir, opts).is_some() {
            DetectRows::WeightedForAccelerations
        } else {
            DetectRows::UnitNorm
        }
    }

    /// Whether each row is weighted by its own estimated error.
    pub fn weighted(self) -> bool {
        self != DetectRows::UnitNorm
    }

    /// One line for the report where the rows were weighted.
    pub fn describe(self) -> Option<String> {
        match self {
            DetectRows::UnitNorm => None,
            DetectRows::Weighted => Some(
                "rows: each weighted by its own estimated error in every per-level fit \
                 (--weighted-rows)"
                    .into(),
            ),
            DetectRows::WeightedForAccelerations => Some(
                "rows: each weighted by its own estimated error in every per-level fit, chosen \
                 for this record (measured accelerations, where the unit-norm rows shrink each \
                 level's fit by a different share; --instrument-rows for those)"
                    .into(),
            ),
        }
    }
}

/// One grouped element: the IR elements between the same two nodes.
pub(super) struct Group {
    /// As detection names it: `k/d (ground, m)`.
    pub(super) name: String,
    pub(super) members: Vec<usize>,
    pub(super) nodes: (dynid_ir::ir::Node, dynid_ir::ir::Node),
}

pub(super) fn groups(ir: &ModelIr) -> Vec<Group> {
    ir.element_groups()
        .into_iter()
        .map(|g| {
            let names: Vec<&str> = g
                .members
                .iter()
                .map(|e| ir.elements[e.index()].name.as_str())
                .collect();
            Group {
                name: format!(
                    "{} ({}, {})",
                    names.join("/"),
                    ir.node_name(g.nodes.0),
                    ir.node_name(g.nodes.1)
                ),
                members: g.members.iter().map(|e| e.index()).collect(),
                nodes: g.nodes,
            }
        })
        .collect()
}

/// The element group and role of an unknown parameter.
fn param_role(ir: &ModelIr, groups: &[Group], p: ParamId) -> (String, Role) {
    for g in groups {
        for &i in &g.members {
            let e = &ir.elements[i];
            for t in &e.terms {
                if t.coef.param != Some(p) {
                    continue;
                }
                let role = if t.basis == e.s {
                    Role::Stiffness
                } else if t.basis == e.v {
                    Role::Damping
                } else {
                    match e.kind {
                        ElementKind::Spring => Role::Stiffness,
                        ElementKind::Damper => Role::Damping,
                        ElementKind::Force => Role::Other,
                    }
                };
                return (g.name.clone(), role);
            }
        }
    }
    for b in &ir.bodies {
        if b.mass.param == Some(p) {
            return (b.name.clone(), Role::Mass);
        }
    }
    (ir.params[p.index()].name.clone(), Role::Other)
}

/// Histogram bins between the smallest and largest value of a signal at one level: fine
/// enough that E[z⁴] and E|z| of the binned distribution are within 1e-4 of the data's.
const HIST_BINS: usize = 2048;

/// What is measured of one element at one level.
struct Intensity {
    sigma_s: f64,
    sigma_v: f64,
    s_dist: Distribution,
    v_dist: Distribution,
}

/// σ_s, σ_v and the distributions of every group at one level, streamed in chunks.
fn intensities(
    ir: &ModelIr,
    groups: &[Group],
    v_measured: &[bool],
    src: &dyn LevelSource,
    chunk_len: usize,
) -> Result<Vec<Intensity>, FromDataError> {
    let mut roots = Vec::new();
    for (g, &vm) in groups.iter().zip(v_measured) {
        let e = &ir.elements[g.members[0]];
        roots.push(e.s);
        roots.push(if vm { e.v } else { e.s });
    }
    let tape = Tape::compile(ir, &roots);
    let nr = roots.len();
    // Sums about the first sample, which removes most of the cancellation of Σx² − n x̄².
    let mut shift: Option<Vec<f64>> = None;
    let mut s1 = vec![0.0; nr];
    let mut s2 = vec![0.0; nr];
    let mut lo = vec![f64::INFINITY; nr];
    let mut hi = vec![f64::NEG_INFINITY; nr];
    let mut n = 0usize;
    let mut out = vec![0.0; nr * chunk_len];
    let mut scratch = TapeScratch::default();
    src.stream(chunk_len, &mut |cols, len| {
        tape.eval_block(cols, len, &mut out, &mut scratch);
        let sh = shift.get_or_insert_with(|| (0..nr).map(|r| out[r * len]).collect());
        for r in 0..nr {
            let (mut a, mut b) = (0.0, 0.0);
            let (mut mn, mut mx) = (lo[r], hi[r]);
            for &x in &out[r * len..(r + 1) * len] {
                let d = x - sh[r];
                a += d;
                b += d * d;
                mn = mn.min(x);
                mx = mx.max(x);
            }
            lo[r] = mn;
            hi[r] = mx;
            s1[r] += a;
            s2[r] += b;
        }
        n += len;
    })?;
    let nf = n.max(1) as f64;
    let shift = shift.unwrap_or_else(|| vec![0.0; nr]);
    let mean: Vec<f64> = (0..nr).map(|r| shift[r] + s1[r] / nf).collect();
    let std: Vec<f64> = (0..nr)
        .map(|r| {
            let m = s1[r] / nf;
            (s2[r] / nf - m * m).max(0.0).sqrt()
        })
        .collect();
    for (gi, g) in groups.iter().enumerate() {
        if std[2 * gi] <= 0.0 || !std[2 * gi].is_finite() {
            return Err(FromDataError::NoMotion {
                origin: src.origin(),
                element: g.name.clone(),
            });
        }
    }

    // Second pass: histograms of s (and of v where measured) for the measured
    // linearisation, and zero crossings with hysteresis for the groups whose velocity is
    // not measured.
    let width: Vec<f64> = (0..nr)
        .map(|r| ((hi[r] - lo[r]) / HIST_BINS as f64).max(f64::MIN_POSITIVE))
        .collect();
    let mut counts = vec![0u64; nr * HIST_BINS];
    let mut crossings = vec![0usize; groups.len()];
    let mut state = vec![0i8; groups.len()];
    src.stream(chunk_len, &mut |cols, len| {
        tape.eval_block(cols, len, &mut out, &mut scratch);
        for (gi, &vm) in v_measured.iter().enumerate() {
            for r in [2 * gi, 2 * gi + 1] {
                if r % 2 == 1 && !vm {
                    continue;
                }
                let hist = &mut counts[r * HIST_BINS..(r + 1) * HIST_BINS];
                for &x in &out[r * len..(r + 1) * len] {
                    let b = ((x - lo[r]) / width[r]) as usize;
                    hist[b.min(HIST_BINS - 1)] += 1;
                }
            }
        }
        for (gi, &vm) in v_measured.iter().enumerate() {
            if vm {
                continue;
            }
            let r = 2 * gi;
            let h = CROSSING_HYSTERESIS * std[r];
            for &x in &out[r * len..(r + 1) * len] {
                let d = x - mean[r];
                let side = if d > h {
                    1
                } else if d < -h {
                    -1
                } else {
                    0
                };
                if side != 0 {
                    if state[gi] != 0 && side != state[gi] {
                        crossings[gi] += 1;
                    }
                    state[gi] = side;
                }
            }
        }
    })?;
    let duration = (n.max(2) - 1) as f64 * src.ts();
    let dist = |r: usize| {
        Distribution::from_counts(
            &counts[r * HIST_BINS..(r + 1) * HIST_BINS],
            lo[r],
            width[r],
            mean[r],
            std[r],
        )
    };
    Ok(groups
        .iter()
        .enumerate()
        .map(|(gi, _)| {
            let ss = std[2 * gi];
            let (sv, vd) = if v_measured[gi] {
                (std[2 * gi + 1], dist(2 * gi + 1))
            } else {
                (
                    std::f64::consts::PI * ss * crossings[gi] as f64 / duration,
                    Distribution::default(),
                )
            };
            Intensity {
                sigma_s: ss,
                sigma_v: sv,
                s_dist: dist(2 * gi),
                v_dist: vd,
            }
        })
        .collect())
}

/// Unknown body masses and the value to hold each at in per-level fits: the weighted mean
/// of its free per-level estimates (see [`level_fits`] for why). A mass that some level
/// cannot estimate is not held.
pub fn held_inertia(ir: &ModelIr, moments: &Measurement) -> Vec<HeldParam> {
    let groups = groups(ir);
    let free: Vec<Identification> = (0..moments.levels().len())
        .map(|i| moments.identify_level(i))
        .collect();
    ir.unknowns()
        .into_iter()
        .filter(|&p| param_role(ir, &groups, p).1 == Role::Mass)
        .filter_map(|p| {
            let name = &ir.params[p.index()].name;
            let est: Vec<(f64, f64)> = free
                .iter()
                .filter_map(|f| f.param(name))
                .filter(|e| e.value.is_finite() && e.stderr > 0.0)
                .map(|e| (e.value, e.stderr))
                .collect();
            if est.len() < free.len() {
                return None;
            }
            let (y, se): (Vec<f64>, Vec<f64>) = est.into_iter().unzip();
            let (value, stderr) = weighted_mean(&y, &se);
            Some(HeldParam {
                param: name.clone(),
                value,
                stderr,
            })
        })
        .collect()
}

/// Unknown constant forces (terms `f0` with basis 1) and the value to hold each at in
/// per-level fits: the pooled estimate. An offset is no equivalent-linear parameter, and
/// at a loud level the mean it puts into the data can hide in the spread of the mean (the
/// loudest level of `models/sdof_offset.dyn` over 1000 s cannot resolve it), so it gets
/// no curve. A constant force that the pooled fit cannot estimate is not held.
fn held_constant_forces(ir: &ModelIr, moments: &Measurement) -> Vec<HeldParam> {
    let constant: Vec<ParamId> = ir
        .unknowns()
        .into_iter()
        .filter(|&p| {
            let mut terms = ir
                .equations
                .iter()
                .flat_map(|e| &e.terms)
                .filter(|t| t.coef.param == Some(p))
                .peekable();
            terms.peek().is_some()
                && terms.all(|t| matches!(t.basis, Basis::Expr(e) if ir.is_constant(e)))
        })
        .collect();
    if constant.is_empty() {
        return Vec::new();
    }
    let pooled = moments.identify_pooled();
    constant
        .into_iter()
        .filter_map(|p| {
            let e = pooled.param(&ir.params[p.index()].name)?;
            Some(HeldParam {
                param: e.name.clone(),
                value: e.value,
                stderr: e.stderr,
            })
        })
        .collect()
}

/// Whether `s` is the position or velocity of a body measured only by its acceleration.
fn accel_only(ir: &ModelIr, s: dynid_ir::ir::SignalId) -> bool {
    match ir.signal(s).kind {
        dynid_ir::ir::SignalKind::Position(b) | dynid_ir::ir::SignalKind::Velocity(b) => {
            ir.acceleration_only(b)
        }
        _ => false,
    }
}

/// The levels with the positions and velocities of acceleration-only bodies integrated
/// from their accelerations ([`crate::ident::integrate`]); none where the model has no
/// such body.
pub(crate) fn integrated_levels<'a>(
    ir: &ModelIr,
    levels: &[&'a dyn LevelSource],
    chunk: usize,
    allow_large: bool,
) -> Result<Vec<IntegratedMotion<'a>>, FromDataError> {
    let mut targets = Vec::new();
    for b in 0..ir.bodies.len() {
        let b = dynid_ir::ir::BodyId(b as u32);
        if !ir.acceleration_only(b) {
            continue;
        }
        let a = ir
            .acceleration(b)
            .expect("invariant: accelerometer")
            .index();
        targets.push(Target {
            slot: ir.position(b).index(),
            accel: a,
            order: 2,
        });
        targets.push(Target {
            slot: ir.velocity(b).index(),
            accel: a,
            order: 1,
        });
    }
    if targets.is_empty() {
        return Ok(Vec::new());
    }
    Ok(IntegratedMotion::design_all(
        levels,
        &targets,
        &crate::ident::integrate::measured_inputs(ir),
        FALLBACK_CORNER,
        chunk,
        allow_large,
    )?)
}

/// High-pass corner (rad/s) of the integration for a level too short for its spectrum.
const FALLBACK_CORNER: f64 = 0.1;

/// Identify the linear model `ir` at each level separately and collect the curves and the
/// element intensities. Each source is one level; at least two are needed.
///
/// With `hold_inertia`, unknown body masses are held at the weighted mean of their free
/// per-level estimates in the per-level fits and get no curve (listed in
/// [`DetectionInput::held`]).
pub fn level_fits(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
    hold_inertia: bool,
) -> Result<LevelFits, FromDataError> {
    if levels.len() < 2 {
        return Err(DetectError::TooFewLevels(levels.len()).into());
    }
    let groups = groups(ir);
    // Bodies measured only by their acceleration: the curves are drawn over displacements
    // and velocities integrated from the accelerations (zero mean: a static offset is
    // invisible to an accelerometer).
    let integrated = integrated_levels(ir, levels, opts.chunk_len, opts.allow_large)?;
    let motion: Vec<&dyn LevelSource> = if integrated.is_empty() {
        levels.to_vec()
    } else {
        integrated.iter().map(|m| m as &dyn LevelSource).collect()
    };
    let tape = Tape::compile(ir, &ir.eval_roots());
    let rows = DetectRows::choose(ir, opts);
    let opts = if rows.weighted() {
        IdentifyOptions {
            efficient: true,
            diagonal_weights: true,
            // The two-step estimate, whatever `identify` would do: iterated, the per-level
            // standard errors came out too small for the constancy test (χ²/dof 1.8
            // against 0.91 away from the joint of `detection_over_seeds`;
            // docs/detection.md, "Noisy accelerations").
            iterate_weights: false,
            ..opts.clone()
        }
    } else {
        opts.clone()
    };
    let opts = &opts;
    let moments = measure(ir, &tape, levels, opts)?;
    // Inertia is not a force element: statistical linearisation turns a nonlinear force
    // into an equivalent stiffness and damping, never into a mass. Fitted freely per
    // level, an unknown mass trades off against the stiffness (on a short level both
    // scatter by far more than the stiffness drift they hide), so it is held at one value
    // for all levels and only force parameters get curves. That value is the weighted
    // mean of the free per-level estimates: each level's equivalent linear system has the
    // true mass, while a pooled linear fit forces every stiffness to be constant as well —
    // the very hypothesis under test — and its mass absorbs the misfit (on two_mass with a
    // cubic coupling the pooled m2 came out 0.52 for a truth of 2).
    let mut held = if hold_inertia {
        held_inertia(ir, &moments)
    } else {
        Vec::new()
    };
    held.extend(held_constant_forces(ir, &moments));
    let held_values: Vec<(String, f64)> = held.iter().map(|h| (h.param.clone(), h.value)).collect();
    let fits: Vec<Identification> = (0..levels.len())
        .map(|i| moments.identify_level_holding(i, &held_values))
        .collect();
    // A parameter that a level's fit cannot estimate (rank loss) has no point on its curve:
    // named here, with the fit's reason, rather than as a missing standard error later.
    for (f, src) in fits.iter().zip(levels) {
        let lost = f
            .unidentifiable
            .iter()
            .find(|u| !held_values.iter().any(|(h, _)| *h == u.name));
        if let Some(u) = lost {
            return Err(FromDataError::Unidentifiable {
                origin: src.origin(),
                param: u.name.clone(),
                reason: u.reason.clone(),
            });
        }
    }
    let n_blocks = fits
        .iter()
        .flat_map(|f| f.levels.iter().map(|l| l.blocks))
        .min()
        .unwrap_or(2);

    let v_measured: Vec<bool> = groups
        .iter()
        .map(|g| {
            let e = &ir.elements[g.members[0]];
            ir.expr_signals(e.v)
                .iter()
                .all(|s| ir.signal(*s).measured || accel_only(ir, *s))
        })
        .collect();
    let per_level: Vec<Vec<Intensity>> = motion
        .iter()
        .map(|src| intensities(ir, &groups, &v_measured, *src, opts.chunk_len))
        .collect::<Result<_, _>>()?;
    let elements = groups
        .iter()
        .enumerate()
        .map(|(gi, g)| ElementIntensity {
            element: g.name.clone(),
            sigma_s: per_level.iter().map(|l| l[gi].sigma_s).collect(),
            sigma_v: per_level.iter().map(|l| l[gi].sigma_v).collect(),
            s_dist: per_level.iter().map(|l| l[gi].s_dist.clone()).collect(),
            v_dist: per_level
                .iter()
                .map(|l| l[gi].v_dist.clone())
                .filter(|d| !d.is_empty())
                .collect(),
        })
        .collect();

    let curves = ir
        .unknowns()
        .into_iter()
        .filter(|&p| !held.iter().any(|h| h.param == ir.params[p.index()].name))
        .map(|p| {
            let name = ir.params[p.index()].name.clone();
            let (element, role) = param_role(ir, &groups, p);
            let (values, stderrs) = fits
                .iter()
                .map(|f| {
                    // An insignificant estimate still counts, with its large standard
                    // error as its (small) weight; only a parameter without any estimate at
                    // a level (rank loss) leaves a gap that the checks of `detect` report.
                    f.param(&name)
                        .map(|e| (e.value, e.stderr))
                        .unwrap_or((f64::NAN, f64::NAN))
                })
                .unzip();
            ParamCurve {
                param: name,
                element,
                role,
                values,
                stderrs,
            }
        })
        .collect();
    let level_labels = levels.iter().map(|l| l.origin()).collect();
    Ok(LevelFits {
        input: DetectionInput {
            level_labels,
            elements,
            curves,
            held,
        },
        fits,
        sigma_v_source: v_measured
            .iter()
            .map(|&m| {
                if m {
                    SigmaVSource::Measured
                } else {
                    SigmaVSource::ZeroCrossings
                }
            })
            .collect(),
        n_blocks,
        rows,
    })
}
