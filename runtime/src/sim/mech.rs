//! The equations of motion as an acceleration function, and a fixed-step RK4 integrator.
//!
//! Equation `i` reads `Σ coef·basis = 0`. The `Deriv{j,2}` terms form the mass matrix `M`,
//! everything else is the force vector `r(x, v, u)`, so `ẍ = −M⁻¹ r`. `M⁻¹` is computed
//! once (coefficients are constants during a simulation).

use super::SimError;
use crate::tape::{PointTape, Tape};
use dynid_ir::ir::{Basis, Coef, ExprId, ModelIr};

/// Precomputed, allocation-free acceleration function of a model.
#[derive(Clone, Debug)]
pub(crate) struct Mechanics {
    pub(crate) n_bodies: usize,
    pub(crate) n_inputs: usize,
    /// The expressions of the terms, evaluated on `MechScratch::mem`, whose first entries
    /// are the signals: position `i` at `2i`, velocity `i` at `2i + 1`, input `j` at `2nb + j`.
    point: PointTape,
    /// The force terms, grouped by equation: equation `i` sums `terms[starts[i]..starts[i + 1]]`.
    /// Each term is `(slot, coefficient value)`, the slot indexing `MechScratch::mem` (a
    /// tape root for an `Expr` term, the velocity signal for a `Deriv{body, 1}` term).
    /// Within an equation the `Expr` terms come first, then the velocity terms, each in
    /// declaration order (the order of the sums the simulator always used).
    terms: Vec<(usize, f64)>,
    starts: Vec<usize>,
    /// `M⁻¹`, row-major.
    minv: Vec<f64>,
    diagonal_mass: bool,
}

/// Scratch space for [`Mechanics::accel`], one per thread.
#[derive(Clone, Debug)]
pub(crate) struct MechScratch {
    /// [`PointTape::memory`]: signals, constants, registers.
    mem: Vec<f64>,
    force: Vec<f64>,
}

/// The terms of a model's equations by kind, in declaration order: `(equation, root
/// index into `ir.eval_roots()`, coefficient)` for expression terms, `(equation, body,
/// coefficient)` for velocity and acceleration (mass) terms. Shared by the simulator and
/// the refinement's sensitivity model, so both read a model the same way.
pub(crate) struct EquationTerms {
    pub(crate) expr: Vec<(usize, usize, Coef)>,
    pub(crate) vel: Vec<(usize, usize, Coef)>,
    pub(crate) mass: Vec<(usize, usize, Coef)>,
}

impl EquationTerms {
    /// The terms of `ir`, whose expression terms are among `roots`; an error naming the
    /// body for equations out of body order or derivatives above the second.
    pub(crate) fn of(ir: &ModelIr, roots: &[ExprId]) -> Result<Self, SimError> {
        let root_index = |e| {
            roots
                .iter()
                .position(|&r| r == e)
                .expect("invariant: root of a term")
        };
        let mut t = EquationTerms {
            expr: Vec::new(),
            vel: Vec::new(),
            mass: Vec::new(),
        };
        for (i, eq) in ir.equations.iter().enumerate() {
            let body_name = || ir.bodies[eq.body.index()].name.clone();
            if eq.body.index() != i {
                return Err(SimError::UnsupportedTerm {
                    body: body_name(),
                    what: "equations are not in body order".into(),
                });
            }
            for term in &eq.terms {
                match term.basis {
                    Basis::Expr(e) => t.expr.push((i, root_index(e), term.coef)),
                    Basis::Deriv { body, order: 1 } => t.vel.push((i, body.index(), term.coef)),
                    Basis::Deriv { body, order: 2 } => t.mass.push((i, body.index(), term.coef)),
                    Basis::Deriv { body, order } => {
                        return Err(SimError::UnsupportedTerm {
                            body: body_name(),
                            what: format!(
                                "derivative of order {order} of `{}`",
                                ir.bodies[body.index()].name
                            ),
                        })
                    }
                }
            }
        }
        Ok(t)
    }
}

