//! The structure of the least-squares problem of one model: which signals are measured,
//! which filter states and balance signals serve as instruments, how every term of every
//! equation turns into a moment, and which (instrument, equation) rows are computable.
//!
//! Notation: the accumulated "row" signals are `ι = [ζ; y]` (filter states, then measured
//! signals), the "column" signals are `w = [g; y]` (static basis roots, then measured
//! signals), and boundary snapshots use `q = [w; v̂]` where `v̂` are end-point velocity
//! estimates of bodies whose velocity is not measured.

use super::bank::BankChoice;
use super::input_delay;
use super::noise::fix::{linear_form, split_factor, ColumnFix, ExtraColumn};
use super::types::{CornerSource, IdentifyError};
use dynid_ir::ir::{Basis, BodyId, ExprId, ModelIr, ParamKind, SignalId, SignalKind, TermOrigin};

/// A sparse linear combination of the row signals `ι`.
pub(crate) type RowCombination = Vec<(usize, f64)>;

/// One element of a filtered signal ([`super::filtered`]): a row signal `ι_i` (a filter state or a measured
/// signal), or a constant static column of `w` with its value (a constant passes the
/// low-pass unchanged).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum FElem {
    Iota(usize),
    Const { col: usize, value: f64 },
}

/// A filtered signal: a linear combination of [`FElem`].
pub(crate) type FCombo = Vec<(FElem, f64)>;

/// How a term's basis becomes a moment with an instrument `a` (see [`super::moments`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum BasisMoment {
    /// `⟨a g⟩` for a static column `w`.
    Static(usize),
    /// `ẋ` with `x` at column `w`, velocity not measured: `−⟨a' x⟩ + [a x]/T`.
    D1Pos(usize),
    /// `ẍ` with measured velocity at column `w`: `−⟨a' v⟩ + [a v]/T`; body given for the
    /// power-balance instrument.
    D2Vel(usize, BodyId),
    /// `ẍ` from positions only (`x` at column `w`, end-point velocity at snapshot column
    /// `q`): `⟨a'' x⟩ − [a' x]/T + [a v̂]/T`.
    D2Pos(usize, usize),
    /// `ẋ` of a body measured only by its acceleration `a` (column `w`), with a band-pass
    /// instrument `a = J''`: `⟨J'' ẋ⟩ = −⟨J' a⟩ + [J' ẋ]/T`, the boundary term dropped (the
    /// velocity is not measured; see docs/method.md, accelerations).
    D1Acc(usize),
    /// `x` of a body measured only by its acceleration (column `w`):
    /// `⟨J'' x⟩ = ⟨J a⟩ + [J' x − J ẋ]/T`, the boundary term dropped.
    D0Acc(usize),
}

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum TermCoef {
    Unknown { col: usize, scale: f64 },
    Known(f64),
}

#[derive(Clone, Debug)]
pub(crate) struct PlanTerm {
    pub coef: TermCoef,
    pub basis: BasisMoment,
}

/// An instrument: a signal `a·ι` with, where computable, its first and second derivatives.
#[derive(Clone, Debug)]
pub(crate) struct Instrument {
    pub label: String,
    pub a: RowCombination,
    pub a1: Option<RowCombination>,
    pub a2: Option<RowCombination>,
    /// Power balance `v_l`: used only in equation `l`, where `⟨v_l ẍ_l⟩ = [v_l²/2]/T`.
    pub power: Option<BodyId>,
    /// A band-pass instrument `a = J''` (a filter state differentiated twice): its
    /// antiderivatives `J'` and `J`, which integrate a measured acceleration.
    pub i1: Option<RowCombination>,
    pub i2: Option<RowCombination>,
    /// A row of the filtered equation: the instrument is this filtered regressor (and `a`
    /// is empty; see [`super::filtered`]).
    pub filtered: Option<FCombo>,
}

