//! The fixed part of a refinement: the records' columns, the sub-records (shooting
//! segments) and the weights, checked once; and the simulation with sensitivities of every
//! sub-record at given values, folded into its triangular factor ([`RowQr`]).

use super::qr::RowQr;
use super::sens::{SensModel, SensRk4};
use super::{RefineError, RefineOptions};
use crate::describe::std_dev;
use crate::record::Record;
use crate::sim::{simulate_driven_from, SimError, Start};
use dynid_ir::ir::{ModelIr, SignalKind};
use rayon::prelude::*;

/// A sub-record: samples `[start, end)` of record `record`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Segment {
    pub(super) record: usize,
    pub(super) start: usize,
    pub(super) end: usize,
    /// The initial state is fitted even for a record's first sub-record.
    pub(super) estimated: bool,
}

impl Segment {
    /// Local unknowns (initial positions and velocities) of the sub-record: none for a
    /// record's first, which starts from the measured state.
    pub(super) fn locals(&self, nb: usize) -> usize {
        if self.start == 0 && !self.estimated {
            0
        } else {
            2 * nb
        }
    }
}

/// A compared signal of one record: `(state index, is velocity, column, weight)`.
type Compared<'a> = (usize, bool, &'a [f64], f64);

/// The fixed part of the problem: data columns, segments and weights.
pub(super) struct Problem<'a> {
    pub(super) ir: &'a ModelIr,
    pub(super) nb: usize,
    pub(super) unknowns: Vec<dynid_ir::ir::ParamId>,
    /// Per record: input columns (model input order).
    pub(super) inputs: Vec<Vec<&'a [f64]>>,
    /// Per record: `(state index, is velocity, column, weight)` of the compared signals.
    pub(super) outputs: Vec<Vec<Compared<'a>>>,
    pub(super) ts: Vec<f64>,
    pub(super) t0: Vec<f64>,
    pub(super) segments: Vec<Segment>,
    /// Parameter column scales (|start|, or 1 for a start at 0).
    pub(super) pscale: Vec<f64>,
    pub(super) limit: f64,
    pub(super) substeps: usize,
    pub(super) signals: Vec<(String, f64)>,
}

/// The cost (sum of squared weighted residuals) of all sub-records' factors.
pub(super) fn total(f: &[RowQr]) -> f64 {
    f.iter().map(|q| q.cost).sum()
}

/// Why a simulation with sensitivities gave no rows.
pub(super) enum Fail {
    /// Record (1-based) and time where a sub-record diverged.
    Diverged { record: usize, time: f64 },
    /// The model cannot be simulated at these values (e.g. a zero mass).
    Model(SimError),
}

