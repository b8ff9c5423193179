//! Rows of the filtered equation ([`super::types::IdentifyOptions::filtered`]).
//!
//! At one corner `λ`, let `F = (λ/(s+λ))ᴷ` be the bank's low-pass chain (its last state).
//! Every term of an equation of motion passes through `F` as a combination of filter
//! states: a static column `g` through the chain it drives (`F g`, a column chain, see
//! [`super::plan::RootDriver`]), `ẋ` and `ẍ` through the chain of the measured position
//! (`F ẋ = (F x)'`, `F ẍ = (F x)''`, combinations of the chain's states by
//! `ζᵢ' = λ (ζᵢ₋₁ − ζᵢ)`), and a constant unchanged. The filtered equation
//! `Σᵢ θᵢ F φᵢ = F f` holds at every sample, with no derivative of the data.
//!
//! Its rows are moments of products of two filtered signals: per equation and unknown
//! `θⱼ` of it, the instrument is the unknown's own filtered regressor `F φⱼ`, and the row
//! `⟨F φⱼ · (Σᵢ θᵢ F φᵢ − F f)⟩ = 0` — the normal equation of regressing the filtered
//! equation sample by sample, written as moments (the rows are solved by SVD like every
//! other; the products are accumulated, never squared afterwards). The products need the
//! states themselves as columns of `w`: the plan's [`Plan::state_cols`], after the noise
//! columns; a constant's products are the means of the states, and its square the window's
//! weight. No boundary term enters (nothing is moved onto an instrument), so each time
//! block's contribution is an exact estimating equation of its own.
//!
//! Efficiency: with the equation error `e` white, the regression of the filtered equation
//! is least squares on `F e`; on the servo axis, measured on the bench `servo_precision`
//! (docs/method.md §2, "Rows of the filtered equation").

use super::moments::Window;
use super::noise::fix::{linear_form, split_factor};
use super::plan::{BasisMoment, FCombo, FElem, Instrument, Plan, RowCombination, TermCoef};
use dynid_ir::ir::{ExprNode, ModelIr, SignalId};

/// Highest corner of the filtered equation's chain when it is designed from the data,
/// as `λ Tₛ`: on the servo axis of the bench `servo_precision` (seeds 1–48) the mass's
/// mean error is −0.13 % (random references) and −0.17 % (planned moves) at `λ Tₛ = 1`
/// (160 Hz at 1 kHz), +0.006 % and +0.007 % at 0.5.
pub(crate) const FILTERED_MAX_LT: f64 = 0.5;

/// Sections of the filtered equation's chain with the inputs' delays estimated
/// ([`super::types::IdentifyOptions::input_delay`]), unless the options or the model's
/// filter block give an order. The delay takes up the first-order lag of the force's path
/// between samples; what is left enters through what the chain passes near and above the
/// Nyquist frequency, where the sampled force misstates its path between samples, and a
/// chain of more sections passes less of it at the same corner. Mean error of the mass on
/// the random references of the bench `servo_precision` (seeds 1–48, row `dynid filt.+delay
/// 4 sect.` with `DYNID_BENCH_FILTERED_ORDER` and `DYNID_BENCH_FILTERED_CORNER` set), with
/// its mean standard error 0.0004–0.0007 %: 4 sections −0.0005 % at `λ Tₛ = 0.25`,
/// −0.0023 % at 0.35, −0.0098 % at 0.5; 6 sections −0.0001 % at 0.4, −0.0003 % at 0.5,
/// −0.0020 % at 0.7; 8 sections −0.0003 % at 0.6, −0.0017 % at 0.8. Six sections keep the
/// bias below the standard error up to 0.5 — the cap without the delay — where the planned
/// moves' mass, whose error is the force noise's, gains from the wider band (RMS 0.0085 %
/// with 4 sections at 0.25, 0.0072 % with 6 at 0.5; designed, the corner stops at the
/// position's information bandwidth, below the cap on those records: 0.0081 %).
pub(crate) const FILTERED_DELAY_ORDER: usize = 6;