#[derive(Clone, Debug)]
pub(crate) struct Plan {
    pub roots: Vec<ExprId>,
    /// Measured signals (SignalId order) and the position of each signal among them.
    pub y: Vec<SignalId>,
    pub y_of: Vec<Option<usize>>,
    pub drivers: Vec<SignalId>,
    /// Chains driven by nonlinear static columns (filtered regressors), after the chains of
    /// `drivers` in the bank.
    pub root_drivers: Vec<RootDriver>,
    pub order: usize,
    pub min_degree: usize,
    pub corners: Vec<f64>,
    pub vhat_bodies: Vec<BodyId>,
    /// `(velocity, position)`: unmeasured velocities used in static terms, estimated from
    /// their measured positions.
    pub estimated: Vec<(SignalId, SignalId)>,
    /// `(position or velocity, acceleration)`: motion of acceleration-only bodies read by
    /// nonlinear static terms, estimated by integrating the acceleration
    /// ([`super::integrate`]).
    pub integrated: Vec<(SignalId, SignalId)>,
    pub unknowns: Vec<usize>,
    pub equations: Vec<Vec<PlanTerm>>,
    pub instruments: Vec<Instrument>,
    /// Computable (instrument, equation) pairs: the rows of one level.
    pub rows: Vec<(usize, usize)>,
    /// Use the virial and power-balance instruments where velocities are measured.
    pub balance: bool,
    /// Per unknown column: every term it multiplies is a constant force (basis 1), so its
    /// moments are the means of the instruments, `⟨ι⟩`.
    pub constant: Vec<bool>,
    /// Columns of `w` after the measured signals, needed by the noise corrections
    /// ([`super::noise`]); empty unless they are attached.
    pub extra: Vec<ExtraColumn>,
    /// Noise corrections of static columns ([`super::noise::attach`]).
    pub fixes: Vec<ColumnFix>,
    /// Static columns linear in measured signals: (column, [(index into `y`, coefficient)]).
    pub linear_roots: Vec<(usize, Vec<(usize, f64)>)>,
    /// Some term integrates a measured acceleration ([`BasisMoment::D1Acc`],
    /// [`BasisMoment::D0Acc`]): band-pass instruments are added.
    pub integrates: bool,
    /// Signals of bodies measured only by their acceleration that static roots read: the
    /// data has no column for them, so they are streamed as zeros (the terms that use them
    /// are formed from the acceleration instead, never from these roots).
    pub absent: Vec<SignalId>,
    /// How the corners were chosen (filled in once the data are seen).
    pub corner_source: CornerSource,
    /// Rows of the filtered equation instead of instrument rows ([`super::filtered`]).
    pub filtered: bool,
    /// Filter states accumulated as columns of `w` too (after the noise columns), for the
    /// products of the filtered equation's rows.
    pub state_cols: Vec<usize>,
    /// The filtered regressor of every term's basis.
    pub filtered_terms: Vec<(BasisMoment, FCombo)>,
}

/// A filter chain driven by a static basis column `g` (the filters may be driven by the
/// extended state: Schiehlen & Krause, see docs/method.md, References, eq. 9): its states
/// are low-pass versions of the column itself, instruments that carry the column's own
/// information (a Coulomb column's switching, a cubic spring's peaks) where chains of
/// positions and inputs see it only weakly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RootDriver {
    /// Index into `roots` (the column `g`).
    pub root: usize,
    /// The column holds an estimated velocity, whose value at a sample depends on position
    /// samples up to the differentiator's half-width `H` on either side: the chain is then
    /// driven by the column `H + 1` samples earlier, so that no instrument shares a
    /// position sample's noise with the column it multiplies.
    pub delayed: bool,
}

