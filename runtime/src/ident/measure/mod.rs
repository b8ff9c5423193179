//! The measuring pass, as a sequence of named steps: check the request, choose the bank and
//! the structure of the problem, take the first pass over every level (statistics, noise
//! floors, screens), decide the noise corrections, design the corners and the time blocks
//! and check that every level is long enough, prepare the level sources (estimated
//! velocities, zero-filled columns) and the rests to leave out, then stream every level once
//! through the filters to accumulate its moments.

mod checks;
mod pass;

use crate::basis::BasisEval;
use crate::data::LevelSource;
use crate::ident::accel::ZeroFill;
use crate::ident::bank::{choose_bank, BankChoice};
use crate::ident::columns::ColumnStore;
use crate::ident::design::{self, Designed};
use crate::ident::first_pass::{self, LevelSpan, LevelStats};
use crate::ident::integrate::{self, IntegratedMotion, Integration};
use crate::ident::measurement::Measurement;
use crate::ident::moments::PhaseTimes;
use crate::ident::pieces::{LevelPiece, MomentDesign};
use crate::ident::plan::{build_structure, Plan};
use crate::ident::rests;
use crate::ident::types::{CornerSource, IdentifyError, IdentifyOptions};
use crate::ident::velocity::{self, EstimatedVelocity, VelocityEstimate};
use crate::ident::NoiseSummary;
use crate::ident::{memory, noise};
use checks::{check_corners, check_lengths, check_rows};
use dynid_ir::ir::ModelIr;
use pass::{centred_levels, level_infos, Pass};
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Stream every level once through the filters and accumulate the moments: the design is
/// made from the first pass over all levels (see [`design_levels`]), the levels measured
/// with it into pieces (see [`measure_pieces`]), and the pieces read as one problem
/// ([`measurement_of`]) — the path of merged moment statistics, taken by every
/// identification.
pub fn measure<'m>(
    ir: &'m ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Measurement<'m>, IdentifyError> {
    let first = first_pass_all(ir, levels, opts)?;
    let design = design_levels(ir, opts, &first, levels)?;
    let (pieces, times) = measure_pieces(ir, eval, levels, opts, &design, first)?;
    measurement_of(ir, &design, pieces, times)
}

/// The structure and first pass of a request: the bank, the plan of the problem before its
/// design, and every level's first-pass statistics (with the time they took).
pub(crate) struct FirstPass {
    pub(crate) bank: BankChoice,
    pub(crate) plan: Plan,
    pub(crate) stats: Vec<LevelStats>,
    pub(crate) time: std::time::Duration,
}

