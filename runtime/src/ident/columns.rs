//! The least-squares rows of a measured model, formed column by column and kept.
//!
//! A level's rows `(C, c)` are read from its moments: the whole record's (the estimate) and
//! each hat window's (the standard errors, see [`super::stats`]). A model is solved many
//! times from the same moments — pooled, per level, in each cross-validation fold, and, in
//! a structure search, as each of hundreds of sub-models ([`Measurement::restricted`]) that
//! share all columns but one. So the rows are formed one column at a time (an unknown's,
//! or the right-hand side's), at every level and window at once, and a formed column is
//! kept and shared: a solve only gathers the columns it uses.
//!
//! A hat window's entries are read one by one from the block sums ([`Hat`]), never as the
//! whole `n_i × n_w` matrices: a column needs a few entries per row.
//!
//! [`Measurement::restricted`]: super::measurement::Measurement::restricted

use super::ends::EndProjection;
use super::moments::{Hat, LevelMoments, MomentView, Window};
use super::plan::{BasisMoment, Instrument, Plan, TermCoef};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// One column of the rows at one level: its entries in the whole-record rows and in the
/// rows of each hat window (`0 ..= n_blocks`).
pub(crate) struct LevelColumn {
    pub view: Vec<f64>,
    pub hats: Vec<Vec<f64>>,
}

/// One column of the rows, per level.
pub(crate) type Column = Vec<LevelColumn>;

/// A term of a row's equation in one column: its coefficient (`scale` of an unknown, `−v`
/// of a known term moved to the right-hand side) and the moment it multiplies.
type ColumnTerm = (f64, BasisMoment);

/// The measured model's moments and the columns of its rows formed so far.
pub(crate) struct ColumnStore {
    plan: Plan,
    pub levels: Vec<LevelMoments>,
    views: Vec<OnceLock<MomentView>>,
    /// Per level: the projection that removes the unmeasured ends of acceleration-only
    /// bodies from its rows (see [`super::ends`]).
    ends: Vec<OnceLock<EndProjection>>,
    /// Per column (the unknowns, then the right-hand side), per row: its terms.
    terms: Vec<Vec<Vec<ColumnTerm>>>,
    formed: Vec<OnceLock<Arc<Column>>>,
}

impl ColumnStore {
    pub fn new(plan: Plan, levels: Vec<LevelMoments>) -> Self {
        let ncol = plan.unknowns.len();
        let mut terms = vec![vec![Vec::new(); plan.rows.len()]; ncol + 1];
        for (r, &(_, l)) in plan.rows.iter().enumerate() {
            for t in &plan.equations[l] {
                match t.coef {
                    TermCoef::Unknown { col, scale } => terms[col][r].push((scale, t.basis)),
                    TermCoef::Known(v) => terms[ncol][r].push((-v, t.basis)),
                }
            }
        }
        ColumnStore {
            views: levels.iter().map(|_| OnceLock::new()).collect(),
            ends: levels.iter().map(|_| OnceLock::new()).collect(),
            formed: (0..=ncol).map(|_| OnceLock::new()).collect(),
            terms,
            plan,
            levels,
        }
    }

    /// Columns of the rows: the measured model's unknowns, then the right-hand side (the
    /// last, index [`Self::rhs`]).
    pub fn rhs(&self) -> usize {
        self.plan.unknowns.len()
    }

    /// Column `c`, formed now and kept if it is not yet.
    pub fn column(&self, c: usize) -> Arc<Column> {
        let cell = &self.formed[c];
        if let Some(col) = cell.get() {
            return Arc::clone(col);
        }
        // Formed outside the cell's lock (two threads may both form it; one is kept), so
        // a caller inside a parallel loop never waits on work its own thread might run.
        let _ = cell.set(Arc::new(self.form(c)));
        Arc::clone(cell.get().expect("invariant: the cell was just set"))
    }

    /// Column `c`: the kept one if it is formed, else formed for the caller alone (a
    /// candidate's column in a structure search is read by that candidate only).
    pub fn column_unkept(&self, c: usize) -> Arc<Column> {
        match self.formed[c].get() {
            Some(col) => Arc::clone(col),
            None => Arc::new(self.form(c)),
        }
    }

    fn view(&self, i: usize) -> &MomentView {
        self.views[i].get_or_init(|| self.levels[i].view())
    }

    fn ends(&self, i: usize) -> &EndProjection {
        self.ends[i].get_or_init(|| {
            if !self.plan.integrates {
                return EndProjection::default();
            }
            // The metric: every row of the whole record at unit norm over all columns, as
            // the solve weighs them (a row without a norm keeps its scale).
            let view = self.view(i);
            let (ncol, nr) = (self.rhs(), self.plan.rows.len());
            let mut c = vec![0.0; nr * ncol];
            for j in 0..ncol {
                for (r, v) in self.entries(j, view).into_iter().enumerate() {
                    c[r * ncol + j] = v;
                }
            }
            let rhs = self.entries(ncol, view);
            let scale: Vec<f64> = super::measurement::row_weights(&c, &rhs, ncol)
                .into_iter()
                .map(|w| if w > 0.0 { w } else { 1.0 })
                .collect();
            EndProjection::new(&self.plan, &self.levels[i], &scale)
        })
    }

