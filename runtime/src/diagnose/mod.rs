//! Diagnosis of the sim-to-real gap: where a simulation model misses measured data, which
//! unmodelled effect explains it, and how far the gap shrinks once that effect is added.
//!
//! The gap is measured by simulation (the model driven by the measured input from the
//! measured initial state, free run, compared with the measured response) and by the
//! covariance-equation residual.
//! Candidate effects from a small library are added as new unknown force elements by editing
//! the model's IR (`dynid_ir::edit`), so that names stay those of the user's model; the
//! corrected model is written as ordinary `.dyn` text by the IR's source printer. Every candidate is fitted
//! on all levels but one and scored on the withheld level, rotating the withheld level, so
//! that an extra term is never rewarded for fitting noise. Definitions and thresholds are
//! documented in `docs/diagnosis.md`.

pub mod metrics;

use crate::data::{DataError, LevelSource, RecordSource};
use crate::ident::{measure, Identification, IdentifyError, IdentifyOptions, Moments};
use crate::record::Record;
use crate::sim::{simulate_driven_from, SimError, Start, DEFAULT_SUBSTEPS};
use crate::tape::Tape;
use dynid_ir::edit::NewTerm;
use dynid_ir::ir::{
    BinaryOp, ExprArena, ExprId, ExprNode, ModelIr, ParamKind, SignalKind, UnaryOp,
};
use dynid_ir::num;
use rayon::prelude::*;
use serde::Serialize;

/// Errors of the diagnosis.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum DiagnoseError {
    #[error("diagnosis needs at least 2 excitation levels, got {0}")]
    #[diagnostic(
        code(dynid::diagnose::levels),
        help("pass one data file per excitation level; the gap is scored on a level withheld from fitting")
    )]
    TooFewLevels(usize),
    #[error("the model has no nominal value for `{0}`, so it cannot be simulated")]
    #[diagnostic(
        code(dynid::diagnose::nominal),
        help("give every unknown parameter a nominal value (`k ~ 4.0`)")
    )]
    MissingNominal(String),
    #[error("the model measures no position or velocity, so there is no response to compare")]
    #[diagnostic(
        code(dynid::diagnose::no_response),
        help("measure at least one body signal")
    )]
    NoResponse,
    #[error(transparent)]
    #[diagnostic(transparent)]
    Identify(#[from] IdentifyError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Sim(#[from] SimError),
}

/// Choices of the diagnosis; `Default` gives the documented settings.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    pub ident: IdentifyOptions,
    /// Fraction of each record discarded before comparing responses (the transient from rest).
    pub discard: f64,
    /// RK4 sub-steps per sample in the free-run simulations.
    pub substeps: usize,
    /// How many candidates (best covariance score first) get the free-run score.
    pub top_k: usize,
    /// Most effects added one after the other.
    pub max_effects: usize,
    /// A coefficient counts as significant when |p| > `t_min` · stderr.
    pub t_min: f64,
    /// Required shrink of the withheld gap: relative and absolute (percentage points).
    pub min_rel_shrink: f64,
    pub min_abs_shrink: f64,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            ident: IdentifyOptions::default(),
            discard: 0.1,
            substeps: DEFAULT_SUBSTEPS,
            top_k: 6,
            max_effects: 2,
            t_min: 4.0,
            min_rel_shrink: 0.2,
            min_abs_shrink: 1.0,
        }
    }
}

/// An unmodelled effect of the library.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Effect {
    Cubic,
    /// An asymmetric spring: stiffer in one direction than the other.
    QuadraticStiffness,
    Coulomb,
    QuadraticDamping,
    Backlash {
        gap: f64,
    },
    Prestress,
}

impl Effect {
    pub fn name(&self) -> String {
        match self {
            Effect::Cubic => "cubic stiffness s^3".into(),
            Effect::QuadraticStiffness => "quadratic (asymmetric) stiffness s^2".into(),
            Effect::Coulomb => "Coulomb friction sign(v)".into(),
            Effect::QuadraticDamping => "quadratic damping v*abs(v)".into(),
            Effect::Backlash { gap } => format!("backlash deadzone(s, {})", num::exact(*gap)),
            Effect::Prestress => "prestress sign(s)".into(),
        }
    }
    /// Short kind name, stable for machines.
    pub fn kind(&self) -> &'static str {
        match self {
            Effect::Cubic => "cubic",
            Effect::QuadraticStiffness => "quadratic_stiffness",
            Effect::Coulomb => "coulomb",
            Effect::QuadraticDamping => "quadratic_damping",
            Effect::Backlash { .. } => "backlash",
            Effect::Prestress => "prestress",
        }
    }
    /// The effect's basis function of an element's relative displacement `s` and velocity
    /// `v`, built into the model's expression DAG.
    fn basis(&self, arena: &mut ExprArena, s: ExprId, v: ExprId) -> ExprId {
        match *self {
            Effect::Cubic => arena.intern(ExprNode::Powi(s, 3)),
            Effect::QuadraticStiffness => arena.intern(ExprNode::Powi(s, 2)),
            Effect::Coulomb => arena.unary(UnaryOp::Sign, v),
            Effect::QuadraticDamping => {
                let a = arena.unary(UnaryOp::Abs, v);
                arena.binary(BinaryOp::Mul, v, a)
            }
            Effect::Backlash { gap } => arena.intern(ExprNode::Deadzone(s, gap.to_bits())),
            Effect::Prestress => arena.unary(UnaryOp::Sign, s),
        }
    }
    fn param_stem(&self) -> &'static str {
        match self {
            Effect::Cubic => "k3",
            Effect::QuadraticStiffness => "k2",
            Effect::Coulomb => "r",
            Effect::QuadraticDamping => "q",
            Effect::Backlash { .. } => "kb",
            Effect::Prestress => "f0",
        }
    }
    fn needs_velocity(&self) -> bool {
        matches!(self, Effect::Coulomb | Effect::QuadraticDamping)
    }
    /// Friction, damping, backlash and preload dissipate or resist: a negative coefficient
    /// is unphysical. A cubic term may harden or soften; the sign of a quadratic term only
    /// says in which direction the spring is stiffer.
    fn sign_ok(&self, p: f64) -> bool {
        matches!(self, Effect::Cubic | Effect::QuadraticStiffness) || p >= 0.0
    }
}

