//! The entry points: identify pooled (with the guard's warnings), per level, or return the
//! stacked system; each measures the levels once (see [`super::measure`](fn@super::measure)).

use super::guard;
use super::input_delay;
use super::measure::measure;
use super::measurement::Measurement;
use super::shape;
use super::types::{CornerTry, Identification, IdentifyError, IdentifyOptions, LinearSystem};
use crate::basis::BasisEval;
use crate::data::LevelSource;
use crate::tape::Tape;
use dynid_ir::ir::ModelIr;

/// Identify the unknown parameters of `ir` from records at one or more excitation levels,
/// pooling all levels into one least-squares problem (Schiehlen & Krause, see
/// docs/method.md, References, eq. 9).
pub fn identify(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let model = &*input_delay::model(ir, opts)?;
    if !model.shapes.is_empty() {
        return Ok(shape::profile(model, levels, opts)?.1);
    }
    let tape = Tape::compile(model, &model.eval_roots());
    let id = pooled(model, &tape, levels, opts)?;
    Ok(choose_rows(model, id, opts, |o| identify(ir, levels, o)))
}

/// The options of the rows of the filtered equation with the inputs' delays where
/// [`IdentifyOptions::auto_rows`] leaves the choice to `identify` and `id` (identified with
/// the instrument rows) shows a record of a servo axis's kind: a `sign` of a velocity
/// whose rests were looked for, a measured input, velocities estimated from measured
/// positions whose noise is below [`super::noise::SIGNIFICANT`] of their spread, no term
/// left to a noise correction, a model that holds (no equation's residual large at every
/// level), corners not given (neither by the options nor by the model's filter block).
/// `None` otherwise.
pub fn servo_rows(
    ir: &ModelIr,
    id: &Identification,
    opts: &IdentifyOptions,
) -> Option<IdentifyOptions> {
    let open = rows_open(opts);
    let coulomb = id.levels.iter().any(|l| l.rests.is_some());
    let from_positions = id
        .estimated
        .iter()
        .any(|e| e.method == super::velocity::METHOD);
    let input = input_delay::any_delayable(ir);
    // Positions with noise below what the noise correction counts as significant (the
    // filtered rows correct no term for noise), and no term left to a correction.
    let quiet_positions = ir.signals.iter().all(|s| {
        !(s.measured && matches!(s.kind, dynid_ir::ir::SignalKind::Position(_)))
            || id
                .noise
                .fraction
                .get(&s.name)
                .is_some_and(|f| *f < super::noise::SIGNIFICANT)
    });
    let quiet = quiet_positions && id.noise.corrected.is_empty() && id.noise.uncorrected.is_empty();
    // A model the instrument rows find does not hold (an equation's residual large at every
    // level): their guard names the likely cause, which the filtered rows, with as many
    // rows as unknowns per level, cannot see.
    let holds = !id
        .fit_warnings
        .iter()
        .any(|w| w.check == super::types::FitCheck::LargeResidual);
    let given = id.filter.corners_from.given;
    (open && coulomb && from_positions && input && quiet && holds && !given).then(|| {
        IdentifyOptions {
            filtered: true,
            input_delay: true,
            auto_rows: false,
            ..opts.clone()
        }
    })
}

/// Whether `opts` leave the choice of rows to `identify` ([`IdentifyOptions::auto_rows`]
/// on, and no row, corner, order, driver, hold or noise option given).
fn rows_open(opts: &IdentifyOptions) -> bool {
    opts.auto_rows
        && opts.corners.is_none()
        && opts.order.is_none()
        && opts.drivers.is_none()
        && opts.noise_correction
        && opts.hold == super::filter::Hold::FirstOrder
        && !(opts.balance
            || opts.column_chains
            || opts.keep_rests
            || opts.efficient
            || opts.filtered
            || opts.input_delay)
}

