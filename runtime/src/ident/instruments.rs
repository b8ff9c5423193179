//! The instruments of a plan once its filter corners are fixed, and the (instrument,
//! equation) rows they make computable: an instrument `a·ι` with its derivatives `a'·ι`,
//! `a''·ι` where they are free of the driving signal's current sample, and the balance
//! signals where velocities are measured.

use super::bank::ACC_MIN_DEGREE;
use super::plan::{BasisMoment, Instrument, Plan, RowCombination};
use dynid_ir::ir::{BodyId, ModelIr, SignalId, SignalKind};

impl Plan {
    /// Why an unknown column that is zero (or, for a constant force, has no mean) cannot be
    /// identified.
    pub fn zero_column_reason(&self, col: usize) -> String {
        if self.constant.get(col).copied().unwrap_or(false) {
            "a constant force needs data whose mean is not zero: every signal driving the \
             filters has zero mean (the records were centred), so its column (the mean of \
             each filter output) is zero but for the filters' start — measure without \
             removing the mean, or remove the term"
                .into()
        } else {
            "never excited at these levels: its column of moments is zero \
             (the term it multiplies vanishes on the data)"
                .into()
        }
    }

    /// Fix the corners and derive the instruments and the computable rows.
    ///
    /// Long: the instruments and the rows they make computable are derived together, in
    /// the order the rows take in `C`.
    pub fn set_corners(&mut self, ir: &ModelIr, corners: &[f64]) {
        assert_eq!(corners.len(), self.corners.len());
        self.corners = corners.to_vec();
        if self.filtered {
            self.set_filtered_rows(ir)
                .expect("invariant: checked when the plan was built");
            return;
        }
        let mut inst = Vec::new();
        for d in 0..self.n_drivers() {
            let driver = self.driver_name(ir, d);
            for (c, &lam) in self.corners.iter().enumerate() {
                for i in (self.min_degree - 1)..self.order {
                    let a = vec![(self.state(d, c, i), 1.0)];
                    let a1 = self.deriv(ir, &a);
                    let a2 = a1.as_ref().and_then(|a1| self.deriv(ir, a1));
                    inst.push(Instrument {
                        label: format!("ζ{}({driver}, λ={lam:.3})", i + 1),
                        a,
                        a1,
                        a2,
                        power: None,
                        i1: None,
                        i2: None,
                        filtered: None,
                    });
                }
                if !self.integrates {
                    continue;
                }
                // Band-pass instruments `ζᵢ''` (a double zero at s = 0): `ζᵢ'` and `ζᵢ` are
                // their integrals, stable filters of the same driver. Degree ≥ 4 keeps the
                // first section (which weighs the current sample) out of `ζᵢ''`.
                for i in (self.min_degree.max(ACC_MIN_DEGREE) - 1)..self.order {
                    let j = vec![(self.state(d, c, i), 1.0)];
                    let Some(j1) = self.deriv(ir, &j) else {
                        continue;
                    };
                    let Some(a) = self.deriv(ir, &j1) else {
                        continue;
                    };
                    let a1 = self.deriv(ir, &a);
                    let a2 = a1.as_ref().and_then(|a1| self.deriv(ir, a1));
                    inst.push(Instrument {
                        label: format!("ζ{}''({driver}, λ={lam:.3})", i + 1),
                        a,
                        a1,
                        a2,
                        power: None,
                        i1: Some(j1),
                        i2: Some(j),
                        filtered: None,
                    });
                }
            }
        }
        if self.balance {
            for (b, body) in ir.bodies.iter().enumerate() {
                let bid = BodyId(b as u32);
                let (Some(xi), Some(vi)) =
                    (self.iota_y(ir.position(bid)), self.iota_y(ir.velocity(bid)))
                else {
                    continue;
                };
                inst.push(Instrument {
                    label: format!("{}.x (virial)", body.name),
                    a: vec![(xi, 1.0)],
                    a1: Some(vec![(vi, 1.0)]),
                    a2: None,
                    power: None,
                    i1: None,
                    i2: None,
                    filtered: None,
                });
                inst.push(Instrument {
                    label: format!("{}.v (power balance)", body.name),
                    a: vec![(vi, 1.0)],
                    a1: None,
                    a2: None,
                    power: Some(bid),
                    i1: None,
                    i2: None,
                    filtered: None,
                });
            }
        }
        let w_signals: Vec<Vec<SignalId>> = self
            .roots
            .iter()
            .map(|&r| {
                // An estimated velocity depends on samples of its position.
                let mut sig = ir.expr_signals(r);
                for &(v, x) in &self.estimated {
                    if sig.contains(&v) && !sig.contains(&x) {
                        sig.push(x);
                    }
                }
                sig
            })
            .chain(self.y.iter().map(|&s| vec![s]))
            .collect();
        let mut rows = Vec::new();
        for (k, ins) in inst.iter().enumerate() {
            let filter_row = ins.a.iter().all(|&(i, _)| i < self.n_filter_states());
            for (l, eq) in self.equations.iter().enumerate() {
                if let Some(p) = ins.power {
                    if p.index() != l {
                        continue;
                    }
                }
                let ok = eq.iter().all(|t| {
                    computable(ins, &t.basis)
                        && (!filter_row || self.noise_free(ir, ins, &t.basis, &w_signals))
                });
                if ok {
                    rows.push((k, l));
                }
            }
        }
        self.instruments = inst;
        self.rows = rows;
    }