/// Where a candidate acts: between two nodes (an existing element's or body to ground).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Location {
    pub a: String,
    pub b: String,
    /// Names of the existing elements between these nodes (empty: a new body-to-ground site).
    pub elements: Vec<String>,
}

impl Location {
    pub fn label(&self) -> String {
        format!("({}, {})", self.a, self.b)
    }
}

/// Response gap of one signal on one level.
#[derive(Clone, Debug, Serialize)]
pub struct SignalGap {
    pub signal: String,
    /// Free-run NRMSE in %.
    pub nrmse: f64,
    /// (std(sim) − std(meas)) / std(meas) in %.
    pub std_error: f64,
    /// Mean |log10| PSD ratio over the band holding 99 % of the measured power.
    pub psd_gap: f64,
}

/// Response gap of a model on one level.
#[derive(Clone, Debug, Serialize)]
pub struct LevelGap {
    pub level: usize,
    pub origin: String,
    /// Mean over response signals of the free-run NRMSE, in %; infinite if the run diverged.
    pub gap: f64,
    pub signals: Vec<SignalGap>,
    /// The simulation diverged (the model is unstable with these parameters).
    pub diverged: bool,
}

/// A model's gap on the levels it was scored on.
#[derive(Clone, Debug, Serialize)]
pub struct ModelGap {
    pub label: String,
    /// Mean of the per-level gaps in % (the headline number).
    pub gap: f64,
    pub levels: Vec<LevelGap>,
}

/// Covariance-equation residual of the nominal model, per equation and level.
#[derive(Clone, Debug, Serialize)]
pub struct EquationGap {
    pub equation: String,
    /// Relative RMS of `C p − c` over the (row-normalised) rows of that equation, in %.
    pub per_level: Vec<f64>,
}

/// A parameter identified separately at each level.
#[derive(Clone, Debug, Serialize)]
pub struct ParamDrift {
    pub name: String,
    pub nominal: Option<f64>,
    pub pooled: Option<f64>,
    pub per_level: Vec<Option<f64>>,
    pub stderr: Vec<Option<f64>>,
    /// (max − min) / |mean| of the per-level values, in %.
    pub drift: f64,
    /// Whether the spread exceeds 4 combined standard errors.
    pub significant: bool,
}

/// One candidate of the search.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateScore {
    pub effect: Effect,
    pub location: Location,
    /// The coefficient identified on all levels, its standard error and t-ratio.
    pub value: f64,
    pub stderr: f64,
    pub t_ratio: f64,
    pub sign_ok: bool,
    /// Cross-validated covariance residual on the withheld levels, in %.
    pub cv_residual: f64,
    /// Cross-validated free-run gap in % (only for the best few by covariance score).
    pub gap: Option<f64>,
    pub accepted: bool,
    pub note: String,
}

/// An effect the diagnosis adds to the model.
#[derive(Clone, Debug, Serialize)]
pub struct FoundEffect {
    pub effect: Effect,
    pub location: Location,
    pub element: String,
    pub param: String,
    pub value: f64,
    pub stderr: f64,
    /// Withheld gap before and after adding this effect (in %).
    pub gap_before: f64,
    pub gap_after: f64,
}

/// What kind of gap the data shows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// An effect of the library explains the gap.
    MissingEffect,
    /// Re-identifying the model's own parameters removes most of the gap.
    MistunedParameters,
    /// The model matches the data (small gap, nothing significant to add).
    Consistent,
    /// A gap remains that no library effect removes.
    Unexplained,
}

/// The result of [`diagnose`].
#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    pub model: String,
    pub levels: Vec<String>,
    pub response_signals: Vec<String>,
    pub verdict: Verdict,
    /// Location and effect of the first found effect (`None` when none is significant).
    pub location: Option<String>,
    pub effect: Option<String>,
    /// Headline gaps in %: nominal model (all levels), and after correction (withheld).
    pub gap_before: f64,
    pub gap_after: f64,
    /// 1 − gap_after / gap_before.
    pub shrink: f64,
    pub nominal: ModelGap,
    /// The model as given, re-identified on the training levels, scored on the withheld one.
    pub reidentified: ModelGap,
    /// The corrected model, cross-validated likewise (same as `reidentified` if nothing found).
    pub corrected: ModelGap,
    pub equations: Vec<EquationGap>,
    pub drift: Vec<ParamDrift>,
    /// Parameters of the model as given: nominal → identified on all levels.
    pub moved: Vec<(String, f64, f64, f64)>,
    pub found: Vec<FoundEffect>,
    /// Candidates of the first search step, best first.
    pub ranking: Vec<CandidateScore>,
    /// Candidates of the last search step, the one that added nothing (on top of the found
    /// effects), best first; empty when the first step found nothing or the search stopped at
    /// `max_effects`. What else the data hints at, below the acceptance threshold.
    pub residual_ranking: Vec<CandidateScore>,
    pub notes: Vec<String>,
    /// The corrected model's source (identified values as nominals).
    pub fixed_source: String,
    /// Spectra for the report (not serialised).
    #[serde(skip)]
    pub spectra: Vec<Spectrum>,
}

/// Power spectra of one response signal on one level: measured and per model.
#[derive(Clone, Debug)]
pub struct Spectrum {
    pub signal: String,
    pub level: usize,
    pub freqs: Vec<f64>,
    pub measured: Vec<f64>,
    pub models: Vec<(String, Vec<f64>)>,
}