/// The options of the instrument rows each weighted by its own estimated error (the
/// efficient solve, [`IdentifyOptions::efficient`], with
/// [`IdentifyOptions::diagonal_weights`], the weighting re-estimated until the estimate
/// settles, [`IdentifyOptions::iterate_weights`]) where [`IdentifyOptions::auto_rows`]
/// leaves the choice to `identify` and `ir` measures accelerations: the choice is the
/// record's kind, not its noise.
///
/// From accelerations every unit-norm row weighs its instruments alike, and the bodies
/// whose equations have no right-hand side (no input, an unknown mass) are shrunk towards
/// zero with whatever the rows carry besides the model: the noise (on the five-body
/// structure at 5 % noise every mass and stiffness about 40 % low, like a regression on
/// noisy regressors) and, noiseless, the error of a nonlinear element's motion integrated
/// from accelerations (the jointed structure's noiseless records: every mass and stiffness
/// 21–29 % low from a log sweep, 5–11 % from a multisine). Weighted, the rows that carry
/// such errors get the little weight they deserve (docs/method.md §2, "Rows for
/// accelerations"): the jointed structure's masses and stiffnesses within 0.6 % (sweep)
/// and 0.5 % (multisine) noiseless (`joint_from_a_sweep`), within 1.6 % from a noisy sweep.
/// The price, on the linear structure's noiseless multisine, where the unit-norm rows
/// carry nothing but the sampling's small systematic errors: 0.31 % (mean |error|) against
/// their 0.05 %, and 0.29 against 0.20 % at 0.2 % noise (`accel_rows_from_the_noise_up`).
/// Each row by its own error ([`IdentifyOptions::diagonal_weights`]): the covariance
/// shrunk halfway gives standard errors 2–10 times too small on the SDOF and two-mass
/// records. The weighting iterated: read once at the unit-norm rows' estimate it left a
/// noisy log sweep's jointed structure 10–29 % low (docs/method.md §5, "Iterated
/// weighting"). `None` otherwise.
pub fn accel_rows(ir: &ModelIr, opts: &IdentifyOptions) -> Option<IdentifyOptions> {
    (rows_open(opts) && guard::measured_accelerations(ir).next().is_some()).then(|| {
        IdentifyOptions {
            efficient: true,
            diagonal_weights: true,
            iterate_weights: true,
            auto_rows: false,
            ..opts.clone()
        }
    })
}

/// `id` (identified with the instrument rows of `model`), or where [`servo_rows`] or
/// [`accel_rows`] chooses other rows the identification `again` makes with them, marked
/// as chosen — unless those rows cannot be formed (a weighting that could not be formed
/// included) or leave a parameter unidentified that the instrument rows identified.
fn choose_rows(
    model: &ModelIr,
    id: Identification,
    opts: &IdentifyOptions,
    again: impl FnOnce(&IdentifyOptions) -> Result<Identification, IdentifyError>,
) -> Identification {
    let Some(o) = servo_rows(model, &id, opts).or_else(|| accel_rows(model, opts)) else {
        return id;
    };
    match again(&o) {
        Ok(mut alt)
            if alt.identifies_as_much_as(&id) && (!o.efficient || alt.filter.weighted_rows) =>
        {
            alt.filter.auto_rows = true;
            alt
        }
        _ => id,
    }
}

/// Factors below the designed corner of the filtered equation with the inputs' delays
/// that [`pooled`] tries as well, keeping the corner whose estimates have the smallest
/// covariance determinant. The designed corner is as high as the data carry information
/// above their noise floor, but which noise dominates the estimates decides where they are
/// most precise: on the bench `servo_precision` (seeds 1–24, six sections, the corner
/// given: `DYNID_BENCH_FILTERED_ORDER=6 DYNID_BENCH_FILTERED_CORNER=…`)
/// the random references, whose only noise is the encoder's rounding, amplified by the
/// chain's derivatives, are most precise an octave below the designed 500 rad/s (RMS
/// errors m 0.0004 against 0.0006 %, d 0.0020 / 0.0032 %, r 0.0054 / 0.0072 %, f0 0.017 /
/// 0.023 %), the planned moves, whose force carries 1 % white noise, at the top (m 0.0075 %
/// at 500 rad/s, 0.0105 % at 250, 0.0175 % at 125) — and the reported standard errors,
/// honest on both, rank the corners the same way. Without the delay the filtered rows'
/// damping carries a bias of several standard errors, so their errors cannot rank the
/// corners (searched, the random references' mass came out 0.0086 % against 0.0060 % at
/// the designed corner): no search there.
pub const FILTERED_CORNER_STEPS: [f64; 2] = [2.0, 4.0];

/// How much smaller the geometric mean of the standard errors at a lower corner of the
/// search ([`FILTERED_CORNER_STEPS`]) must be than at the designed corner to be kept: the
/// errors are estimates themselves, and keeping the smallest of three noisy ones would
/// keep the one that came out too small. On one 6.18 s cycle of the planned servo records
/// (`tests/servo_planned.rs`, seeds 1–12) the three corners' errors lay within 2–17 % of
/// each other, and without a margin the search moved the corner down for three seeds'
/// cycles, which left the cycles' mass errors too small (χ²/dof 2.27, one pair 6.0 joint
/// standard errors apart, against 1.35 and 3.7 with the margin; measured once without it).
/// On whole records the lower corner it keeps is better by more: about 1.4 times on the
/// bench's random references (the mean standard errors at 500 and 250 rad/s), 3.6 on the
/// CLI's held-force record (`tests/servo_workflow.rs`).
pub const FILTERED_CORNER_GAIN: f64 = 1.2;

