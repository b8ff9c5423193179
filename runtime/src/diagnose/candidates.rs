//! The candidates of a search step: every effect of the library at every site of the
//! current model, less what the data cannot support (velocity terms where a body's
//! velocity is neither measured nor estimable from its position or acceleration) and the
//! kinds already found at a site; the backlash at a grid of gaps (multiples of the spread
//! of the relative displacement, measured or integrated from accelerations), refined once
//! around the best; and, when no single effect is accepted, pairs of the first step's
//! best.

use super::effects::{constant_force_sites, locations, Effect, Location};
use super::levels::Data;
use super::metrics;
use super::types::{CandidateScore, FoundEffect};
use crate::data::{LevelSource, RecordSource};
use crate::record::Record;
use dynid_ir::ir::{BodyId, ModelIr, SignalKind};
use dynid_ir::num;

/// Every effect at every location on top of `ir`, except the kinds already `found` at a
/// location (a second copy of a term is collinear with the first). What is not searched,
/// and why, is said once in `notes`.
pub(super) fn candidates(
    ir: &ModelIr,
    found: &[FoundEffect],
    data: &Data,
    notes: &mut Vec<String>,
) -> Vec<(Effect, Location)> {
    // A velocity term needs each velocity measured or estimable from a measured position
    // (identification then differentiates the position, see `ident::velocity`) or
    // acceleration (integrated, see `ident::integrate`).
    let vel_measured = ir.signals.iter().all(|s| match s.kind {
        SignalKind::Velocity(b) => {
            s.measured || ir.signal(ir.position(b)).measured || ir.acceleration_only(b)
        }
        _ => true,
    });
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
        let sg = sigma_s(ir, &data.displacements, loc);
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
    // A constant force on each body. Where the data carry no mean (centred records) its
    // column is zero and identification names it unidentifiable: the candidate then has
    // no value and is not scored ("not resolved by the data").
    for loc in constant_force_sites(ir, &locs) {
        if !already(Effect::ConstantForce.kind(), &loc) {
            cands.push((Effect::ConstantForce, loc));
        }
    }
    note_skipped(skipped_velocity, notes);
    cands
}

/// Say once what the search leaves out: the velocity terms when no velocity is measured
/// or estimable.
fn note_skipped(skipped_velocity: bool, notes: &mut Vec<String>) {
    if skipped_velocity && !notes.iter().any(|s| s.contains("velocities")) {
        notes.push(
            "velocities are neither measured nor estimable from positions: Coulomb friction and \
             quadratic damping candidates were skipped (cubic, quadratic stiffness, backlash, prestress and constant force were searched)"
                .into(),
        );
    }
}

/// The level whose recorded columns have the largest summed standard deviation.
fn largest_level(records: &[Record]) -> usize {
    let spread = |r: &Record| r.columns.iter().map(|c| metrics::std_dev(c)).sum::<f64>();
    (0..records.len())
        .max_by(|&a, &b| spread(&records[a]).total_cmp(&spread(&records[b])))
        .unwrap_or(0)
}