/// Read a level source into memory (the free-run comparison needs the whole record).
pub fn read_record(src: &dyn LevelSource, ir: &ModelIr) -> Result<Record, DataError> {
    let measured = ir.measured_signals();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); measured.len()];
    src.stream(8192, &mut |cols, len| {
        for (out, s) in columns.iter_mut().zip(&measured) {
            out.extend_from_slice(&cols[s.index()][..len]);
        }
    })?;
    Ok(Record {
        names: measured
            .iter()
            .map(|s| ir.signal(*s).name.clone())
            .collect(),
        columns,
        ts: src.ts(),
        t0: 0.0,
    })
}

/// Values in the diagnosis' text and report: five significant digits.
pub fn fmt_num(v: f64) -> String {
    num::sig(v, 5, false)
}

/// The candidate sites: every node pair that carries an element, then every body to ground.
fn locations(ir: &ModelIr) -> Vec<Location> {
    let mut out: Vec<Location> = Vec::new();
    for e in &ir.elements {
        let (a, b) = (
            ir.node_name(e.nodes.0).to_string(),
            ir.node_name(e.nodes.1).to_string(),
        );
        match out
            .iter_mut()
            .find(|l| (l.a == a && l.b == b) || (l.a == b && l.b == a))
        {
            Some(l) => l.elements.push(e.name.clone()),
            None => out.push(Location {
                a,
                b,
                elements: vec![e.name.clone()],
            }),
        }
    }
    for body in &ir.bodies {
        let b = body.name.clone();
        if !out
            .iter()
            .any(|l| (l.a == "ground" && l.b == b) || (l.b == "ground" && l.a == b))
        {
            out.push(Location {
                a: "ground".into(),
                b,
                elements: vec![],
            });
        }
    }
    out
}

/// A model variant: the model with the added force elements.
struct Variant {
    ir: ModelIr,
    /// Parameter names of the added terms.
    added: Vec<String>,
}

/// `base` with `effect` added as a new force element at `loc`, its coefficient an unknown
/// with nominal 0; returns the model and the new parameter's name.
fn add_effect(base: &ModelIr, effect: Effect, loc: &Location) -> Option<(ModelIr, String)> {
    let mut ir = base.clone();
    let el = ir.fresh_name("gap_fix");
    let p = ir.fresh_name(&format!("{}_fix", effect.param_stem()));
    let basis = |arena: &mut ExprArena, s: ExprId, v: ExprId| effect.basis(arena, s, v);
    let term = NewTerm {
        param: &p,
        nominal: Some(0.0),
        basis: &basis,
    };
    ir.add_force(&el, (&loc.a, &loc.b), &[term]).ok()?;
    Some((ir, p))
}

/// Parameter values to simulate with: identified values for identified unknowns.
fn with_values(ir: &ModelIr, id: &Identification) -> ModelIr {
    let mut out = ir.clone();
    for p in out.params.iter_mut() {
        if let ParamKind::Unknown { nominal } = &mut p.kind {
            if let Some(e) = id.param(&p.name) {
                *nominal = Some(e.value);
            } else if nominal.is_none() {
                *nominal = Some(0.0);
            }
        }
    }
    out
}

struct Data<'a> {
    records: &'a [Record],
    origins: &'a [String],
    response: Vec<String>,
}

/// Free-run gap of `ir` (with its nominal values) on level `w`.
#[allow(clippy::type_complexity)]
fn level_gap(
    ir: &ModelIr,
    data: &Data,
    w: usize,
    opts: &DiagnoseOptions,
    want_psd: bool,
) -> (
    LevelGap,
    Option<Vec<(String, Vec<f64>, Vec<f64>, Vec<f64>)>>,
) {
    let rec = &data.records[w];
    let diverged = |origin: &str| LevelGap {
        level: w,
        origin: origin.to_string(),
        gap: f64::INFINITY,
        signals: vec![],
        diverged: true,
    };
    let sim = match simulate_driven_from(ir, rec, opts.substeps, Start::Measured) {
        Ok(s) => s,
        Err(_) => return (diverged(&data.origins[w]), None),
    };
    let start = ((rec.len() as f64) * opts.discard) as usize;
    let mut signals = Vec::new();
    let mut spectra = Vec::new();
    for name in &data.response {
        let (Some(y), Some(m)) = (sim.column(name), rec.column(name)) else {
            continue;
        };
        let (y, m) = (&y[start..], &m[start..]);
        let (f, pm) = metrics::welch(m, rec.ts, 4096);
        let (_, ps) = metrics::welch(y, rec.ts, 4096);
        let sm = metrics::std_dev(m);
        signals.push(SignalGap {
            signal: name.clone(),
            nrmse: 100.0 * metrics::nrmse(y, m),
            std_error: 100.0 * (metrics::std_dev(y) - sm) / sm,
            psd_gap: metrics::psd_gap(&ps, &pm),
        });
        if want_psd {
            spectra.push((name.clone(), f, pm, ps));
        }
    }
    let gap = signals.iter().map(|s| s.nrmse).sum::<f64>() / signals.len().max(1) as f64;
    let gap = if gap.is_finite() { gap } else { f64::INFINITY };
    (
        LevelGap {
            level: w,
            origin: data.origins[w].clone(),
            gap,
            signals,
            diverged: !gap.is_finite(),
        },
        want_psd.then_some(spectra),
    )
}

fn mean_gap(levels: &[LevelGap]) -> f64 {
    levels.iter().map(|l| l.gap).sum::<f64>() / levels.len().max(1) as f64
}