impl Mechanics {
    /// `params[p]` is the value of parameter `p`.
    pub(crate) fn new(ir: &ModelIr, params: &[f64]) -> Result<Self, SimError> {
        let nb = ir.bodies.len();
        let roots = ir.eval_roots();
        let split = EquationTerms::of(ir, &roots)?;
        let value = |c: Coef| c.scale * c.param.map_or(1.0, |p| params[p.index()]);
        let mut mass = nalgebra::DMatrix::<f64>::zeros(nb, nb);
        for &(i, body, c) in &split.mass {
            mass[(i, body)] += value(c);
        }
        let (minv, diagonal_mass) = inverse_mass(ir, mass)?;
        let point = PointTape::new(&Tape::compile(ir, &roots));
        let mut terms = Vec::with_capacity(split.expr.len() + split.vel.len());
        let mut starts = Vec::with_capacity(nb + 1);
        for eq in 0..nb {
            starts.push(terms.len());
            terms.extend(
                split
                    .expr
                    .iter()
                    .filter(|t| t.0 == eq)
                    .map(|&(_, root, c)| (point.root_slot(root), value(c))),
            );
            terms.extend(
                split
                    .vel
                    .iter()
                    .filter(|t| t.0 == eq)
                    .map(|&(_, body, c)| (2 * body + 1, value(c))),
            );
        }
        starts.push(terms.len());
        // What `accel`'s unchecked reads rely on.
        assert!(
            terms.iter().all(|&(slot, _)| slot < point.memory_len()),
            "invariant: every term reads the tape's memory"
        );
        Ok(Mechanics {
            n_bodies: nb,
            n_inputs: ir.inputs.len(),
            point,
            terms,
            starts,
            minv,
            diagonal_mass,
        })
    }

    pub(crate) fn scratch(&self) -> MechScratch {
        MechScratch {
            mem: self.point.memory(),
            force: vec![0.0; self.n_bodies],
        }
    }

    /// Write body `i`'s position and velocity where [`Mechanics::accel`] reads them.
    #[inline(always)]
    fn put_body(s: &mut MechScratch, i: usize, x: f64, v: f64) {
        s.mem[2 * i] = x;
        s.mem[2 * i + 1] = v;
    }

    /// Write the inputs at fraction `f` of the sample interval, `u0 + f · (u1 − u0)` (as
    /// [`lerp`]), where [`Mechanics::accel`] reads them.
    #[inline(always)]
    fn put_inputs(&self, s: &mut MechScratch, u0: &[f64], u1: &[f64], f: f64) {
        let nb = self.n_bodies;
        lerp(u0, u1, f, &mut s.mem[2 * nb..2 * nb + self.n_inputs]);
    }

    /// Accelerations `a` at the positions, velocities and inputs written into `s` by
    /// [`Mechanics::put_body`] and [`Mechanics::put_inputs`] (straight into the tape's
    /// memory: the state takes no extra trip through memory on its way to the tape).
    #[inline(always)]
    pub(crate) fn accel<const NB: usize>(&self, s: &mut MechScratch, a: &mut [f64]) {
        // `NB` bodies known at compile time (0: any number).
        let nb = if NB == 0 { self.n_bodies } else { NB };
        let mem = &mut s.mem[..];
        self.point.eval(mem);
        let mem = &s.mem[..];
        assert!(
            mem.len() >= self.point.memory_len(),
            "invariant: scratch of this model"
        );
        let force = |w: &[usize]| {
            let mut sum = 0.0;
            for &(slot, c) in &self.terms[w[0]..w[1]] {
                // SAFETY: `new` checks every slot against `memory_len` (asserted above).
                sum += c * unsafe { *mem.get_unchecked(slot) };
            }
            sum
        };
        if self.diagonal_mass {
            // Each force straight into its acceleration (no round trip through memory).
            for (i, (a, w)) in a[..nb].iter_mut().zip(self.starts.windows(2)).enumerate() {
                *a = -self.minv[i * nb + i] * force(w);
            }
        } else {
            for (f, w) in s.force[..nb].iter_mut().zip(self.starts.windows(2)) {
                *f = force(w);
            }
            for (a, row) in a.iter_mut().zip(self.minv.chunks_exact(nb)) {
                *a = -row.iter().zip(&s.force).map(|(m, f)| m * f).sum::<f64>();
            }
        }
    }
}

