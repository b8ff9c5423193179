//! The unmeasured ends of a body measured only by its acceleration, removed from the rows.
//!
//! A term linear in such a body's position or velocity is formed from the acceleration by
//! a band-pass instrument `ι = J''` (see [`super::plan::BasisMoment::D0Acc`]). Over a run
//! `[t₀, t₁]` of the record, integrating by parts,
//!
//! ```text
//! ∫ ι x = ∫ J a + [J' x − J v],        ∫ ι v = −∫ J' a + [J' v],
//! ```
//!
//! and the rows read only `∫ J a` and `−∫ J' a`: the position and velocity at the ends are
//! not measured. What is dropped is, in every row of body `l`'s equation,
//!
//! ```text
//! Σ_ends ± ( J'(t) β_l(t) − J(t) γ_l(t) ),   β_l = Σ k x + Σ d v,   γ_l = Σ k v,
//! ```
//!
//! the sums over that equation's terms in the acceleration-only bodies, at the end `t`.
//! `β_l` and `γ_l` are unknown, but the same for every row of the equation; only the
//! instrument's `J'(t)` and `J(t)` change from row to row, and they are known (the
//! snapshots at the block boundaries hold `ι qᵀ` for every filter state). So the error lies
//! in the span of two known vectors per end over the equation's rows, and projecting those
//! rows onto the orthogonal complement of that span removes it exactly, whatever the ends
//! are — without estimating `x` or `v` there. Each end costs an equation two of its rows'
//! worth of information: with a single long record that is two or four rows of many.
//!
//! The projection is one linear map of a level's rows, the same for every column and the
//! right-hand side, for the whole record and every hat window alike (the hats still sum
//! to the whole record). The start of a record whose filters start at rest adds nothing
//! (`J = J' = 0` there, the vectors are dropped as zero); the ends of the runs between
//! rests are ends as well.
//!
//! Before this, the dropped terms biased the linear fit of a lightly damped five-body
//! structure from noiseless accelerations by −6 … −82 % in its masses and stiffnesses
//! (`tests/accel_structure.rs`).

use super::moments::LevelMoments;
use super::plan::{BasisMoment, Plan, RowCombination};

/// The rows of one equation and an orthonormal basis (over those rows) of the directions
/// the unmeasured ends reach.
#[derive(Clone, Debug)]
struct Group {
    rows: Vec<usize>,
    /// Per row: the weight of the metric the projection is orthogonal in.
    scale: Vec<f64>,
    basis: Vec<Vec<f64>>,
}

/// Per level: the projection that removes the unmeasured ends from its rows.
#[derive(Clone, Debug, Default)]
pub(crate) struct EndProjection {
    groups: Vec<Group>,
}

/// A vector of the span whose norm, after the earlier ones are removed, falls below this
/// fraction of its own is already in the span; one below this fraction of the largest
/// vector of the equation is a filter state at rest (a record's start).
const SPAN_TOL: f64 = 1e-10;

impl EndProjection {
    /// The projection for the level `lm` of `plan` (empty where no equation integrates an
    /// acceleration).
    pub fn new(plan: &Plan, lm: &LevelMoments, row_scale: &[f64]) -> Self {
        let ends: Vec<usize> = (0..=lm.n_blocks())
            .filter(|&j| lm.kept_before(j) != lm.kept_after(j))
            .collect();
        let mut groups = Vec::new();
        for (l, terms) in plan.equations.iter().enumerate() {
            let position = terms
                .iter()
                .any(|t| matches!(t.basis, BasisMoment::D0Acc(_)));
            let velocity = terms
                .iter()
                .any(|t| matches!(t.basis, BasisMoment::D1Acc(_)));
            if !(position || velocity) {
                continue;
            }
            let rows: Vec<usize> = (0..plan.rows.len())
                .filter(|&r| plan.rows[r].1 == l)
                .collect();
            let instrument = |r: usize| &plan.instruments[plan.rows[r].0];
            let scale: Vec<f64> = rows.iter().map(|&r| row_scale[r]).collect();
            let mut vectors = Vec::new();
            for &j in &ends {
                vectors.push(end_vector(lm, j, &rows, |r| instrument(r).i1.as_ref()));
                if position {
                    vectors.push(end_vector(lm, j, &rows, |r| instrument(r).i2.as_ref()));
                }
            }
            for v in &mut vectors {
                v.iter_mut().zip(&scale).for_each(|(a, s)| *a *= s);
            }
            let basis = orthonormal(vectors);
            if !basis.is_empty() {
                groups.push(Group { rows, scale, basis });
            }
        }
        EndProjection { groups }
    }