impl<'a> Problem<'a> {
    pub(super) fn new(
        ir: &'a ModelIr,
        records: &'a [Record],
        start: &[f64],
        opts: &RefineOptions,
    ) -> Result<Self, RefineError> {
        let unknowns = check_start(ir, start, opts)?;
        let (compared, weight) = compared_signals(ir, opts)?;
        if records.is_empty() {
            return Err(RefineError::BadRecord {
                record: 0,
                what: "no records".into(),
            });
        }
        let column = |r: usize, name: &str| -> Result<&'a [f64], RefineError> {
            let rec = &records[r];
            let c = rec.column(name).ok_or_else(|| RefineError::MissingColumn {
                record: r + 1,
                signal: name.to_string(),
                found: rec.names.join(", "),
            })?;
            if let Some(i) = c.iter().position(|x| !x.is_finite()) {
                return Err(RefineError::BadRecord {
                    record: r + 1,
                    what: format!(
                        "column `{name}` has the non-finite value {} at sample {i}",
                        c[i]
                    ),
                });
            }
            Ok(c)
        };
        let mut inputs = Vec::new();
        let mut cols: Vec<Vec<&[f64]>> = Vec::new();
        let (mut ts, mut t0) = (Vec::new(), Vec::new());
        for (r, rec) in records.iter().enumerate() {
            if !(rec.ts.is_finite() && rec.ts > 0.0) {
                return Err(RefineError::BadRecord {
                    record: r + 1,
                    what: format!("sample interval {} is not positive", rec.ts),
                });
            }
            inputs.push(
                ir.inputs
                    .iter()
                    .map(|i| column(r, &i.name))
                    .collect::<Result<Vec<_>, _>>()?,
            );
            cols.push(
                compared
                    .iter()
                    .map(|c| column(r, &c.2))
                    .collect::<Result<Vec<_>, _>>()?,
            );
            ts.push(rec.ts);
            t0.push(rec.t0);
        }
        // σ_s over all records.
        let sigma: Vec<f64> = (0..compared.len())
            .map(|i| {
                let all: Vec<f64> = cols.iter().flat_map(|c| c[i].iter().copied()).collect();
                let s = std_dev(&all);
                if s > 0.0 && s.is_finite() {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        let scale: Vec<f64> = weight.iter().zip(&sigma).map(|(w, s)| w / s).collect();
        let outputs = cols
            .iter()
            .map(|c| {
                compared
                    .iter()
                    .zip(c)
                    .zip(&scale)
                    .map(|((cmp, col), w)| (cmp.0, cmp.1, *col, *w))
                    .collect()
            })
            .collect();
        let segments = segments(records, opts)?;
        let spread = inputs
            .iter()
            .flatten()
            .chain(cols.iter().flatten())
            .map(|c| std_dev(c))
            .fold(0.0, f64::max);
        Ok(Problem {
            ir,
            nb: ir.bodies.len(),
            pscale: start
                .iter()
                .map(|v| if *v != 0.0 { v.abs() } else { 1.0 })
                .collect(),
            unknowns,
            inputs,
            outputs,
            ts,
            t0,
            segments,
            limit: 1e6 * (1.0 + spread),
            substeps: opts.substeps,
            signals: compared
                .iter()
                .zip(&scale)
                .map(|(c, w)| (c.2.clone(), *w))
                .collect(),
        })
    }

    /// Every parameter's value with the unknowns at `theta`.
    pub(super) fn params(&self, theta: &[f64]) -> Vec<f64> {
        let mut ir_values: Vec<f64> = self
            .ir
            .params
            .iter()
            .map(|p| p.nominal().unwrap_or(0.0))
            .collect();
        for (p, v) in self.unknowns.iter().zip(theta) {
            ir_values[p.index()] = *v;
        }
        ir_values
    }

    /// The state at the first sample of `s`, as `Start::Measured` takes it.
    pub(super) fn measured_state(&self, s: Segment) -> Vec<f64> {
        let nb = self.nb;
        let mut x0 = vec![0.0; 2 * nb];
        let ts = self.ts[s.record];
        for &(b, vel, col, _) in &self.outputs[s.record] {
            if !vel {
                let x = &col[s.start..];
                x0[b] = x[0];
                if x0[nb + b] == 0.0 {
                    x0[nb + b] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * ts);
                }
            }
        }
        for &(b, vel, col, _) in &self.outputs[s.record] {
            if vel {
                x0[nb + b] = col[s.start];
            }
        }
        x0
    }

    /// Σ of the squared weighted residuals of whole records simulated from their measured
    /// states at `theta` (the score; infinite when a run diverges or cannot be built).
    pub(super) fn free_run_cost(&self, theta: &[f64]) -> f64 {
        let fitted = self.ir.with_nominals(theta);
        let runs = (0..self.inputs.len())
            .into_par_iter()
            .map(|r| {
                let rec = self.record(r);
                let sim = simulate_driven_from(&fitted, &rec, self.substeps, Start::Measured)
                    .map_err(|_| ())?;
                let mut c = 0.0;
                for &(b, vel, col, wt) in &self.outputs[r] {
                    let name = &self.ir.signals[2 * b + usize::from(vel)].name;
                    let y = sim.column(name).ok_or(())?;
                    c += y
                        .iter()
                        .zip(col)
                        .map(|(a, m)| (wt * (a - m)).powi(2))
                        .sum::<f64>();
                }
                Ok::<f64, ()>(c)
            })
            .collect::<Vec<_>>();
        runs.into_iter().map(|c| c.unwrap_or(f64::INFINITY)).sum()
    }

    /// Record `r` with the columns the driven run reads: the inputs and compared signals.
    pub(super) fn record(&self, r: usize) -> Record {
        let mut names = Vec::new();
        let mut columns = Vec::new();
        for (i, c) in self.ir.inputs.iter().zip(&self.inputs[r]) {
            names.push(i.name.clone());
            columns.push(c.to_vec());
        }
        for &(b, vel, col, _) in &self.outputs[r] {
            names.push(self.ir.signals[2 * b + usize::from(vel)].name.clone());
            columns.push(col.to_vec());
        }
        Record {
            names,
            columns,
            ts: self.ts[r],
            t0: self.t0[r],
        }
    }

    /// Simulate all segments with sensitivities and fold their rows.
    pub(super) fn evaluate(&self, theta: &[f64], x0: &[Vec<f64>]) -> Result<Vec<RowQr>, Fail> {
        let params = self.params(theta);
        let mut direction = vec![None; self.ir.params.len()];
        for (k, p) in self.unknowns.iter().enumerate() {
            direction[p.index()] = Some(k);
        }
        let model = SensModel::new(self.ir, &params, &direction).map_err(Fail::Model)?;
        crate::first_error_in_order(
            self.segments
                .par_iter()
                .zip(x0)
                .map(|(s, x)| self.segment_with(&model, *s, x)),
        )
    }

    pub(super) fn segment_with(
        &self,
        m: &SensModel,
        s: Segment,
        x0: &[f64],
    ) -> Result<RowQr, Fail> {
        let (nb, q) = (self.nb, m.q);
        let w = 1 + q;
        let ts = self.ts[s.record];
        let mut rk = SensRk4::new(m, &x0[..nb], &x0[nb..]);
        // The columns kept: the initial state's only where it is a local unknown.
        let skip = 2 * nb - s.locals(nb);
        let mut qr = RowQr::new(q - skip);
        let mut row = vec![0.0; q - skip];
        let inputs = &self.inputs[s.record];
        let mut u0 = vec![0.0; inputs.len()];
        let mut u1 = vec![0.0; inputs.len()];
        for k in s.start..s.end {
            for &(b, vel, col, wt) in &self.outputs[s.record] {
                let st = if vel { &rk.v } else { &rk.x };
                let res = wt * (st[b * w] - col[k]);
                for (i, r) in row.iter_mut().enumerate() {
                    let j = i + skip;
                    let scale = if j < 2 * nb {
                        1.0
                    } else {
                        self.pscale[j - 2 * nb]
                    };
                    *r = wt * st[b * w + 1 + j] * scale;
                }
                qr.push(&mut row, res);
            }
            if k + 1 == s.end {
                break;
            }
            for (j, c) in inputs.iter().enumerate() {
                u0[j] = c[k];
                u1[j] = c[k + 1];
            }
            rk.advance(m, &u0, &u1, ts, self.substeps);
            let mag = rk.magnitude(w);
            if !(mag.is_finite() && mag <= self.limit) {
                return Err(Fail::Diverged {
                    record: s.record + 1,
                    time: self.t0[s.record] + ts * (k + 1) as f64,
                });
            }
        }
        Ok(qr)
    }
}

/// The unknowns of `ir`, checked with the start values and the settings: an open-loop
/// model with unknowns, one finite start value each, at least one RK4 sub-step.
fn check_start(
    ir: &ModelIr,
    start: &[f64],
    opts: &RefineOptions,
) -> Result<Vec<dynid_ir::ir::ParamId>, RefineError> {
    let unknowns = ir.unknowns();
    if unknowns.is_empty() {
        return Err(RefineError::NoUnknowns);
    }
    if !ir.controls.is_empty() {
        return Err(RefineError::ControlLaws {
            model: ir.name.clone(),
        });
    }
    if start.len() != unknowns.len() {
        return Err(RefineError::StartLength {
            got: start.len(),
            expected: unknowns.len(),
        });
    }
    for (p, v) in unknowns.iter().zip(start) {
        if !v.is_finite() {
            return Err(RefineError::BadStart {
                name: ir.params[p.index()].name.clone(),
                value: *v,
            });
        }
    }
    if opts.substeps == 0 {
        return Err(SimError::BadInputData {
            what: "substeps is 0 (use at least 1)".into(),
        }
        .into());
    }
    Ok(unknowns)
}

/// A compared signal: `(body, is velocity, name)`.
type CompareSignal = (usize, bool, String);

/// The compared signals (measured positions and velocities) and their weights (1 unless
/// given).
fn compared_signals(
    ir: &ModelIr,
    opts: &RefineOptions,
) -> Result<(Vec<CompareSignal>, Vec<f64>), RefineError> {
    let compared: Vec<CompareSignal> = ir
        .signals
        .iter()
        .filter(|s| s.measured)
        .filter_map(|s| match s.kind {
            SignalKind::Position(b) => Some((b.index(), false, s.name.clone())),
            SignalKind::Velocity(b) => Some((b.index(), true, s.name.clone())),
            _ => None,
        })
        .collect();
    if compared.is_empty() {
        return Err(RefineError::NoOutput);
    }
    let choices = compared
        .iter()
        .map(|c| c.2.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    let mut weight = vec![1.0; compared.len()];
    for (name, w) in &opts.weights {
        let bad = |what: String| RefineError::BadWeight {
            signal: name.clone(),
            what,
            choices: choices.clone(),
        };
        let i = compared
            .iter()
            .position(|c| c.2 == *name)
            .ok_or_else(|| bad("not a measured position or velocity of the model".into()))?;
        if !(w.is_finite() && *w >= 0.0) {
            return Err(bad(format!("{w} is not a finite value ≥ 0")));
        }
        weight[i] = *w;
    }
    if weight.iter().all(|w| *w == 0.0) {
        return Err(RefineError::BadWeight {
            signal: choices.clone(),
            what: "every weight is 0".into(),
            choices,
        });
    }
    Ok((compared, weight))
}

/// The sub-records: each record cut into `ceil(n / segment)` nearly equal parts of at
/// least 3 samples.
fn segments(records: &[Record], opts: &RefineOptions) -> Result<Vec<Segment>, RefineError> {
    let mut segments = Vec::new();
    for (r, rec) in records.iter().enumerate() {
        let n = rec.len();
        let max = opts.segment.unwrap_or(n).max(1);
        let k = n.div_ceil(max).max(1);
        for j in 0..k {
            let (a, b) = (j * n / k, (j + 1) * n / k);
            if b - a < 3 {
                return Err(RefineError::BadRecord {
                    record: r + 1,
                    what: format!("a sub-record of {} samples", b - a),
                });
            }
            segments.push(Segment {
                record: r,
                start: a,
                end: b,
                estimated: opts.estimate_initial,
            });
        }
    }
    Ok(segments)
}