/// The displacement of every body of `ir` on the loudest of the levels `records` (named
/// `origins`): its recorded position, or for a body measured by its acceleration alone its
/// position integrated from the acceleration as identification integrates it
/// (`ident::integrate`: band-limited, or exactly over whole periods); `None` for a body
/// with neither, or where the integration fails. Once per diagnosis ([`Data`]): a search
/// step adds force elements, never bodies.
pub(super) fn displacements(
    ir: &ModelIr,
    records: &[Record],
    origins: &[String],
) -> Vec<Option<Vec<f64>>> {
    let big = largest_level(records);
    let rec = &records[big];
    let mut out: Vec<Option<Vec<f64>>> = ir
        .bodies
        .iter()
        .map(|b| rec.column(&format!("{}.x", b.name)).map(<[f64]>::to_vec))
        .collect();
    if out.iter().all(Option::is_some) {
        return out;
    }
    let Ok(src) = RecordSource::new(rec, ir, origins[big].clone()) else {
        return out;
    };
    let chunk = crate::ident::IdentifyOptions::default().chunk_len;
    let Ok(integrated) = crate::detect::from_data::integrated_levels(ir, &[&src], chunk, true)
    else {
        return out;
    };
    let Some(motion) = integrated.first() else {
        return out;
    };
    let slots: Vec<(usize, usize)> = (0..ir.bodies.len())
        .filter(|&b| out[b].is_none() && ir.acceleration_only(BodyId(b as u32)))
        .map(|b| (b, ir.position(BodyId(b as u32)).index()))
        .collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); slots.len()];
    let streamed = motion.stream(chunk, &mut |chunk_cols, len| {
        for (c, &(_, slot)) in cols.iter_mut().zip(&slots) {
            if let Some(x) = chunk_cols.get(slot) {
                c.extend_from_slice(&x[..len.min(x.len())]);
            }
        }
    });
    if streamed.is_ok() {
        for (c, (b, _)) in cols.into_iter().zip(slots) {
            out[b] = (c.len() == rec.len()).then_some(c);
        }
    }
    out
}

/// The standard deviation of the relative displacement `s` at `loc` among `disp` (the
/// bodies' displacements on one level; the backlash grid's gaps are multiples of it); 0
/// where a node's displacement is neither recorded nor integrated.
fn sigma_s(ir: &ModelIr, disp: &[Option<Vec<f64>>], loc: &Location) -> f64 {
    let col = |node: &str| {
        let b = ir.bodies.iter().position(|b| b.name == node)?;
        disp[b].as_deref()
    };
    let s: Vec<f64> = match (loc.a.as_str(), col(&loc.a), col(&loc.b)) {
        ("ground", _, Some(xb)) => xb.to_vec(),
        (_, Some(xa), Some(xb)) => xb.iter().zip(xa).map(|(b, a)| b - a).collect(),
        (_, Some(xa), None) if loc.b == "ground" => xa.iter().map(|a| -a).collect(),
        _ => return 0.0,
    };
    metrics::std_dev(&s)
}

/// The backlash gaps tried around the best grid gap of each location of `ir` (by the
/// cross-validated covariance residual among the `ranked` backlash candidates there).
pub(super) fn refined_backlash<'c>(
    ir: &ModelIr,
    ranked: impl Iterator<Item = &'c CandidateScore> + Clone,
) -> Vec<(Effect, Location)> {
    let mut refined = Vec::new();
    for loc in &locations(ir) {
        let best = ranked
            .clone()
            .filter(|s| s.location == *loc && matches!(s.effect, Effect::Backlash { .. }))
            .min_by(|a, b| a.cv_residual.total_cmp(&b.cv_residual));
        if let Some(Effect::Backlash { gap }) = best.map(|s| s.effect) {
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
    refined
}

/// How many of the first step's best candidates (by the cross-validated covariance
/// residual) are tried in pairs when no single effect is accepted: at most
/// `PAIR_POOL · (PAIR_POOL − 1) / 2 = 28` more measuring passes, and free runs only for the
/// pairs whose two coefficients are both significant.
const PAIR_POOL: usize = 8;

/// The pairs of the first step's best candidates in `ranking` (two of a kind at one site
/// excepted). A candidate the search left without a value (within its error of zero, its
/// column pruned) may still be half of a pair: those follow the valued ones, in ranking
/// order.
pub(super) fn pairs(ranking: &[CandidateScore]) -> Vec<(&CandidateScore, &CandidateScore)> {
    let pool: Vec<&CandidateScore> = ranking
        .iter()
        .filter(|c| c.value.is_finite())
        .chain(ranking.iter().filter(|c| !c.value.is_finite()))
        .take(PAIR_POOL)
        .collect();
    let mut pairs = Vec::new();
    for i in 0..pool.len() {
        for j in i + 1..pool.len() {
            if pool[i].location != pool[j].location
                || pool[i].effect.kind() != pool[j].effect.kind()
            {
                pairs.push((pool[i], pool[j]));
            }
        }
    }
    pairs
}