    fn form(&self, c: usize) -> Column {
        (0..self.levels.len())
            .into_par_iter()
            .map(|i| {
                let lm = &self.levels[i];
                let ends = self.ends(i);
                let projected = |mut y: Vec<f64>| {
                    ends.apply(&mut y);
                    y
                };
                LevelColumn {
                    view: projected(self.entries(c, self.view(i))),
                    hats: (0..=lm.n_blocks())
                        .map(|j| projected(self.entries(c, &Hat::new(lm, j))))
                        .collect(),
                }
            })
            .collect()
    }

    /// Column `c`'s entry in every row, for the weight whose moments `w` reads.
    fn entries(&self, c: usize, w: &impl Window) -> Vec<f64> {
        let plan = &self.plan;
        self.terms[c]
            .iter()
            .zip(&plan.rows)
            .map(|(terms, &(k, _))| {
                let ins = &plan.instruments[k];
                let mut v = 0.0;
                for (coef, basis) in terms {
                    v += coef
                        * match &ins.filtered {
                            Some(a) => plan.filtered_moment(a, plan.filtered_of(basis), w),
                            None => term_moment(ins, basis, w),
                        };
                }
                v
            })
            .collect()
    }
}

/// Invariant: a row is formed only where its instrument has the derivatives its terms need
/// (`Plan::set_corners` keeps only computable rows).
const ROW_NEEDS_DERIVATIVES: &str = "invariant: the row's instrument has the derivatives it needs";

/// The moment `⟨φ ι basis⟩` of an instrument from a weight's moments (`φ ≡ 1` for the
/// whole record; the `φ'` terms of a hat window vanish there, see the `moments` module).
pub(crate) fn term_moment(ins: &Instrument, basis: &BasisMoment, v: &impl Window) -> f64 {
    let a = &ins.a;
    match *basis {
        BasisMoment::Static(w) => v.mean(a, w),
        BasisMoment::D1Pos(x) => {
            -v.mean(ins.a1.as_ref().expect(ROW_NEEDS_DERIVATIVES), x) + v.bnd(a, x) - v.mean_d(a, x)
        }
        BasisMoment::D2Vel(w, body) => {
            if ins.power == Some(body) {
                0.5 * (v.bnd(a, w) - v.mean_d(a, w))
            } else {
                -v.mean(ins.a1.as_ref().expect(ROW_NEEDS_DERIVATIVES), w) + v.bnd(a, w)
                    - v.mean_d(a, w)
            }
        }
        // The integrals of a band-pass instrument: no boundary term (the velocity and
        // position at the ends are not measured; the directions they reach are projected
        // out of the rows afterwards, see `super::ends`), and no `φ'` term in a hat window
        // (the hats' contributions then sum exactly to the record's; each carries a
        // boundary error of its own, which the standard errors count as spread).
        BasisMoment::D1Acc(w) => -v.mean(ins.i1.as_ref().expect(ROW_NEEDS_DERIVATIVES), w),
        BasisMoment::D0Acc(w) => v.mean(ins.i2.as_ref().expect(ROW_NEEDS_DERIVATIVES), w),
        BasisMoment::D2Pos(x, q) => {
            let a1 = ins.a1.as_ref().expect(ROW_NEEDS_DERIVATIVES);
            v.mean(ins.a2.as_ref().expect(ROW_NEEDS_DERIVATIVES), x) - v.bnd(a1, x)
                + v.bnd(a, q)
                + 2.0 * v.mean_d(a1, x)
                - v.bnd_d(a, x)
        }
    }
}

/// The row-major whole-record rows `(C, c)` of level `i` from the columns `cols` (the
/// unknowns in order, then the right-hand side), with the `held` columns moved to the
/// right-hand side. (The hat windows' rows are read from the columns directly, see
/// [`super::stats::sandwich_stderr`].)
pub(crate) fn gather(
    cols: &[Arc<Column>],
    i: usize,
    held: &[(usize, f64)],
) -> (Vec<f64>, Vec<f64>) {
    let (unknowns, rhs) = cols.split_at(cols.len() - 1);
    let ncol = unknowns.len();
    let mut rhs = rhs[0][i].view.clone();
    let nr = rhs.len();
    let mut c = vec![0.0; nr * ncol];
    for (j, col) in unknowns.iter().enumerate() {
        for (r, &v) in col[i].view.iter().enumerate() {
            c[r * ncol + j] = v;
        }
    }
    for (r, b) in rhs.iter_mut().enumerate() {
        for &(j, v) in held {
            *b -= v * c[r * ncol + j];
            c[r * ncol + j] = 0.0;
        }
    }
    (c, rhs)
}