/// Check the request, choose the bank and the structure, and take the first pass over
/// every level (statistics, noise floors, screens).
pub(crate) fn first_pass_all(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<FirstPass, IdentifyError> {
    check_request(ir, levels, opts)?;
    // Before any sample is read: a model too large for memory is refused with the estimate.
    memory::check(ir, levels.len(), opts, 0.0, "identification")?;
    let bank = choose_bank(ir, opts)?;
    let plan = build_structure(ir, opts.balance, &bank)?;
    let t0 = Instant::now();
    let stats = first_pass::all_levels(ir, &plan, levels, opts.chunk_len)?;
    Ok(FirstPass {
        bank,
        plan,
        stats,
        time: t0.elapsed(),
    })
}

/// The design of the levels of `first` taken together: the noise corrections, the corners
/// (given or designed from every level) and the time blocks (from the shortest level), each
/// level checked against them.
pub(crate) fn design_levels(
    ir: &ModelIr,
    opts: &IdentifyOptions,
    first: &FirstPass,
    levels: &[&dyn LevelSource],
) -> Result<MomentDesign, IdentifyError> {
    let fixes = noise::needs_fixes(&first.plan, &first.stats, opts.noise_correction);
    let mut plan = first.plan.clone();
    let n_blocks = set_filters(ir, opts, &first.bank, &mut plan, &first.stats, levels)?;
    check_rows(&plan, levels.len())?;
    Ok(MomentDesign::new(
        ir,
        opts,
        first.bank.order,
        plan.corners.clone(),
        plan.corner_source.clone(),
        n_blocks,
        fixes,
    ))
}

/// Give the structure `plan` the design's noise corrections and corners; per level of
/// `stats` the noise variances its moments are de-biased for, and the noise summary of
/// those levels.
pub(crate) fn apply_design(
    ir: &ModelIr,
    design: &MomentDesign,
    plan: &mut Plan,
    stats: &[LevelStats],
) -> (Vec<Vec<f64>>, NoiseSummary) {
    let opts = &design.options;
    let (var, summary) =
        noise::decide_designed(ir, plan, stats, opts.noise_correction, design.noise_fixes);
    plan.corner_source = design.corners_from.clone();
    plan.corners = vec![0.0; design.corners.len()];
    plan.set_corners(ir, &design.corners);
    (var, summary)
}

/// Measure every level of `first` with the design: one piece per level (its moments and
/// what the report and the solve read of it), and the time the pass took.
pub(crate) fn measure_pieces(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
    design: &MomentDesign,
    first: FirstPass,
) -> Result<(Vec<LevelPiece>, PhaseTimes), IdentifyError> {
    let FirstPass {
        mut plan,
        stats,
        time: stats_time,
        ..
    } = first;
    let (noise_var, _) = apply_design(ir, design, &mut plan, &stats);
    let n_blocks = design.n_blocks;

    let estimators = velocity_estimators(&plan, levels, opts.chunk_len)?;
    let sources: Vec<&dyn LevelSource> = if estimators.is_empty() {
        levels.to_vec()
    } else {
        estimators.iter().map(|e| e as &dyn LevelSource).collect()
    };
    let zero_filled = zero_fill(&plan, &sources);
    let sources: Vec<&dyn LevelSource> = if zero_filled.is_empty() {
        sources
    } else {
        zero_filled.iter().map(|z| z as &dyn LevelSource).collect()
    };
    let integrated = integrators(ir, &plan, &sources, opts.chunk_len, opts.allow_large)?;
    let sources: Vec<&dyn LevelSource> = if integrated.is_empty() {
        sources
    } else {
        integrated.iter().map(|z| z as &dyn LevelSource).collect()
    };
    let samples: Vec<usize> = stats.iter().map(|s| s.n).collect();
    let rests = rests::find_levels(
        ir,
        levels,
        &samples,
        n_blocks,
        opts.keep_rests,
        opts.filtered,
        opts.chunk_len,
    )?;

    let pass = Pass {
        ir,
        eval,
        plan: &plan,
        n_blocks,
        opts,
    };
    let t_pass = Instant::now();
    let (moments, mut times) = pass.all(&sources, &stats, &noise_var, &rests, &estimators)?;
    times.read += stats_time;
    times.pass += t_pass.elapsed();
    let infos = level_infos(ir, &plan, &stats, levels, &moments, &rests);
    let centred = centred_levels(&plan, &stats);
    let pieces = moments
        .into_iter()
        .zip(stats)
        .zip(infos)
        .zip(centred)
        .enumerate()
        .map(|(level, (((moments, stats), info), centred))| LevelPiece {
            moments,
            stats,
            info,
            centred,
            // Per estimated velocity (cutoff, half-width), then per integrated signal
            // (high-pass corner, 0) or (0, whole periods).
            velocity: estimators
                .get(level)
                .map(|e| e.designs().iter().map(|d| (d.1, d.2)).collect::<Vec<_>>())
                .unwrap_or_default()
                .into_iter()
                .chain(integrated.get(level).into_iter().flat_map(|m| {
                    (0..plan.integrated.len()).map(move |k| match m.how() {
                        Integration::Band { corner } => (corner, 0),
                        Integration::Periodic { periods, floor, .. } => {
                            (m.lowest_line(k).unwrap_or(floor), periods)
                        }
                    })
                }))
                .collect(),
        })
        .collect();
    Ok((pieces, times))
}

/// The measured problem of the pieces of one design (levels in their order): the plan
/// rebuilt from the model and the design, the noise summary over all pieces, and the
/// report of the estimated velocities per piece.
pub(crate) fn measurement_of<'m>(
    ir: &'m ModelIr,
    design: &MomentDesign,
    pieces: Vec<LevelPiece>,
    times: PhaseTimes,
) -> Result<Measurement<'m>, IdentifyError> {
    if pieces.is_empty() {
        return Err(IdentifyError::NoLevels);
    }
    let opts = design.identify_options();
    let bank = choose_bank(ir, &opts)?;
    let mut plan = build_structure(ir, opts.balance, &bank)?;
    let mut stats = Vec::with_capacity(pieces.len());
    let mut moments = Vec::with_capacity(pieces.len());
    let mut infos = Vec::with_capacity(pieces.len());
    let mut centred = Vec::with_capacity(pieces.len());
    let mut velocity = Vec::with_capacity(pieces.len());
    for p in pieces {
        stats.push(p.stats);
        moments.push(p.moments);
        infos.push(p.info);
        centred.push(p.centred);
        velocity.push(p.velocity);
    }
    let (_, noise) = apply_design(ir, design, &mut plan, &stats);
    check_rows(&plan, moments.len())?;
    let estimated = plan
        .estimated
        .iter()
        .enumerate()
        .map(|(k, (v, x))| VelocityEstimate {
            signal: ir.signal(*v).name.clone(),
            from: ir.signal(*x).name.clone(),
            method: velocity::METHOD.into(),
            cutoff: velocity
                .iter()
                .map(|l| l.get(k).map_or(0.0, |d| d.0))
                .collect(),
            half_width: velocity
                .iter()
                .map(|l| l.get(k).map_or(0, |d| d.1))
                .collect(),
        })
        .chain(integration_reports(ir, &plan, &velocity))
        .collect();
    Ok(Measurement {
        ir,
        store: Arc::new(ColumnStore::new(plan.clone(), moments)),
        cols: None,
        plan,
        infos,
        centred,
        estimated,
        rcond: opts.rcond,
        times,
        prune_t: 0.0,
        noise,
        efficient: opts.efficient,
        shrinkage: if opts.diagonal_weights {
            1.0
        } else {
            super::stats::SHRINKAGE
        },
        iterate_weights: opts.iterate_weights,
    })
}