impl Plan {
    /// Chains per corner: the signal drivers, then the column drivers.
    pub fn n_drivers(&self) -> usize {
        self.drivers.len() + self.root_drivers.len()
    }
    /// Filter states `ζ`: drivers × corners × order.
    pub fn n_filter_states(&self) -> usize {
        self.n_drivers() * self.corners.len() * self.order
    }
    /// Row signals `ι = [ζ; y]` (the `n_i` of the notation): filter states, then measured
    /// signals.
    pub fn n_row_signals(&self) -> usize {
        self.n_filter_states() + self.y.len()
    }
    /// Column signals `w = [g; y]` (`n_w`): static roots, measured signals, noise columns.
    pub fn n_col_signals(&self) -> usize {
        self.roots.len() + self.y.len() + self.extra.len() + self.state_cols.len()
    }
    /// Snapshot columns `q = [w; v̂]` (`n_q`): `w` and the end-point velocity estimates.
    pub fn n_snap_cols(&self) -> usize {
        self.n_col_signals() + self.vhat_bodies.len()
    }
    /// Row index of a measured signal in `ι`.
    pub fn iota_y(&self, s: SignalId) -> Option<usize> {
        self.y_of[s.index()].map(|k| self.n_filter_states() + k)
    }
    /// Filter state index of (driver, corner, section `i` = relative degree − 1).
    pub fn state(&self, d: usize, c: usize, i: usize) -> usize {
        (d * self.corners.len() + c) * self.order + i
    }
}