/// The cap of the filtered equation's designed corner with the inputs' delays estimated
/// on a chain of fewer than [`FILTERED_DELAY_ORDER`] sections (an order given by the
/// options or the model): with 4 sections the mass's mean error on the random references
/// is −0.0005 % at `λ Tₛ = 0.25` and −0.0098 % at 0.5 (see [`FILTERED_DELAY_ORDER`]).
pub(crate) const FILTERED_DELAY_MAX_LT: f64 = 0.25;

/// The highest designed corner of the filtered equation for `opts` on a chain of `order`
/// sections, as `λ Tₛ`.
pub(crate) fn max_lt(opts: &super::types::IdentifyOptions, order: usize) -> f64 {
    if opts.input_delay && order < FILTERED_DELAY_ORDER {
        FILTERED_DELAY_MAX_LT
    } else {
        FILTERED_MAX_LT
    }
}

/// Why a model's filtered equation cannot be formed.
pub(crate) fn unsupported(what: &str) -> String {
    format!(
        "the rows of the filtered equation need every term as a filter output of a measured \
         signal; {what}"
    )
}

impl Plan {
    /// The chain of driver `d` at the filtered corner (the first): its last state.
    fn last_state(&self, d: usize) -> usize {
        self.state(d, 0, self.order - 1)
    }

    /// The chain driven by measured signal `s`, if any.
    fn driver_of(&self, s: SignalId) -> Option<usize> {
        self.drivers.iter().position(|&d| d == s)
    }

    /// `F s` for a measured signal `s` that drives a chain, or a velocity whose position
    /// drives one (`F v = (F x)'`).
    fn filtered_signal(&self, ir: &ModelIr, s: SignalId) -> Result<RowCombination, String> {
        let from_position = match ir.signal(s).kind {
            dynid_ir::ir::SignalKind::Velocity(b) => self.driver_of(ir.position(b)),
            _ => None,
        };
        match (self.driver_of(s), from_position) {
            (Some(d), _) => Ok(vec![(self.last_state(d), 1.0)]),
            (None, Some(d)) => self
                .deriv(ir, &vec![(self.last_state(d), 1.0)])
                .ok_or_else(|| unsupported("a chain is too short for the derivatives")),
            (None, None) => Err(unsupported(&format!(
                "`{}` drives no filter chain (add it to the model's `filter … driven_by`)",
                ir.signal(s).name
            ))),
        }
    }

    /// The filtered regressor `F b` of a term's basis, as a combination of row signals and
    /// constant columns.
    pub(crate) fn filtered_basis(&self, ir: &ModelIr, b: &BasisMoment) -> Result<FCombo, String> {
        let n_g = self.roots.len();
        let iota = |c: RowCombination| -> FCombo {
            c.into_iter().map(|(i, v)| (FElem::Iota(i), v)).collect()
        };
        let y_signal = |w: usize| self.y[w - n_g];
        let derivs = |s: SignalId, n: usize| -> Result<FCombo, String> {
            let mut c = self.filtered_signal(ir, s)?;
            for _ in 0..n {
                c = self
                    .deriv(ir, &c)
                    .ok_or_else(|| unsupported("a chain is too short for the derivatives"))?;
            }
            Ok(iota(c))
        };
        match *b {
            BasisMoment::Static(w) if w >= n_g => derivs(y_signal(w), 0),
            BasisMoment::Static(w) => {
                let root = self.roots[w];
                if let ExprNode::Const(value) = ir.exprs[root.index()] {
                    return Ok(vec![(
                        FElem::Const {
                            col: w,
                            value: f64::from_bits(value),
                        },
                        1.0,
                    )]);
                }
                if let Some(k) = self.root_drivers.iter().position(|r| r.root == w) {
                    return Ok(vec![(
                        FElem::Iota(self.last_state(self.drivers.len() + k)),
                        1.0,
                    )]);
                }
                let (f, core) = split_factor(ir, root);
                let lin = linear_form(ir, core).ok_or_else(|| {
                    unsupported(&format!(
                        "`{}` drives no filter chain",
                        dynid_ir::print::render_expr(ir, root)
                    ))
                })?;
                let mut out = FCombo::new();
                for (s, c) in lin {
                    for (e, v) in derivs(s, 0)? {
                        out.push((e, f * c * v));
                    }
                }
                Ok(out)
            }
            BasisMoment::D1Pos(x) => derivs(y_signal(x), 1),
            BasisMoment::D2Pos(x, _) => derivs(y_signal(x), 2),
            BasisMoment::D2Vel(v, body) => match self.driver_of(ir.position(body)) {
                Some(_) => derivs(ir.position(body), 2),
                None => derivs(y_signal(v), 1),
            },
            BasisMoment::D1Acc(_) | BasisMoment::D0Acc(_) => Err(unsupported(
                "a body measured only by its acceleration is not (its motion is an integral)",
            )),
        }
    }