/// Refuse a request that cannot be measured: no level, nothing to identify, or block and
/// chunk counts below two.
fn check_request(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<(), IdentifyError> {
    if levels.is_empty() {
        return Err(IdentifyError::NoLevels);
    }
    if ir.unknowns().is_empty() {
        return Err(IdentifyError::NoUnknowns);
    }
    if opts.chunk_len < 2 || opts.n_blocks.is_some_and(|b| b < 2) {
        return Err(IdentifyError::BadOption {
            message: "chunk length and number of blocks must be at least 2".into(),
            help: "use the defaults".into(),
        });
    }
    Ok(())
}

/// Design the filter corners from the first pass (or take the given ones), check them and
/// the length of every level, and set them in the plan; the number of time blocks.
fn set_filters(
    ir: &ModelIr,
    opts: &IdentifyOptions,
    bank: &BankChoice,
    plan: &mut Plan,
    stats: &[LevelStats],
    levels: &[&dyn LevelSource],
) -> Result<usize, IdentifyError> {
    let span = LevelSpan::of(stats);
    let designed = design_from_data(ir, plan, stats, &span, bank.order, bank.n_corners);
    let given = corners_given(ir, opts);
    plan.corner_source = CornerSource {
        filtered: opts.filtered,
        ..corner_source(given, designed.as_ref())
    };
    let corners = chosen_corners(ir, opts, designed.as_ref(), &span, bank);
    check_corners(&corners, given, stats, &span, levels)?;
    plan.corners = vec![0.0; corners.len()];
    plan.set_corners(ir, &corners);
    let n_blocks = opts.n_blocks.unwrap_or_else(|| {
        design::blocks_up_to(
            span.min_duration,
            design::time_constant(&corners, bank.order),
            span.min_samples,
            design::max_blocks(opts),
        )
    });
    check_lengths(
        stats,
        levels,
        &corners,
        bank.order,
        n_blocks,
        designed.as_ref(),
        &span,
    )?;
    Ok(n_blocks)
}

/// Corners designed from the dominant frequencies of the drivers and fitted to the
/// shortest level, with the band above the noise floor carried for the report: the lowest
/// over the levels and the measured drivers whose floor is white noise (a driver with a
/// floor of its own content, such as a controller's force, carries information up to the
/// Nyquist frequency).
fn design_from_data(
    ir: &ModelIr,
    plan: &Plan,
    stats: &[LevelStats],
    span: &LevelSpan,
    order: usize,
    n_corners: usize,
) -> Option<Designed> {
    let omegas: Vec<f64> = stats.iter().flat_map(|s| s.omegas.clone()).collect();
    let mut info: Option<(String, f64)> = None;
    for st in stats {
        for (k, s) in plan.y.iter().enumerate() {
            if !plan.drivers.contains(s) || !st.noise_flat[k] {
                continue;
            }
            if let Some(w) = st.info[k] {
                if info.as_ref().is_none_or(|(_, v)| w < *v) {
                    info = Some((ir.signal(*s).name.clone(), w));
                }
            }
        }
    }
    design::fit_corners_info(
        &omegas,
        info,
        span.ts_min,
        span.min_duration,
        order,
        n_corners,
    )
}

/// Whether the corners are given (by the options or the model's filter block).
fn corners_given(ir: &ModelIr, opts: &IdentifyOptions) -> bool {
    opts.corners.is_some() || ir.filter.as_ref().is_some_and(|f| !f.corners.is_empty())
}

/// Where the corners come from, for the report.
fn corner_source(given: bool, designed: Option<&Designed>) -> CornerSource {
    CornerSource {
        given,
        lower: designed.filter(|_| !given).map(|d| d.lower),
        upper: designed.filter(|_| !given).map(|d| d.upper),
        info_signal: designed.and_then(|d| d.info_signal.as_ref().map(|(n, _)| n.clone())),
        info_bandwidth: designed.and_then(|d| d.info_signal.as_ref().map(|(_, w)| *w)),
        filtered: false,
    }
}

/// The corners used: the options', else the model's, else the designed ones.
fn chosen_corners(
    ir: &ModelIr,
    opts: &IdentifyOptions,
    designed: Option<&Designed>,
    span: &LevelSpan,
    bank: &BankChoice,
) -> Vec<f64> {
    match (&opts.corners, ir.filter.as_ref().map(|f| &f.corners)) {
        (Some(c), _) => c.clone(),
        (None, Some(c)) if !c.is_empty() => c.clone(),
        // The filtered equation: one corner, as high as the measured signals carry
        // information above their noise floor, and at most `max_lt / Tₛ`.
        _ if opts.filtered => {
            let top = crate::ident::filtered::max_lt(opts, bank.order) / span.ts_min;
            let info = designed.and_then(|d| d.info_signal.as_ref().map(|(_, w)| *w));
            vec![info.map_or(top, |w| w.min(top))]
        }
        _ => match designed {
            Some(d) => d.corners.clone(),
            // Not even the fastest admissible corners settle: fall through to the length
            // check, which names the record length they need.
            None => {
                let cap = design::max_corner(span.ts_min);
                vec![cap / 2.0; bank.n_corners]
            }
        },
    }
}

/// Unmeasured velocities in nonlinear terms: estimated from the positions, per level
/// (none where the plan estimates none).
fn velocity_estimators<'a>(
    plan: &Plan,
    levels: &[&'a dyn LevelSource],
    chunk: usize,
) -> Result<Vec<EstimatedVelocity<'a>>, IdentifyError> {
    let targets: Vec<(usize, usize)> = plan
        .estimated
        .iter()
        .map(|(v, x)| (v.index(), x.index()))
        .collect();
    if targets.is_empty() {
        return Ok(Vec::new());
    }
    Ok(crate::first_error_in_order(levels.par_iter().map(|src| {
        EstimatedVelocity::design(*src, &targets, chunk)
    }))?)
}