    /// Signals that a combination depends on within the same sample: the driver of a
    /// relative-degree-1 state (its exact discretisation weighs the current input sample
    /// by `≈ λTₛ/2`) and raw measured signals.
    fn same_sample(&self, ir: &ModelIr, c: &RowCombination) -> Vec<SignalId> {
        let n_filter_states = self.n_filter_states();
        let mut out = Vec::new();
        for &(k, _) in c {
            if k >= n_filter_states {
                out.push(self.y[k - n_filter_states]);
            } else if k % self.order == 0 {
                let d = k / self.order / self.corners.len();
                match d.checked_sub(self.drivers.len()) {
                    None => out.push(self.drivers[d]),
                    Some(r) if !self.root_drivers[r].delayed => {
                        out.extend(ir.expr_signals(self.roots[self.root_drivers[r].root]))
                    }
                    Some(_) => {}
                }
            }
        }
        out
    }

    /// The signal or column that drives chain `d`, for labels.
    pub fn driver_name(&self, ir: &ModelIr, d: usize) -> String {
        match d.checked_sub(self.drivers.len()) {
            None => ir.signal(self.drivers[d]).name.clone(),
            Some(r) => dynid_ir::print::render_expr(ir, self.roots[self.root_drivers[r].root]),
        }
    }

    /// Whether a filter instrument's moment with this basis keeps white measurement noise
    /// out: no product may pair a signal with something that depends on the same sample of
    /// that signal, or the noise variance enters the moment (amplified by `λ²` in `ι''`).
    fn noise_free(
        &self,
        ir: &ModelIr,
        ins: &Instrument,
        b: &BasisMoment,
        w_signals: &[Vec<SignalId>],
    ) -> bool {
        let (comb, col) = match *b {
            BasisMoment::Static(w) => (Some(&ins.a), w),
            BasisMoment::D1Pos(x) => (ins.a1.as_ref(), x),
            BasisMoment::D2Vel(v, _) => (ins.a1.as_ref(), v),
            BasisMoment::D2Pos(x, _) => (ins.a2.as_ref(), x),
            BasisMoment::D1Acc(w) => (ins.i1.as_ref(), w),
            BasisMoment::D0Acc(w) => (ins.i2.as_ref(), w),
        };
        let Some(comb) = comb else { return true };
        let hazards = self.same_sample(ir, comb);
        !w_signals[col].iter().any(|s| hazards.contains(s))
    }

    /// Time derivative of `a·ι`, if it is again a combination of `ι`: filter states
    /// differentiate through `ζ' = F ζ + H s`; a measured position differentiates to its
    /// measured velocity; anything else (an input, a velocity) has no computable derivative.
    pub(super) fn deriv(&self, ir: &ModelIr, a: &RowCombination) -> Option<RowCombination> {
        let n_filter_states = self.n_filter_states();
        let mut out: RowCombination = Vec::new();
        let mut add = |k: usize, v: f64| match out.iter_mut().find(|(j, _)| *j == k) {
            Some(e) => e.1 += v,
            None => out.push((k, v)),
        };
        for &(k, coef) in a {
            if k < n_filter_states {
                let chain = k / self.order;
                let i = k % self.order;
                let lam = self.corners[chain % self.corners.len()];
                let d = chain / self.corners.len();
                add(k, -lam * coef);
                if i == 0 {
                    // A column driver is no row signal: its chain's first state has no
                    // computable derivative.
                    add(self.iota_y(*self.drivers.get(d)?)?, lam * coef);
                } else {
                    add(k - 1, lam * coef);
                }
            } else {
                let sig = self.y[k - n_filter_states];
                match ir.signal(sig).kind {
                    SignalKind::Position(b) => add(self.iota_y(ir.velocity(b))?, coef),
                    _ => return None,
                }
            }
        }
        Some(out)
    }
}

fn computable(ins: &Instrument, b: &BasisMoment) -> bool {
    match *b {
        BasisMoment::Static(_) => true,
        BasisMoment::D1Pos(_) => ins.a1.is_some(),
        BasisMoment::D2Vel(_, body) => ins.a1.is_some() || ins.power == Some(body),
        BasisMoment::D2Pos(_, _) => ins.a2.is_some(),
        BasisMoment::D1Acc(_) => ins.i1.is_some(),
        BasisMoment::D0Acc(_) => ins.i2.is_some(),
    }
}