    /// The filtered regressors of every term, the instruments (one per equation and
    /// unknown in it: the unknown's filtered regressor) and their rows, and the filter
    /// states the products need as columns.
    pub(crate) fn set_filtered_rows(&mut self, ir: &ModelIr) -> Result<(), String> {
        let mut terms: Vec<(BasisMoment, FCombo)> = Vec::new();
        for t in self.equations.iter().flatten() {
            if !terms.iter().any(|(b, _)| *b == t.basis) {
                terms.push((t.basis, self.filtered_basis(ir, &t.basis)?));
            }
        }
        let of = |b: &BasisMoment| -> &FCombo {
            &terms
                .iter()
                .find(|(c, _)| c == b)
                .expect("invariant: every term's basis is filtered")
                .1
        };
        let mut inst = Vec::new();
        let mut rows = Vec::new();
        for (l, eq) in self.equations.iter().enumerate() {
            let mut cols: Vec<usize> = Vec::new();
            for t in eq {
                if let TermCoef::Unknown { col, .. } = t.coef {
                    if !cols.contains(&col) {
                        cols.push(col);
                    }
                }
            }
            for col in cols {
                let mut a = FCombo::new();
                for t in eq {
                    if let TermCoef::Unknown { col: c, scale } = t.coef {
                        if c == col {
                            a.extend(of(&t.basis).iter().map(|&(e, v)| (e, scale * v)));
                        }
                    }
                }
                rows.push((inst.len(), l));
                inst.push(Instrument {
                    label: format!(
                        "F·{} (λ={:.3})",
                        ir.params[self.unknowns[col]].name, self.corners[0]
                    ),
                    a: Vec::new(),
                    a1: None,
                    a2: None,
                    power: None,
                    i1: None,
                    i2: None,
                    filtered: Some(a),
                });
            }
        }
        let n_fs = self.n_filter_states();
        let mut states: Vec<usize> = Vec::new();
        for (_, c) in &terms {
            for &(e, _) in c {
                if let FElem::Iota(i) = e {
                    if i < n_fs && !states.contains(&i) {
                        states.push(i);
                    }
                }
            }
        }
        states.sort_unstable();
        // The snapshot columns of the end-point velocities follow `w`: shift them by the
        // change in the number of state columns.
        let (old, new) = (self.state_cols.len(), states.len());
        for eq in &mut self.equations {
            for t in eq.iter_mut() {
                if let BasisMoment::D2Pos(x, q) = t.basis {
                    t.basis = BasisMoment::D2Pos(x, q - old + new);
                }
            }
        }
        // The shift changes the D2Pos bases the regressors were keyed by.
        for (b, _) in &mut terms {
            if let BasisMoment::D2Pos(x, q) = *b {
                *b = BasisMoment::D2Pos(x, q - old + new);
            }
        }
        self.state_cols = states;
        self.filtered_terms = terms;
        self.instruments = inst;
        self.rows = rows;
        Ok(())
    }