/// Positions and velocities of acceleration-only bodies in nonlinear terms: integrated from
/// their accelerations, per level (none where the plan integrates none), with the
/// high-pass corner a quarter of the lowest filter corner (see [`integrate`]).
fn integrators<'a>(
    ir: &ModelIr,
    plan: &Plan,
    levels: &[&'a dyn LevelSource],
    chunk: usize,
    allow_large: bool,
) -> Result<Vec<IntegratedMotion<'a>>, IdentifyError> {
    let targets: Vec<integrate::Target> = plan
        .integrated
        .iter()
        .map(|(s, a)| integrate::Target {
            slot: s.index(),
            accel: a.index(),
            order: match ir.signal(*s).kind {
                dynid_ir::ir::SignalKind::Position(_) => 2,
                _ => 1,
            },
        })
        .collect();
    if targets.is_empty() {
        return Ok(Vec::new());
    }
    let corner = plan.corners.iter().copied().fold(f64::INFINITY, f64::min) / 4.0;
    Ok(IntegratedMotion::design_all(
        levels,
        &targets,
        &integrate::measured_inputs(ir),
        corner,
        chunk,
        allow_large,
    )?)
}

/// The report of the integrated signals: per level, the high-pass corner (rad/s; where the
/// level held whole periods and was integrated exactly, the lowest line kept), no window.
fn integration_reports<'a>(
    ir: &'a ModelIr,
    plan: &'a Plan,
    velocity: &'a [Vec<(f64, usize)>],
) -> impl Iterator<Item = VelocityEstimate> + 'a {
    let skip = plan.estimated.len();
    plan.integrated.iter().enumerate().map(move |(k, (s, a))| {
        let per = |l: &Vec<(f64, usize)>| l.get(skip + k).copied().unwrap_or((0.0, 0));
        let periods = velocity.iter().map(|l| per(l).1).find(|&p| p > 0);
        let band = velocity.iter().any(|l| per(l).1 == 0);
        let exact = |p| format!("{} ({p} periods)", integrate::METHOD_PERIODIC);
        let method = match (band, periods) {
            (true, Some(p)) => format!(
                "{}; levels of whole periods: {}",
                integrate::METHOD_BAND,
                exact(p)
            ),
            (false, Some(p)) => exact(p),
            _ => integrate::METHOD_BAND.to_string(),
        };
        VelocityEstimate {
            signal: ir.signal(*s).name.clone(),
            from: ir.signal(*a).name.clone(),
            method,
            cutoff: velocity.iter().map(|l| per(l).0).collect(),
            half_width: vec![0; velocity.len()],
        }
    })
}

/// Positions and velocities of acceleration-only bodies that roots read: streamed as zeros
/// (none where the plan has no such body).
fn zero_fill<'a>(plan: &Plan, sources: &[&'a dyn LevelSource]) -> Vec<ZeroFill<'a>> {
    if plan.absent.is_empty() {
        return Vec::new();
    }
    let slots: Vec<usize> = plan.absent.iter().map(|s| s.index()).collect();
    sources
        .iter()
        .map(|s| ZeroFill::new(*s, slots.clone()))
        .collect()
}

/// Check the levels of `first` against a design made before them (from a sample of the
/// data): its corners below every level's Nyquist frequency, every level long enough for
/// its filters and blocks.
pub(crate) fn check_against(
    design: &MomentDesign,
    first: &FirstPass,
    levels: &[&dyn LevelSource],
) -> Result<(), IdentifyError> {
    let span = LevelSpan::of(&first.stats);
    check_corners(&design.corners, true, &first.stats, &span, levels)?;
    check_lengths(
        &first.stats,
        levels,
        &design.corners,
        design.order,
        design.n_blocks,
        None,
        &span,
    )
}