/// `M⁻¹` row-major, and whether `M` is diagonal; an error naming a body when `M` is
/// singular (a zero or non-finite diagonal, or a condition number above 10¹²).
pub(crate) fn inverse_mass(
    ir: &ModelIr,
    mass: nalgebra::DMatrix<f64>,
) -> Result<(Vec<f64>, bool), SimError> {
    let nb = mass.nrows();
    let diagonal = (0..nb).all(|i| (0..nb).all(|j| i == j || mass[(i, j)] == 0.0));
    let minv = if diagonal {
        let mut m = nalgebra::DMatrix::zeros(nb, nb);
        for i in 0..nb {
            let d = mass[(i, i)];
            if d == 0.0 || !d.is_finite() {
                return Err(SimError::SingularMass {
                    body: ir.bodies[i].name.clone(),
                });
            }
            m[(i, i)] = 1.0 / d;
        }
        m
    } else {
        let svd = mass.clone().svd(false, false);
        let smax = svd.singular_values.max();
        if svd.singular_values.min().partial_cmp(&(1e-12 * smax))
            != Some(std::cmp::Ordering::Greater)
        {
            let body = (0..nb)
                .min_by(|&a, &b| mass[(a, a)].abs().total_cmp(&mass[(b, b)].abs()))
                .unwrap_or(0);
            return Err(SimError::SingularMass {
                body: ir.bodies[body].name.clone(),
            });
        }
        mass.try_inverse()
            .expect("invariant: well-conditioned mass matrix")
    };
    let rows = (0..nb)
        .flat_map(|i| (0..nb).map(move |j| (i, j)))
        .map(|(i, j)| minv[(i, j)])
        .collect();
    Ok((rows, diagonal))
}

/// Classical RK4 state and stage buffers (allocated once per run).
#[derive(Clone, Debug)]
pub(crate) struct Rk4 {
    pub(crate) x: Vec<f64>,
    pub(crate) v: Vec<f64>,
    /// The stages `a1 a2 a3 a4 v2 v3 v4`, `n_bodies` values each, in one buffer so that
    /// `advance` works on slices of one known length.
    stages: Vec<f64>,
    scratch: MechScratch,
    /// The accelerations at the state and inputs of the last [`Rk4::refresh_accel`].
    pub(crate) acc: Vec<f64>,
}

impl Rk4 {
    /// At rest at the origin.
    pub(crate) fn new(mech: &Mechanics) -> Self {
        let nb = mech.n_bodies;
        Rk4 {
            x: vec![0.0; nb],
            v: vec![0.0; nb],
            stages: vec![0.0; 7 * nb],
            scratch: mech.scratch(),
            acc: vec![0.0; nb],
        }
    }

    /// The exact accelerations `ẍ = M⁻¹ f(x, v, u)` at the current state and inputs `u`
    /// (the equations of motion evaluated, not differenced), into [`Rk4::acc`]: what an
    /// accelerometer on each body reads at this instant.
    pub(crate) fn refresh_accel(&mut self, mech: &Mechanics, u: &[f64]) {
        let nb = mech.n_bodies;
        mech.put_inputs(&mut self.scratch, u, u, 0.0);
        for i in 0..nb {
            Mechanics::put_body(&mut self.scratch, i, self.x[i], self.v[i]);
        }
        mech.accel::<0>(&mut self.scratch, &mut self.acc);
    }