fn sources<'r>(ir: &ModelIr, data: &'r Data) -> Result<Vec<RecordSource<'r>>, DataError> {
    data.records
        .iter()
        .zip(data.origins)
        .map(|(r, o)| RecordSource::new(r, ir, o.clone()))
        .collect()
}

fn measure_all<'m>(
    ir: &'m ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
) -> Result<Moments<'m>, DiagnoseError> {
    let srcs = sources(ir, data)?;
    let refs: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let tape = Tape::compile(ir, &ir.eval_roots());
    let mut m = measure(ir, &tape, &refs, &opts.ident)?;
    // The structure search treats a term whose estimate is within its standard error of
    // zero as absent, and scores the variant without it.
    m.prune_insignificant(true);
    Ok(m)
}

fn training(n: usize, w: usize) -> Vec<usize> {
    (0..n).filter(|&i| i != w).collect()
}

/// Relative residual (%) of the row-normalised rows of level `w` with the parameters `p`,
/// optionally restricted to the rows of one equation.
fn cov_residual(m: &Moments, p: &[f64], w: usize, equation: Option<&str>) -> f64 {
    let sys = m.system();
    let n_levels = m.levels().len();
    let per = sys.rows / n_levels;
    let (mut num, mut den) = (0.0, 0.0);
    for r in w * per..(w + 1) * per {
        if let Some(eq) = equation {
            if !sys.row_labels[r].ends_with(&format!("→ {eq}")) {
                continue;
            }
        }
        let row = &sys.c_matrix[r * sys.cols..(r + 1) * sys.cols];
        let norm = (row.iter().map(|x| x * x).sum::<f64>() + sys.rhs[r] * sys.rhs[r]).sqrt();
        if norm == 0.0 {
            continue;
        }
        let cp = row.iter().zip(p).map(|(a, b)| a * b).sum::<f64>();
        let e = cp - sys.rhs[r];
        num += (e / norm).powi(2);
        // Relative to the size of the individual terms: an equation without input has a
        // zero right-hand side, so `c` alone is no scale.
        let terms: f64 =
            row.iter().zip(p).map(|(a, b)| (a * b).powi(2)).sum::<f64>() + sys.rhs[r] * sys.rhs[r];
        den += terms / (norm * norm);
    }
    if den > 0.0 {
        100.0 * (num / den).sqrt()
    } else {
        f64::NAN
    }
}

fn param_vector(ir: &ModelIr, id: &Identification) -> Vec<f64> {
    ir.unknowns()
        .iter()
        .map(|p| {
            let name = &ir.params[p.index()].name;
            id.param(name)
                .map(|e| e.value)
                .or(ir.params[p.index()].nominal())
                .unwrap_or(0.0)
        })
        .collect()
}

/// Cross-validated scores of a variant: covariance residual (mean over withheld levels)
/// and the training fits per withheld level.
fn cross_validate(m: &Moments, ir: &ModelIr, n: usize) -> (f64, Vec<Identification>) {
    let mut fits = Vec::with_capacity(n);
    let mut res = 0.0;
    for w in 0..n {
        let fit = m.identify_levels(&training(n, w));
        let p = param_vector(ir, &fit);
        res += cov_residual(m, &p, w, None);
        fits.push(fit);
    }
    (res / n as f64, fits)
}

/// Free-run gap with the training fits, each scored on its withheld level.
fn cv_gap(
    ir: &ModelIr,
    fits: &[Identification],
    data: &Data,
    opts: &DiagnoseOptions,
    label: &str,
) -> ModelGap {
    let levels: Vec<LevelGap> = fits
        .par_iter()
        .enumerate()
        .map(|(w, fit)| level_gap(&with_values(ir, fit), data, w, opts, false).0)
        .collect();
    ModelGap {
        label: label.into(),
        gap: mean_gap(&levels),
        levels,
    }
}

struct Search {
    ranking: Vec<CandidateScore>,
    best: Option<(CandidateScore, Variant, ModelGap, Identification)>,
}