/// Check that every term can be formed from the measured signals and classify it.
///
/// Long: one walk over the equations' terms fills the plan's tables (columns, instruments,
/// term moments) together, and the order of that walk is the order of the columns of `w`,
/// on which every moment depends bit for bit.
pub(crate) fn build_structure(
    ir: &ModelIr,
    balance: bool,
    bank: &BankChoice,
) -> Result<Plan, IdentifyError> {
    let roots = ir.eval_roots();
    let y: Vec<SignalId> = ir.measured_signals();
    let mut y_of = vec![None; ir.signals.len()];
    for (k, s) in y.iter().enumerate() {
        y_of[s.index()] = Some(k);
    }
    let unknowns = ir.unknowns();
    let col_of = |p: dynid_ir::ir::ParamId| unknowns.iter().position(|u| *u == p);
    let root_of = |e: ExprId| roots.iter().position(|r| *r == e).expect("invariant: root");
    let n_g = roots.len();
    let mut vhat_bodies = Vec::new();
    let mut estimated = Vec::new();
    let mut integrated = Vec::new();
    let mut absent: Vec<SignalId> = Vec::new();
    let mut equations = Vec::new();
    for (l, eq) in ir.equations.iter().enumerate() {
        let mut terms = Vec::new();
        for t in &eq.terms {
            let coef = match t.coef.param {
                Some(p) => match ir.params[p.index()].kind {
                    ParamKind::Known(v) => TermCoef::Known(v * t.coef.scale),
                    ParamKind::Unknown { .. } => TermCoef::Unknown {
                        col: col_of(p).expect("invariant: unknown"),
                        scale: t.coef.scale,
                    },
                },
                None => TermCoef::Known(t.coef.scale),
            };
            let basis = match t.basis {
                Basis::Expr(e)
                    if linear_form(ir, e).is_some()
                        && ir
                            .expr_signals(e)
                            .iter()
                            .any(|&s| accel_only_signal(ir, s).is_some()) =>
                {
                    // Linear in the motion of bodies measured only by accelerations: one
                    // term per signal, each formed from the acceleration by the band-pass
                    // instruments (measured signals of the form stay static columns).
                    let unmeasured = |s: SignalId| IdentifyError::UnmeasuredInTerm {
                        equation: ir.bodies[l].name.clone(),
                        term: dynid_ir::print::render_expr(ir, e),
                        signal: ir.signal(s).name.clone(),
                    };
                    let lin = linear_form(ir, e).expect("invariant: checked by the guard");
                    for (s, c) in lin {
                        let part = match accel_only_signal(ir, s) {
                            Some(b) => {
                                let a = ir.acceleration(b).expect("invariant: accelerometer");
                                let aw = n_g + y_of[a.index()].expect("invariant: measured");
                                match ir.signal(s).kind {
                                    SignalKind::Position(_) => BasisMoment::D0Acc(aw),
                                    _ => BasisMoment::D1Acc(aw),
                                }
                            }
                            None => match y_of[s.index()] {
                                Some(k) => BasisMoment::Static(n_g + k),
                                None => return Err(unmeasured(s)),
                            },
                        };
                        for r in ir.expr_signals(e) {
                            if accel_only_signal(ir, r).is_some() && !absent.contains(&r) {
                                absent.push(r);
                            }
                        }
                        let coef = match coef.clone() {
                            TermCoef::Unknown { col, scale } => TermCoef::Unknown {
                                col,
                                scale: scale * c,
                            },
                            TermCoef::Known(v) => TermCoef::Known(v * c),
                        };
                        terms.push(PlanTerm { coef, basis: part });
                    }
                    continue;
                }
                Basis::Expr(e) => {
                    for s in ir.expr_signals(e) {
                        if y_of[s.index()].is_some() {
                            continue;
                        }
                        // Nonlinear in the motion of a body measured only by its
                        // acceleration: read on integrals of the acceleration.
                        if let Some(b) = accel_only_signal(ir, s) {
                            let a = ir.acceleration(b).expect("invariant: accelerometer");
                            if !integrated.contains(&(s, a)) {
                                integrated.push((s, a));
                            }
                            continue;
                        }
                        // An unmeasured velocity of a body whose position is measured is
                        // estimated from the position (see [`super::velocity`]).
                        let from = match ir.signal(s).kind {
                            SignalKind::Velocity(b) => {
                                Some(ir.position(b)).filter(|x| y_of[x.index()].is_some())
                            }
                            _ => None,
                        };
                        match from {
                            Some(x) => {
                                if !estimated.contains(&(s, x)) {
                                    estimated.push((s, x));
                                }
                            }
                            None => {
                                return Err(IdentifyError::UnmeasuredInTerm {
                                    equation: ir.bodies[l].name.clone(),
                                    term: dynid_ir::print::render_expr(ir, e),
                                    signal: ir.signal(s).name.clone(),
                                })
                            }
                        }
                    }
                    BasisMoment::Static(root_of(e))
                }
                Basis::Deriv { body, order } => {
                    let xs = ir.position(body);
                    let vs = ir.velocity(body);
                    let xw = y_of[xs.index()].map(|k| n_g + k);
                    let vw = y_of[vs.index()].map(|k| n_g + k);
                    // A measured acceleration is the second derivative itself.
                    let aw = ir
                        .acceleration(body)
                        .and_then(|a| y_of[a.index()])
                        .map(|k| n_g + k);
                    match (order, vw, xw) {
                        (2, _, _) if aw.is_some() => {
                            BasisMoment::Static(aw.expect("invariant: checked"))
                        }
                        (1, None, None) if aw.is_some() => {
                            BasisMoment::D1Acc(aw.expect("invariant: checked"))
                        }
                        (1, Some(v), _) => BasisMoment::Static(v),
                        (1, None, Some(x)) => BasisMoment::D1Pos(x),
                        (2, Some(v), _) => BasisMoment::D2Vel(v, body),
                        (2, None, Some(x)) => {
                            let k = match vhat_bodies.iter().position(|b| *b == body) {
                                Some(k) => k,
                                None => {
                                    vhat_bodies.push(body);
                                    vhat_bodies.len() - 1
                                }
                            };
                            // The snapshot column is fixed below once n_w is known.
                            BasisMoment::D2Pos(x, usize::MAX - k)
                        }
                        _ => {
                            return Err(IdentifyError::UnmeasuredInTerm {
                                equation: ir.bodies[l].name.clone(),
                                term: format!(
                                    "{}{}",
                                    ir.signal(xs).name,
                                    "'".repeat(order as usize)
                                ),
                                signal: ir.signal(xs).name.clone(),
                            })
                        }
                    }
                }
            };
            // A delayed input, `c u(t − τ) ≈ c u − c τ u̇`: the unknown τ multiplies the
            // input's derivative, formed on the instruments ([`super::input_delay`]).
            let delay = match (t.origin, &coef) {
                (TermOrigin::Input(i), TermCoef::Known(c)) => input_delay::param_of(ir, i)
                    .and_then(|p| Some((col_of(p)?, *c, y_of[ir.input_signal(i).index()]?))),
                _ => None,
            };
            terms.push(PlanTerm { coef, basis });
            if let Some((col, c, k)) = delay {
                terms.push(PlanTerm {
                    coef: TermCoef::Unknown { col, scale: -c },
                    basis: BasisMoment::D1Pos(n_g + k),
                });
            }
        }
        equations.push(terms);
    }
    let n_col_signals = n_g + y.len();
    let integrates = equations
        .iter()
        .flatten()
        .any(|t| matches!(t.basis, BasisMoment::D1Acc(_) | BasisMoment::D0Acc(_)));
    // Roots reading an acceleration-only body's motion beyond those split above (none
    // but the split ones reach here: any other is refused) still get evaluated, on zeros.
    for &r in &roots {
        for s in ir.expr_signals(r) {
            if accel_only_signal(ir, s).is_some() && !absent.contains(&s) {
                absent.push(s);
            }
        }
    }
    let constant = (0..unknowns.len())
        .map(|col| {
            let mut terms = equations.iter().flatten().filter(
                |t| matches!(t.coef, TermCoef::Unknown { col: c, .. } if c == col),
            );
            terms.all(|t| matches!(t.basis, BasisMoment::Static(w) if w < n_g && ir.is_constant(roots[w])))
        })
        .collect();
    for eq in &mut equations {
        for t in eq.iter_mut() {
            if let BasisMoment::D2Pos(x, q) = t.basis {
                t.basis = BasisMoment::D2Pos(x, n_col_signals + (usize::MAX - q));
            }
        }
    }
    let mut root_drivers: Vec<RootDriver> = Vec::new();
    if bank.regressors {
        let est: Vec<SignalId> = estimated.iter().map(|&(v, _)| v).collect();
        for t in equations.iter().flatten() {
            // The filtered equation filters every term, known ones too.
            let (true, BasisMoment::Static(w)) = (
                bank.filtered || matches!(t.coef, TermCoef::Unknown { .. }),
                t.basis,
            ) else {
                continue;
            };
            // Constant and linear columns add nothing: their chains are the constant or
            // combinations of the measured signals' chains.
            let linear = |r| linear_form(ir, split_factor(ir, r).1);
            if w >= n_g
                || ir.is_constant(roots[w])
                || linear(roots[w]).is_some()
                || root_drivers.iter().any(|r| r.root == w)
            {
                continue;
            }
            // The filtered equation needs the column itself, not a delayed copy.
            let delayed =
                !bank.filtered && ir.expr_signals(roots[w]).iter().any(|s| est.contains(s));
            root_drivers.push(RootDriver { root: w, delayed });
        }
    }
    for d in &bank.drivers {
        if y_of[d.index()].is_none() {
            return Err(IdentifyError::UnmeasuredDriver {
                signal: ir.signal(*d).name.clone(),
            });
        }
    }
    if bank.filtered && bank.n_corners != 1 {
        return Err(IdentifyError::BadOption {
            message: format!(
                "the rows of the filtered equation use one filter corner, not {}",
                bank.n_corners
            ),
            help: "give one corner (--filter-corners LAMBDA, in rad/s) or none".into(),
        });
    }
    let mut plan = Plan {
        roots,
        y,
        y_of,
        drivers: bank.drivers.clone(),
        root_drivers,
        order: bank.order,
        min_degree: bank.min_degree,
        corners: vec![0.0; bank.n_corners],
        vhat_bodies,
        estimated,
        integrated,
        unknowns: unknowns.iter().map(|p| p.index()).collect(),
        equations,
        instruments: Vec::new(),
        rows: Vec::new(),
        balance,
        extra: Vec::new(),
        fixes: Vec::new(),
        linear_roots: Vec::new(),
        constant,
        integrates,
        absent,
        corner_source: Default::default(),
        filtered: bank.filtered,
        state_cols: Vec::new(),
        filtered_terms: Vec::new(),
    };
    if plan.filtered {
        plan.set_filtered_rows(ir)
            .map_err(|message| IdentifyError::BadOption {
                message,
                help: "identify this model with the instrument rows (the default)".into(),
            })?;
    }
    Ok(plan)
}

/// The body whose position or velocity `s` is, if that body is measured only by its
/// acceleration.
fn accel_only_signal(ir: &ModelIr, s: SignalId) -> Option<BodyId> {
    match ir.signal(s).kind {
        SignalKind::Position(b) | SignalKind::Velocity(b) if ir.acceleration_only(b) => Some(b),
        _ => None,
    }
}