    /// Column of `w` that holds filter state `i` (one of [`Plan::state_cols`]).
    pub(crate) fn state_col(&self, i: usize) -> Option<usize> {
        let base = self.roots.len() + self.y.len() + self.extra.len();
        self.state_cols
            .iter()
            .position(|&s| s == i)
            .map(|k| base + k)
    }

    /// The filtered regressor of a basis ([`Self::set_filtered_rows`] formed them).
    pub(crate) fn filtered_of(&self, b: &BasisMoment) -> &FCombo {
        &self
            .filtered_terms
            .iter()
            .find(|(c, _)| c == b)
            .expect("invariant: every term's basis is filtered")
            .1
    }

    /// `⟨φ · a · b⟩` of two filtered signals for a weight's moments `v`.
    pub(crate) fn filtered_moment(&self, a: &FCombo, b: &FCombo, v: &impl Window) -> f64 {
        let n_fs = self.n_filter_states();
        let n_g = self.roots.len();
        // A row signal as a column of `w`: a state among the state columns, or a measured
        // signal.
        let as_col = |i: usize| -> Option<usize> {
            if i < n_fs {
                self.state_col(i)
            } else {
                Some(n_g + (i - n_fs))
            }
        };
        let prod = |x: FElem, y: FElem| -> f64 {
            match (x, y) {
                (FElem::Iota(i), FElem::Iota(j)) => match as_col(j) {
                    Some(col) => v.mean(&[(i, 1.0)], col),
                    None => v.mean(
                        &[(j, 1.0)],
                        as_col(i).expect("invariant: one of two states is a column"),
                    ),
                },
                (FElem::Iota(i), FElem::Const { col, .. })
                | (FElem::Const { col, .. }, FElem::Iota(i)) => v.mean(&[(i, 1.0)], col),
                (FElem::Const { value: p, .. }, FElem::Const { value: q, .. }) => {
                    p * q * v.weight()
                }
            }
        };
        let mut s = 0.0;
        for &(x, cx) in a {
            for &(y, cy) in b {
                s += cx * cy * prod(x, y);
            }
        }
        s
    }
}

/// Samples after which the bank's chain (order `order`, corner `lambda` rad/s) has
/// forgotten to `tol`: its step response is within `tol` of its end value,
/// `e^{−λt} Σ_{k<K} (λt)ᵏ/k! < tol`. A filtered equation read earlier than that after the
/// record's start (the chains start at zero, the signals do not: [`START_TOL`]) or after a
/// rest (where the model does not hold: [`REST_TOL`]) carries what the filter remembers of
/// it.
pub(crate) fn forget_samples(lambda: f64, order: usize, ts: f64, tol: f64) -> usize {
    let tail = |u: f64| {
        let (mut term, mut sum) = (1.0, 1.0);
        for k in 1..order {
            term *= u / k as f64;
            sum += term;
        }
        (-u).exp() * sum
    };
    let mut u = 1.0;
    while tail(u) > tol {
        u += 0.5;
    }
    (u / (lambda * ts)).ceil() as usize
}

/// What the filter may remember of the record's start: the positions' start value, which
/// may be far larger than their motion, enters `F ẍ` as `x(0) h'(t)`.
pub(crate) const START_TOL: f64 = 1e-13;

/// What the filter may remember of a rest or a reversal: a force error of the order of the
/// friction force.
pub(crate) const REST_TOL: f64 = 1e-6;

/// The intervals `[a, b)` a filtered equation's rows leave out: the record's first `start`
/// samples and each rest with the `after` samples after it, merged and within `0 .. n`.
pub(crate) fn left_out(
    rests: &[(usize, usize)],
    n: usize,
    start: usize,
    after: usize,
) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    let spans = std::iter::once((0, start)).chain(rests.iter().map(|&(a, b)| (a, b + after)));
    for (a, b) in spans {
        let (a, b) = (a.min(n), b.min(n));
        if b <= a {
            continue;
        }
        match out.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}