    /// Advance over one sample interval of length `ts` in `substeps` RK4 steps. The inputs
    /// go linearly from `u0` to `u1` across the interval (first-order hold), which is
    /// exactly what the identification's filter discretisation assumes.
    pub(crate) fn advance(
        &mut self,
        mech: &Mechanics,
        u0: &[f64],
        u1: &[f64],
        ts: f64,
        substeps: usize,
    ) {
        // Small models with their number of bodies known at compile time: every loop over
        // the bodies unrolled (the same operations in the same order).
        match mech.n_bodies {
            1 => self.advance_n::<1>(mech, u0, u1, ts, substeps),
            2 => self.advance_n::<2>(mech, u0, u1, ts, substeps),
            3 => self.advance_n::<3>(mech, u0, u1, ts, substeps),
            4 => self.advance_n::<4>(mech, u0, u1, ts, substeps),
            _ => self.advance_n::<0>(mech, u0, u1, ts, substeps),
        }
    }

    /// [`Rk4::advance`] for `NB` bodies (`0`: any number).
    #[inline(always)]
    fn advance_n<const NB: usize>(
        &mut self,
        mech: &Mechanics,
        u0: &[f64],
        u1: &[f64],
        ts: f64,
        substeps: usize,
    ) {
        let nb = if NB == 0 { mech.n_bodies } else { NB };
        debug_assert_eq!(nb, mech.n_bodies);
        let h = ts / substeps as f64;
        let (h2, h6) = (0.5 * h, h / 6.0);
        let n = substeps as f64;
        let (x, v) = (&mut self.x[..nb], &mut self.v[..nb]);
        let scratch = &mut self.scratch;
        // Each stage's state goes straight into the tape's memory; the velocities are also
        // kept for the final combination. The three stages are written out: a shared helper
        // for them measured 9.6 against 10.5 M sub-steps/s (`--bench simulate`).
        let mut parts = self.stages.chunks_exact_mut(nb);
        let mut next = || parts.next().expect("invariant: seven stages");
        let (a1, a2, a3, a4) = (next(), next(), next(), next());
        let (v2, v3, v4) = (next(), next(), next());
        for j in 0..substeps {
            let j = j as f64;
            mech.put_inputs(scratch, u0, u1, j / n);
            for i in 0..nb {
                Mechanics::put_body(scratch, i, x[i], v[i]);
            }
            mech.accel::<NB>(scratch, a1);
            mech.put_inputs(scratch, u0, u1, (j + 0.5) / n);
            for i in 0..nb {
                v2[i] = v[i] + h2 * a1[i];
                Mechanics::put_body(scratch, i, x[i] + h2 * v[i], v2[i]);
            }
            mech.accel::<NB>(scratch, a2);
            for i in 0..nb {
                v3[i] = v[i] + h2 * a2[i];
                Mechanics::put_body(scratch, i, x[i] + h2 * v2[i], v3[i]);
            }
            mech.accel::<NB>(scratch, a3);
            mech.put_inputs(scratch, u0, u1, (j + 1.0) / n);
            for i in 0..nb {
                v4[i] = v[i] + h * a3[i];
                Mechanics::put_body(scratch, i, x[i] + h * v3[i], v4[i]);
            }
            mech.accel::<NB>(scratch, a4);
            for i in 0..nb {
                x[i] += h6 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
                v[i] += h6 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
            }
        }
    }

    /// The largest magnitude of the state, or infinity if any entry is not finite.
    pub(crate) fn magnitude(&self) -> f64 {
        max_magnitude(self.x.iter().chain(&self.v).copied())
    }
}

/// The largest magnitude of `values`, or infinity if one is not finite.
pub(crate) fn max_magnitude(values: impl Iterator<Item = f64>) -> f64 {
    values
        .map(|s| {
            if s.is_finite() {
                s.abs()
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max)
}

/// `out = u0 + f · (u1 − u0)`, element by element.
#[inline]
pub(crate) fn lerp(u0: &[f64], u1: &[f64], f: f64, out: &mut [f64]) {
    for ((o, &a), &b) in out.iter_mut().zip(u0).zip(u1) {
        *o = a + f * (b - a);
    }
}