/// The pooled identification of `ir` (its inputs' delays already among its unknowns); for
/// the filtered equation with the inputs' delays and a designed corner, the best of that
/// corner and those a factor [`FILTERED_CORNER_STEPS`] below it (a lower corner only by
/// the margin [`FILTERED_CORNER_GAIN`]; a corner the records cannot carry is not tried),
/// said in [`super::types::FilterSummary::corners_tried`].
fn pooled(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let m = measure(ir, eval, levels, opts)?;
    let designed = guarded(&m, levels, opts);
    let searched = opts.filtered
        && opts.input_delay
        && !designed.filter.corners_from.given
        && designed.filter.corners.len() == 1;
    let Some(score) = searched.then(|| log_det(&designed)).flatten() else {
        return Ok(designed);
    };
    let top = designed.filter.corners[0];
    let designed_params = designed.params.clone();
    let source = designed.filter.corners_from.clone();
    let p = designed.params.len().max(1) as f64;
    let mut tried = vec![(top, score)];
    // A lower corner must beat the designed one by the margin: its score is compared
    // with the designed corner's less `2p ln(gain)`. `kept`: the kept corner's own score.
    let mut best = (score - 2.0 * p * FILTERED_CORNER_GAIN.ln(), designed);
    let mut kept = score;
    for step in FILTERED_CORNER_STEPS {
        let alt_opts = IdentifyOptions {
            corners: Some(vec![top / step]),
            ..opts.clone()
        };
        // A corner too low for the records: not a candidate.
        let Ok(m) = measure(ir, eval, levels, &alt_opts) else {
            continue;
        };
        let alt = guarded(&m, levels, &alt_opts);
        let same = alt.unidentifiable.len() == best.1.unidentifiable.len();
        let Some(score) = log_det(&alt).filter(|_| same) else {
            continue;
        };
        tried.push((top / step, score));
        if score < best.0 && agrees(&designed_params, &alt) {
            best = (score, alt);
            kept = score;
        }
    }
    let (_, mut id) = best;
    id.filter.corners_from = source;
    id.filter.corners_tried = tried
        .into_iter()
        .map(|(corner, s)| CornerTry {
            corner,
            se_ratio: ((s - kept) / (2.0 * p)).exp(),
        })
        .collect();
    Ok(id)
}

/// How many of its own standard errors at the designed corner an estimate at a lower
/// corner of the search may lie from the designed corner's and still be kept
/// ([`agrees`]).
pub const FILTERED_CORNER_AGREE: f64 = 3.0;

/// Whether every estimate of `alt` (a lower corner of the search) lies within
/// [`FILTERED_CORNER_AGREE`] standard errors (the designed corner's) of the designed
/// corner's estimate `designed`. Where both are unbiased the lower corner's is the more
/// precise and their difference is smaller than the designed corner's standard error
/// (its variance is about the difference of the two variances); a larger difference is a
/// bias at one of them that the standard errors do not show — on a 20 µm encoder (the
/// README's servo record, seed 1, `tests/servo_workflow.rs`) the corner quartered to
/// 24.6 rad/s gives errors 2.5 times smaller, and kept (measured once, before this test)
/// it put the damping 0.33 % off at 19 of them.
fn agrees(designed: &[super::types::ParamEstimate], alt: &Identification) -> bool {
    designed.iter().all(|p| {
        alt.param(&p.name)
            .is_some_and(|a| (a.value - p.value).abs() <= FILTERED_CORNER_AGREE * p.stderr)
    })
}

/// `ln det` of the estimates' covariance, `None` where it is not positive definite (or
/// holds no parameter).
fn log_det(id: &Identification) -> Option<f64> {
    let p = id.params.len();
    if p == 0 || id.covariance.len() != p * p {
        return None;
    }
    let cov = nalgebra::DMatrix::from_row_slice(p, p, &id.covariance);
    let chol = cov.cholesky()?;
    let v: f64 = chol.l().diagonal().iter().map(|d| 2.0 * d.ln()).sum();
    v.is_finite().then_some(v)
}

/// The pooled identification with the guard's warnings (see [`guard`]).
fn guarded(
    m: &Measurement<'_>,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Identification {
    let mut id = m.identify_pooled();
    id.fit_warnings = guard::check(m, &id, levels, opts);
    id
}

/// As [`identify`], with a caller-supplied basis evaluator (e.g. macro-generated code).
pub fn identify_with(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let model = &*input_delay::model(ir, opts)?;
    let id = pooled(model, eval, levels, opts)?;
    Ok(choose_rows(model, id, opts, |o| {
        identify_with(ir, eval, levels, o)
    }))
}

/// Identify separately at each level (for detection: an equivalent-linear parameter that
/// drifts with the level reveals a hidden nonlinearity).
pub fn identify_per_level(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Vec<Identification>, IdentifyError> {
    let ir = &*input_delay::model(ir, opts)?;
    let tape = Tape::compile(ir, &ir.eval_roots());
    let m = measure(ir, &tape, levels, opts)?;
    Ok((0..levels.len()).map(|i| m.identify_level(i)).collect())
}

/// The stacked system `C p = c` of all levels.
pub fn assemble(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<LinearSystem, IdentifyError> {
    let ir = &*input_delay::model(ir, opts)?;
    Ok(measure(ir, eval, levels, opts)?.system())
}