/// One greedy step: try every effect at every location on top of `base`, except the kinds
/// already `found` at a location (a second copy of a term is collinear with the first).
fn search_step(
    base: &Variant,
    found: &[FoundEffect],
    data: &Data,
    baseline: f64,
    opts: &DiagnoseOptions,
    notes: &mut Vec<String>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Search {
    let ir = &base.ir;
    let n = data.records.len();
    let vel_measured = ir
        .signals
        .iter()
        .filter(|s| matches!(s.kind, SignalKind::Velocity { .. }))
        .all(|s| s.measured);
    // Gaps of the backlash grid are relative to each location's σ_s on the largest level.
    let sigma_s = |loc: &Location| -> f64 {
        let big = (0..n)
            .max_by(|&a, &b| {
                let sa = data.records[a]
                    .columns
                    .iter()
                    .map(|c| metrics::std_dev(c))
                    .sum::<f64>();
                let sb = data.records[b]
                    .columns
                    .iter()
                    .map(|c| metrics::std_dev(c))
                    .sum::<f64>();
                sa.total_cmp(&sb)
            })
            .unwrap_or(0);
        let rec = &data.records[big];
        let col = |node: &str| rec.column(&format!("{node}.x"));
        let s: Vec<f64> = match (loc.a.as_str(), col(&loc.a), col(&loc.b)) {
            ("ground", _, Some(xb)) => xb.to_vec(),
            (_, Some(xa), Some(xb)) => xb.iter().zip(xa).map(|(b, a)| b - a).collect(),
            (_, Some(xa), None) if loc.b == "ground" => xa.iter().map(|a| -a).collect(),
            _ => return 0.0,
        };
        metrics::std_dev(&s)
    };
    let locs = locations(ir);
    let mut cands: Vec<(Effect, Location)> = Vec::new();
    let mut skipped_velocity = false;
    let already = |kind: &str, loc: &Location| {
        found
            .iter()
            .any(|f| f.effect.kind() == kind && f.location.a == loc.a && f.location.b == loc.b)
    };
    for loc in &locs {
        for eff in [
            Effect::Cubic,
            Effect::QuadraticStiffness,
            Effect::Coulomb,
            Effect::QuadraticDamping,
            Effect::Prestress,
        ] {
            if eff.needs_velocity() && !vel_measured {
                skipped_velocity = true;
                continue;
            }
            if already(eff.kind(), loc) {
                continue;
            }
            cands.push((eff, loc.clone()));
        }
        let sg = sigma_s(loc);
        if sg > 0.0 && !already("backlash", loc) {
            for f in [0.1, 0.25, 0.5, 1.0] {
                cands.push((
                    Effect::Backlash {
                        gap: num::round_sig(f * sg, 3),
                    },
                    loc.clone(),
                ));
            }
        }
    }
    if skipped_velocity && !notes.iter().any(|s| s.contains("velocities")) {
        notes.push(
            "velocities are not measured: Coulomb friction and quadratic damping candidates \
             were skipped (cubic, quadratic stiffness, backlash and prestress were searched)"
                .into(),
        );
    }
    let total = cands.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let evaluate = |(eff, loc): &(Effect, Location)| -> Option<(CandidateScore, Variant, Vec<Identification>, Identification)> {
        let out = (|| {
            let (cir, p) = add_effect(ir, *eff, loc)?;
            let m = measure_all(&cir, data, opts).ok()?;
            let all = m.identify_pooled();
            let est = all.param(&p).cloned().unwrap_or(crate::ident::ParamEstimate {
                name: p.clone(),
                value: f64::NAN,
                stderr: f64::NAN,
                significant: false,
            });
            let (cv, fits) = cross_validate(&m, &cir, n);
            let t = if est.value.is_finite() {
                est.value.abs() / est.stderr.max(f64::MIN_POSITIVE)
            } else {
                0.0
            };
            let mut added = base.added.clone();
            added.push(p);
            let score = CandidateScore {
                effect: *eff,
                location: loc.clone(),
                value: est.value,
                stderr: est.stderr,
                t_ratio: t,
                sign_ok: est.value.is_finite() && eff.sign_ok(est.value),
                cv_residual: cv,
                gap: None,
                accepted: false,
                note: String::new(),
            };
            Some((score, Variant { ir: cir, added }, fits, all))
        })();
        let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(k, total);
        out
    };
    let mut results: Vec<_> = cands.par_iter().filter_map(&evaluate).collect();
    // Refine the backlash gap around the best grid point of each location.
    let mut refined = Vec::new();
    for loc in &locs {
        let best = results
            .iter()
            .filter(|r| r.0.location == *loc && matches!(r.0.effect, Effect::Backlash { .. }))
            .min_by(|a, b| a.0.cv_residual.total_cmp(&b.0.cv_residual));
        if let Some((s, ..)) = best {
            if let Effect::Backlash { gap } = s.effect {
                for f in [0.75, 1.35] {
                    refined.push((
                        Effect::Backlash {
                            gap: num::round_sig(gap * f, 3),
                        },
                        loc.clone(),
                    ));
                }
            }
        }
    }
    let more: Vec<_> = refined.par_iter().filter_map(&evaluate).collect();
    results.extend(more);
    // Keep one backlash (the best gap) per location in the ranking.
    results.sort_by(|a, b| a.0.cv_residual.total_cmp(&b.0.cv_residual));
    let mut seen_bl: Vec<Location> = Vec::new();
    results.retain(|r| {
        if matches!(r.0.effect, Effect::Backlash { .. }) {
            if seen_bl.contains(&r.0.location) {
                return false;
            }
            seen_bl.push(r.0.location.clone());
        }
        true
    });
    // Free-run score for the best few physically admissible candidates.
    let mut scored = 0;
    let mut gaps: Vec<(usize, ModelGap)> = Vec::new();
    #[allow(clippy::needless_range_loop)]
    for i in 0..results.len() {
        if scored >= opts.top_k {
            break;
        }
        let r = &results[i];
        if !r.0.sign_ok || r.0.t_ratio <= opts.t_min {
            results[i].0.note = if !r.0.value.is_finite() {
                "not resolved by the data".into()
            } else if !r.0.sign_ok {
                "unphysical sign".into()
            } else {
                format!("not significant (|p|/σ = {:.1})", r.0.t_ratio)
            };
            continue;
        }
        scored += 1;
        let g = cv_gap(&r.1.ir, &r.2, data, opts, "corrected");
        results[i].0.gap = Some(g.gap);
        gaps.push((i, g));
    }
    // Free-run gaps within 10 % of the best are a tie (a wide dead zone mimics a cubic
    // spring): the cross-validated covariance residual, which sees every instrument, breaks it.
    let best_gap = gaps.iter().map(|g| g.1.gap).fold(f64::INFINITY, f64::min);
    let best = gaps
        .into_iter()
        .filter(|(_, g)| g.gap <= 1.1 * best_gap)
        .min_by(|a, b| {
            results[a.0]
                .0
                .cv_residual
                .total_cmp(&results[b.0].0.cv_residual)
        });
    let mut out_best = None;
    if let Some((i, g)) = best {
        let shrink_abs = baseline - g.gap;
        let ok = g.gap.is_finite()
            && shrink_abs > opts.min_abs_shrink
            && shrink_abs > opts.min_rel_shrink * baseline;
        if ok {
            results[i].0.accepted = true;
            results[i].0.note = "accepted".into();
            let r = &results[i];
            out_best = Some((
                r.0.clone(),
                Variant {
                    ir: r.1.ir.clone(),
                    added: r.1.added.clone(),
                },
                g,
                r.3.clone(),
            ));
        } else {
            results[i].0.note = format!(
                "gap {:.1} % vs {:.1} % without it: not a material reduction",
                g.gap, baseline
            );
        }
    }
    Search {
        ranking: results.into_iter().map(|r| r.0).collect(),
        best: out_best,
    }
}

/// Diagnose the gap between the model in `source` and measured `levels` (one record per
/// excitation level, at least 2). `progress(done, total)` reports the candidate search.
pub fn diagnose(
    model: &ModelIr,
    levels: &[Record],
    origins: &[String],
    opts: &DiagnoseOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Diagnosis, DiagnoseError> {
    let ir = model.clone();
    let n = levels.len();
    if n < 2 {
        return Err(DiagnoseError::TooFewLevels(n));
    }
    if let Some(p) = ir.params.iter().find(|p| p.nominal().is_none()) {
        return Err(DiagnoseError::MissingNominal(p.name.clone()));
    }
    let response: Vec<String> = ir
        .measured_signals()
        .iter()
        .map(|s| ir.signal(*s))
        .filter(|s| !matches!(s.kind, SignalKind::Input { .. }))
        .map(|s| s.name.clone())
        .collect();
    if response.is_empty() {
        return Err(DiagnoseError::NoResponse);
    }
    let origins: Vec<String> = (0..n)
        .map(|i| {
            origins
                .get(i)
                .cloned()
                .unwrap_or(format!("level {}", i + 1))
        })
        .collect();
    let data = Data {
        records: levels,
        origins: &origins,
        response: response.clone(),
    };
    let mut notes = Vec::new();

    // Before: the nominal model on every level.
    let nominal_runs: Vec<_> = (0..n)
        .into_par_iter()
        .map(|w| level_gap(&ir, &data, w, opts, true))
        .collect();
    let nominal_levels: Vec<LevelGap> = nominal_runs.iter().map(|r| r.0.clone()).collect();
    let nominal = ModelGap {
        label: "nominal".into(),
        gap: mean_gap(&nominal_levels),
        levels: nominal_levels,
    };
    // Where: covariance residual per equation with the nominal values; drift per level.
    let m = measure_all(&ir, &data, opts)?;
    let p_nom: Vec<f64> = ir
        .unknowns()
        .iter()
        .map(|p| ir.params[p.index()].nominal().unwrap_or(0.0))
        .collect();
    let equations = ir
        .bodies
        .iter()
        .map(|b| EquationGap {
            equation: b.name.clone(),
            per_level: (0..n)
                .map(|w| cov_residual(&m, &p_nom, w, Some(&b.name)))
                .collect(),
        })
        .collect();
    let pooled = m.identify_pooled();
    // Masses held at one value, as detection does: a mass fitted freely per level trades
    // off against the stiffness and hides its drift (Silverbox: m and a each scatter by
    // 10 % while their ratio rises 8 %).
    let held: Vec<(String, f64)> = crate::detect::held_inertia(&ir, &m)
        .into_iter()
        .map(|h| (h.param, h.value))
        .collect();
    let per_level: Vec<Identification> =
        (0..n).map(|i| m.identify_level_holding(i, &held)).collect();
    let drift: Vec<ParamDrift> = ir
        .unknowns()
        .iter()
        .filter(|p| !held.iter().any(|(h, _)| *h == ir.params[p.index()].name))
        .map(|p| {
            let name = ir.params[p.index()].name.clone();
            let vals: Vec<Option<f64>> = per_level
                .iter()
                .map(|id| id.param(&name).map(|e| e.value))
                .collect();
            let errs: Vec<Option<f64>> = per_level
                .iter()
                .map(|id| id.param(&name).map(|e| e.stderr))
                .collect();
            let v: Vec<f64> = vals.iter().flatten().copied().collect();
            let e: Vec<f64> = errs.iter().flatten().copied().collect();
            let (lo, hi) = v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
            let spread = hi - lo;
            let se = e.iter().map(|x| x * x).sum::<f64>().sqrt();
            ParamDrift {
                nominal: ir.params[p.index()].nominal(),
                pooled: pooled.param(&name).map(|e| e.value),
                drift: if v.len() > 1 && mean != 0.0 {
                    100.0 * spread / mean.abs()
                } else {
                    0.0
                },
                significant: v.len() > 1 && spread > 4.0 * se,
                name,
                per_level: vals,
                stderr: errs,
            }
        })
        .collect();
    let moved = ir
        .unknowns()
        .iter()
        .filter_map(|p| {
            let pr = &ir.params[p.index()];
            let nom = pr.nominal()?;
            let e = pooled.param(&pr.name)?;
            let rel = if nom != 0.0 {
                100.0 * (e.value - nom) / nom.abs()
            } else {
                f64::INFINITY
            };
            Some((pr.name.clone(), nom, e.value, rel))
        })
        .collect();
    let (_, base_fits) = cross_validate(&m, &ir, n);
    let reidentified = cv_gap(&ir, &base_fits, &data, opts, "re-identified");
    drop(m);

    // Which effect: greedy search.
    let mut current = Variant {
        ir: ir.clone(),
        added: vec![],
    };
    let mut current_gap = reidentified.clone();
    let mut current_fit = pooled.clone();
    let mut found = Vec::new();
    let mut ranking = Vec::new();
    let mut residual_ranking = Vec::new();
    for step in 0..opts.max_effects {
        let s = search_step(
            &current,
            &found,
            &data,
            current_gap.gap,
            opts,
            &mut notes,
            progress,
        );
        if step == 0 {
            ranking = s.ranking;
        } else if s.best.is_none() {
            residual_ranking = s.ranking;
        }
        let Some((c, v, g, fit)) = s.best else { break };
        let param = v.added.last().cloned().unwrap_or_default();
        let element =
            v.ir.elements
                .iter()
                .rev()
                .find(|e| e.name.starts_with("gap_fix"))
                .map(|e| e.name.clone())
                .unwrap_or_default();
        found.push(FoundEffect {
            effect: c.effect,
            location: c.location.clone(),
            element,
            param,
            value: c.value,
            stderr: c.stderr,
            gap_before: current_gap.gap,
            gap_after: g.gap,
        });
        current = v;
        current_gap = g;
        current_fit = fit;
    }

    // The corrected model: identified on all levels, values written as nominals.
    // Five significant digits: the standard errors are far larger than the rounding.
    let mut fixed_ir = current.ir.clone();
    for e in &current_fit.params {
        // An unknown of the model by construction; a non-finite value keeps the nominal.
        let _ = fixed_ir.set_nominal(&e.name, num::round_sig(e.value, 5));
    }
    let fixed = dynid_ir::print::to_source(&fixed_ir);
    let corrected = ModelGap {
        label: "corrected".into(),
        ..current_gap.clone()
    };

    // Spectra on the level where the nominal model misses most.
    let big = (0..n)
        .max_by(|&a, &b| nominal.levels[a].gap.total_cmp(&nominal.levels[b].gap))
        .unwrap_or(0);
    let corrected_runs = level_gap(&fixed_ir, &data, big, opts, true);
    let mut spectra = Vec::new();
    if let (Some(nom), Some(cor)) = (&nominal_runs[big].1, &corrected_runs.1) {
        for ((sig, f, pm, ps), (_, _, _, pc)) in nom.iter().zip(cor) {
            spectra.push(Spectrum {
                signal: sig.clone(),
                level: big,
                freqs: f.clone(),
                measured: pm.clone(),
                models: vec![
                    ("nominal".into(), ps.clone()),
                    ("corrected".into(), pc.clone()),
                ],
            });
        }
    }

    let gap_before = nominal.gap;
    let gap_after = corrected.gap.min(gap_before);
    let verdict = if !found.is_empty() {
        Verdict::MissingEffect
    } else if reidentified.gap < 0.5 * gap_before && gap_before > opts.min_abs_shrink * 2.0 {
        if reidentified.gap < 5.0 {
            Verdict::MistunedParameters
        } else {
            Verdict::Unexplained
        }
    } else if reidentified.gap.min(gap_before) < 5.0 {
        Verdict::Consistent
    } else {
        Verdict::Unexplained
    };
    Ok(Diagnosis {
        model: ir.name.clone(),
        levels: origins.clone(),
        response_signals: response,
        verdict,
        location: found.first().map(|f| f.location.label()),
        effect: found.first().map(|f| f.effect.name()),
        gap_before,
        gap_after: if found.is_empty() {
            reidentified.gap.min(gap_before)
        } else {
            gap_after
        },
        shrink: if gap_before > 0.0 {
            1.0 - (if found.is_empty() {
                reidentified.gap.min(gap_before)
            } else {
                gap_after
            }) / gap_before
        } else {
            0.0
        },
        nominal,
        reidentified,
        corrected,
        equations,
        drift,
        moved,
        found,
        ranking,
        residual_ranking,
        notes,
        fixed_source: fixed,
        spectra,
    })
}

impl Diagnosis {
    /// A short human summary: verdict, location, effect, shrink, evidence.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Model `{}` against {} levels ({}); response signals: {}",
            self.model,
            self.levels.len(),
            self.levels.join(", "),
            self.response_signals.join(", ")
        );
        let _ = writeln!(s);
        let _ = writeln!(s, "Gap (free-run NRMSE, mean over response signals):");
        let _ = writeln!(
            s,
            "  nominal model                      {:>7.1} %",
            self.nominal.gap
        );
        let _ = writeln!(
            s,
            "  re-identified (withheld level)     {:>7.1} %",
            self.reidentified.gap
        );
        if !self.found.is_empty() {
            let _ = writeln!(
                s,
                "  corrected model (withheld level)   {:>7.1} %",
                self.corrected.gap
            );
        }
        let _ = writeln!(s);
        // Where.
        let worst: Vec<String> = {
            let mut sig: Vec<(String, f64)> = self
                .response_signals
                .iter()
                .map(|name| {
                    let v: Vec<f64> = self
                        .nominal
                        .levels
                        .iter()
                        .filter_map(|l| l.signals.iter().find(|g| &g.signal == name))
                        .map(|g| g.nrmse)
                        .collect();
                    (name.clone(), v.iter().sum::<f64>() / v.len().max(1) as f64)
                })
                .collect();
            sig.sort_by(|a, b| b.1.total_cmp(&a.1));
            sig.iter()
                .take(3)
                .map(|(n, v)| format!("{n} {v:.1} %"))
                .collect()
        };
        let _ = writeln!(s, "Where: worst signals (nominal): {}", worst.join(", "));
        let eqs: Vec<String> = self
            .equations
            .iter()
            .map(|e| {
                format!(
                    "{} {:.1} %",
                    e.equation,
                    e.per_level.iter().sum::<f64>() / e.per_level.len().max(1) as f64
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "       covariance residual per equation: {}",
            eqs.join(", ")
        );
        let drifting: Vec<String> = self
            .drift
            .iter()
            .filter(|d| d.significant)
            .map(|d| {
                let v: Vec<String> = d
                    .per_level
                    .iter()
                    .map(|x| x.map_or("–".into(), fmt_num))
                    .collect();
                format!("{} [{}]", d.name, v.join(" → "))
            })
            .collect();
        if drifting.is_empty() {
            let _ = writeln!(s, "       no parameter drifts significantly with the level");
        } else {
            let _ = writeln!(
                s,
                "       parameters drifting with level: {}",
                drifting.join(", ")
            );
        }
        let _ = writeln!(s);
        match self.verdict {
            Verdict::MissingEffect => {
                for (k, f) in self.found.iter().enumerate() {
                    let shrink = 100.0 * (1.0 - f.gap_after / f.gap_before.max(1e-300));
                    let conf = confidence(f.value / f.stderr, shrink);
                    let _ = writeln!(
                        s,
                        "{} missing effect: {} at {}{}",
                        if k == 0 { "Most likely" } else { "Also" },
                        f.effect.name(),
                        f.location.label(),
                        if f.location.elements.is_empty() {
                            " (body to ground)".to_string()
                        } else {
                            format!(" (element {})", f.location.elements.join(", "))
                        }
                    );
                    let _ = writeln!(
                        s,
                        "  identified {} = {} ± {} (|p|/σ = {:.0}); withheld gap {:.1} % → {:.1} % ({:.0} % smaller); confidence: {}",
                        f.param,
                        fmt_num(f.value),
                        fmt_num(f.stderr),
                        f.value.abs() / f.stderr,
                        f.gap_before,
                        f.gap_after,
                        shrink,
                        conf
                    );
                }
                let _ = writeln!(
                    s,
                    "Overall: {:.1} % → {:.1} % ({:.0} % of the gap removed); remaining {:.1} %",
                    self.gap_before,
                    self.gap_after,
                    100.0 * self.shrink,
                    self.gap_after
                );
                if let Some(next) = self
                    .ranking
                    .iter()
                    .filter(|c| !c.accepted)
                    .find(|c| c.gap.is_some())
                {
                    let _ = writeln!(
                        s,
                        "  runner-up: {} at {} (withheld gap {:.1} %)",
                        next.effect.name(),
                        next.location.label(),
                        next.gap.unwrap_or(f64::NAN)
                    );
                }
                if !self.residual_ranking.is_empty() {
                    let _ = writeln!(s, "On top of that, below the acceptance threshold:");
                    for c in self.residual_ranking.iter().take(4) {
                        let gap = c
                            .gap
                            .map_or(String::new(), |g| format!(", withheld gap {g:.1} %"));
                        let val = if c.value.is_finite() {
                            format!("{} ± {}", fmt_num(c.value), fmt_num(c.stderr))
                        } else {
                            "–".into()
                        };
                        let _ = writeln!(
                            s,
                            "  {} at {}: {val}{gap} ({})",
                            c.effect.name(),
                            c.location.label(),
                            if c.note.is_empty() {
                                "not scored"
                            } else {
                                &c.note
                            }
                        );
                    }
                }
            }
            Verdict::MistunedParameters => {
                let _ = writeln!(
                    s,
                    "Mis-tuned parameters: re-identification alone removes the gap ({:.1} % → {:.1} %); no significant unmodelled effect.",
                    self.nominal.gap, self.reidentified.gap
                );
                let mut moved = self.moved.clone();
                moved.sort_by(|a, b| b.3.abs().total_cmp(&a.3.abs()));
                for (n, a, b, r) in moved.iter().take(4) {
                    let _ = writeln!(s, "  {n}: {} → {} ({r:+.1} %)", fmt_num(*a), fmt_num(*b));
                }
            }
            Verdict::Consistent => {
                let _ = writeln!(
                    s,
                    "No significant unmodelled effect: the model matches the data within {:.1} %.",
                    self.reidentified.gap.min(self.nominal.gap)
                );
            }
            Verdict::Unexplained => {
                let _ = writeln!(
                    s,
                    "No significant unmodelled effect from the library explains the remaining gap of {:.1} %.",
                    self.reidentified.gap
                );
            }
        }
        for n in &self.notes {
            let _ = writeln!(s, "Note: {n}");
        }
        s
    }
}

fn confidence(t: f64, shrink: f64) -> &'static str {
    if t.abs() > 20.0 && shrink > 70.0 {
        "high"
    } else if t.abs() > 8.0 && shrink > 40.0 {
        "medium"
    } else {
        "low"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every effect added on the IR gives the model that compiling the same element,
    /// written in the language, gives: the same equations and the same printed source.
    #[test]
    fn an_effect_added_on_the_ir_is_the_written_element() {
        let src = "model a {\n    body m = 1\n    body n = 2\n    input u on m\n    spring k (ground, m) ~ 4\n    spring k2 (m, n) ~ 1\n}\n";
        let ir = dsl_parser::compile_str("a", src).unwrap();
        let cases = [
            (Effect::Cubic, "r ~ 0 * s^3"),
            (Effect::QuadraticStiffness, "r ~ 0 * s^2"),
            (Effect::Coulomb, "r ~ 0 * sign(v)"),
            (Effect::QuadraticDamping, "r ~ 0 * v * abs(v)"),
            (Effect::Backlash { gap: 0.25 }, "r ~ 0 * deadzone(s, 0.25)"),
            (Effect::Prestress, "r ~ 0 * sign(s)"),
        ];
        for loc in &locations(&ir) {
            for (effect, text) in cases {
                let (edited, p) = add_effect(&ir, effect, loc).unwrap();
                let stem = effect.param_stem();
                assert_eq!(p, format!("{stem}_fix"));
                let line = format!(
                    "    force gap_fix ({}, {}) = {}\n}}\n",
                    loc.a,
                    loc.b,
                    text.replacen('r', &p, 1)
                );
                let written = src.replacen("}\n", &line, 1);
                let compiled = dsl_parser::compile_str("a", &written).unwrap();
                let printed = dynid_ir::print::to_source(&edited);
                assert_eq!(printed, dynid_ir::print::to_source(&compiled), "{written}");
                assert_eq!(
                    dynid_ir::print::render_equations(&edited),
                    dynid_ir::print::render_equations(&compiled)
                );
                // The printed model compiles back to the edited one.
                let again = dsl_parser::compile_str("a", &printed).unwrap();
                assert_eq!(dynid_ir::print::to_source(&again), printed);
            }
        }
    }
}