    /// Remove the ends' directions from a column's entries `y` (one per row of the level).
    pub fn apply(&self, y: &mut [f64]) {
        for g in &self.groups {
            let mut z: Vec<f64> = g
                .rows
                .iter()
                .zip(&g.scale)
                .map(|(&r, s)| y[r] * s)
                .collect();
            for q in &g.basis {
                let dot: f64 = z.iter().zip(q).map(|(a, b)| a * b).sum();
                z.iter_mut().zip(q).for_each(|(a, b)| *a -= dot * b);
            }
            for ((&r, s), zi) in g.rows.iter().zip(&g.scale).zip(z) {
                y[r] = zi / s;
            }
        }
    }
}

/// The values at block boundary `j` of the combination `comb(r)` of each row's instrument
/// (`J'` or `J`), up to one common factor: the snapshots hold `ι q_k` for every snapshot
/// column `k`, and the column with the largest values gives the direction (`q_k(t)` is a
/// common factor of the whole vector). Rows whose instrument lacks the combination get 0.
fn end_vector<'p>(
    lm: &LevelMoments,
    j: usize,
    rows: &[usize],
    comb: impl Fn(usize) -> Option<&'p RowCombination>,
) -> Vec<f64> {
    let snap = &lm.snaps[j];
    let n = lm.n_snap_cols;
    let at = |r: usize, k: usize| -> f64 {
        comb(r).map_or(0.0, |c| c.iter().map(|&(i, a)| a * snap[i * n + k]).sum())
    };
    let best = (0..n)
        .map(|k| (k, rows.iter().map(|&r| at(r, k).powi(2)).sum::<f64>()))
        .filter(|(_, s)| s.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k);
    match best {
        Some(k) => rows.iter().map(|&r| at(r, k)).collect(),
        None => vec![0.0; rows.len()],
    }
}

/// An orthonormal basis of the span of `vectors` (Gram–Schmidt, applied twice), leaving
/// out vectors already in the span and those negligible against the largest.
fn orthonormal(vectors: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let largest = vectors.iter().map(|v| norm(v)).fold(0.0, f64::max);
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for mut v in vectors {
        let n0 = norm(&v);
        // (A vector with a non-finite entry counts as negligible too.)
        if n0.partial_cmp(&(SPAN_TOL * largest)) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        for _ in 0..2 {
            for q in &basis {
                let dot: f64 = v.iter().zip(q).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(q).for_each(|(a, b)| *a -= dot * b);
            }
        }
        let n1 = norm(&v);
        if n1 > SPAN_TOL * n0 {
            v.iter_mut().for_each(|a| *a /= n1);
            basis.push(v);
        }
    }
    basis
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_projection_removes_exactly_the_span_and_keeps_its_complement() {
        let a = vec![1.0, 2.0, 0.0, 1.0];
        let b = vec![0.0, 1.0, 1.0, -1.0];
        let basis = orthonormal(vec![a.clone(), b.clone(), vec![2.0, 4.0, 0.0, 2.0]]);
        assert_eq!(
            basis.len(),
            2,
            "the third vector is in the span of the first"
        );
        let p = EndProjection {
            groups: vec![Group {
                rows: vec![0, 2, 3, 5],
                scale: vec![1.0; 4],
                basis,
            }],
        };
        // A column in the span vanishes on the group's rows; other rows are untouched.
        let mut y = vec![0.0; 6];
        for (k, &r) in [0, 2, 3, 5].iter().enumerate() {
            y[r] = 3.0 * a[k] - 2.0 * b[k];
        }
        y[1] = 7.0;
        y[4] = -1.5;
        p.apply(&mut y);
        for r in [0, 2, 3, 5] {
            assert!(y[r].abs() < 1e-14, "row {r}: {}", y[r]);
        }
        assert_eq!((y[1], y[4]), (7.0, -1.5));
        // A column orthogonal to the span is kept as it is.
        let mut z = vec![1.0, 4.0, 0.0, -1.0, 0.0, -1.0];
        let before = z.clone();
        p.apply(&mut z);
        for (u, v) in z.iter().zip(&before) {
            assert!((u - v).abs() < 1e-14);
        }
    }
}
