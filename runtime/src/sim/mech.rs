//! The equations of motion as an acceleration function, and a fixed-step RK4 integrator.
//!
//! Equation `i` reads `Σ coef·basis = 0`. The `Deriv{j,2}` terms form the mass matrix `M`,
//! everything else is the force vector `r(x, v, u)`, so `ẍ = −M⁻¹ r`. `M⁻¹` is computed
//! once (coefficients are constants during a simulation).

use super::SimError;
use crate::tape::Tape;
use dynid_ir::ir::{Basis, ModelIr};

/// Precomputed, allocation-free acceleration function of a model.
#[derive(Clone, Debug)]
pub(crate) struct Mechanics {
    pub(crate) n_bodies: usize,
    pub(crate) n_inputs: usize,
    tape: Tape,
    /// `(equation, root, coefficient value)` for every `Expr` term.
    expr_terms: Vec<(usize, usize, f64)>,
    /// `(equation, body, coefficient value)` for every `Deriv{body, 1}` term.
    vel_terms: Vec<(usize, usize, f64)>,
    /// `M⁻¹`, row-major.
    minv: Vec<f64>,
    diagonal_mass: bool,
}

/// Scratch space for [`Mechanics::accel`], one per thread.
#[derive(Clone, Debug)]
pub(crate) struct MechScratch {
    signals: Vec<f64>,
    regs: Vec<f64>,
    roots: Vec<f64>,
    force: Vec<f64>,
}

impl Mechanics {
    /// `params[p]` is the value of parameter `p`.
    pub(crate) fn new(ir: &ModelIr, params: &[f64]) -> Result<Self, SimError> {
        let nb = ir.bodies.len();
        let roots = ir.eval_roots();
        let root_index = |e| {
            roots
                .iter()
                .position(|&r| r == e)
                .expect("invariant: root of a term")
        };
        let value = |c: dynid_ir::ir::Coef| c.scale * c.param.map_or(1.0, |p| params[p.index()]);
        let mut mass = nalgebra::DMatrix::<f64>::zeros(nb, nb);
        let mut expr_terms = Vec::new();
        let mut vel_terms = Vec::new();
        for (i, eq) in ir.equations.iter().enumerate() {
            let body_name = || ir.bodies[eq.body.index()].name.clone();
            if eq.body.index() != i {
                return Err(SimError::UnsupportedTerm {
                    body: body_name(),
                    what: "equations are not in body order".into(),
                });
            }
            for t in &eq.terms {
                let c = value(t.coef);
                match t.basis {
                    Basis::Expr(e) => expr_terms.push((i, root_index(e), c)),
                    Basis::Deriv { body, order: 1 } => vel_terms.push((i, body.index(), c)),
                    Basis::Deriv { body, order: 2 } => mass[(i, body.index())] += c,
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
        let diagonal_mass = (0..nb).all(|i| (0..nb).all(|j| i == j || mass[(i, j)] == 0.0));
        let minv = if diagonal_mass {
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
        let minv = (0..nb)
            .flat_map(|i| (0..nb).map(move |j| (i, j)))
            .map(|(i, j)| minv[(i, j)])
            .collect();
        Ok(Mechanics {
            n_bodies: nb,
            n_inputs: ir.inputs.len(),
            tape: Tape::compile(ir, &roots),
            expr_terms,
            vel_terms,
            minv,
            diagonal_mass,
        })
    }

    pub(crate) fn scratch(&self) -> MechScratch {
        MechScratch {
            signals: vec![0.0; self.tape.n_signals],
            regs: vec![0.0; self.tape.ops.len()],
            roots: vec![0.0; self.tape.n_roots()],
            force: vec![0.0; self.n_bodies],
        }
    }

    /// Accelerations `a` at positions `x`, velocities `v` and inputs `u`.
    #[inline]
    pub(crate) fn accel(
        &self,
        x: &[f64],
        v: &[f64],
        u: &[f64],
        s: &mut MechScratch,
        a: &mut [f64],
    ) {
        let nb = self.n_bodies;
        for i in 0..nb {
            s.signals[2 * i] = x[i];
            s.signals[2 * i + 1] = v[i];
        }
        s.signals[2 * nb..2 * nb + self.n_inputs].copy_from_slice(u);
        self.tape.eval_point(&s.signals, &mut s.regs, &mut s.roots);
        s.force.fill(0.0);
        for &(eq, root, c) in &self.expr_terms {
            s.force[eq] += c * s.roots[root];
        }
        for &(eq, body, c) in &self.vel_terms {
            s.force[eq] += c * v[body];
        }
        if self.diagonal_mass {
            for (i, (a, f)) in a.iter_mut().zip(&s.force).enumerate() {
                *a = -self.minv[i * nb + i] * f;
            }
        } else {
            for (a, row) in a.iter_mut().zip(self.minv.chunks_exact(nb)) {
                *a = -row.iter().zip(&s.force).map(|(m, f)| m * f).sum::<f64>();
            }
        }
    }
}

/// Classical RK4 state and stage buffers (allocated once per run).
#[derive(Clone, Debug)]
pub(crate) struct Rk4 {
    pub(crate) x: Vec<f64>,
    pub(crate) v: Vec<f64>,
    a1: Vec<f64>,
    a2: Vec<f64>,
    a3: Vec<f64>,
    a4: Vec<f64>,
    v2: Vec<f64>,
    v3: Vec<f64>,
    v4: Vec<f64>,
    xt: Vec<f64>,
    u: Vec<f64>,
    scratch: MechScratch,
}

impl Rk4 {
    /// At rest at the origin.
    pub(crate) fn new(mech: &Mechanics) -> Self {
        let z = vec![0.0; mech.n_bodies];
        Rk4 {
            x: z.clone(),
            v: z.clone(),
            a1: z.clone(),
            a2: z.clone(),
            a3: z.clone(),
            a4: z.clone(),
            v2: z.clone(),
            v3: z.clone(),
            v4: z.clone(),
            xt: z,
            u: vec![0.0; mech.n_inputs],
            scratch: mech.scratch(),
        }
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
        let h = ts / substeps as f64;
        let (h2, h6) = (0.5 * h, h / 6.0);
        let n = substeps as f64;
        let nb = mech.n_bodies;
        for j in 0..substeps {
            let j = j as f64;
            lerp(u0, u1, j / n, &mut self.u);
            mech.accel(&self.x, &self.v, &self.u, &mut self.scratch, &mut self.a1);
            for i in 0..nb {
                self.xt[i] = self.x[i] + h2 * self.v[i];
                self.v2[i] = self.v[i] + h2 * self.a1[i];
            }
            lerp(u0, u1, (j + 0.5) / n, &mut self.u);
            mech.accel(&self.xt, &self.v2, &self.u, &mut self.scratch, &mut self.a2);
            for i in 0..nb {
                self.xt[i] = self.x[i] + h2 * self.v2[i];
                self.v3[i] = self.v[i] + h2 * self.a2[i];
            }
            mech.accel(&self.xt, &self.v3, &self.u, &mut self.scratch, &mut self.a3);
            for i in 0..nb {
                self.xt[i] = self.x[i] + h * self.v3[i];
                self.v4[i] = self.v[i] + h * self.a3[i];
            }
            lerp(u0, u1, (j + 1.0) / n, &mut self.u);
            mech.accel(&self.xt, &self.v4, &self.u, &mut self.scratch, &mut self.a4);
            for i in 0..nb {
                self.x[i] += h6 * (self.v[i] + 2.0 * self.v2[i] + 2.0 * self.v3[i] + self.v4[i]);
                self.v[i] += h6 * (self.a1[i] + 2.0 * self.a2[i] + 2.0 * self.a3[i] + self.a4[i]);
            }
        }
    }

    /// The largest magnitude of the state, or infinity if any entry is not finite.
    pub(crate) fn magnitude(&self) -> f64 {
        self.x
            .iter()
            .chain(&self.v)
            .map(|&s| {
                if s.is_finite() {
                    s.abs()
                } else {
                    f64::INFINITY
                }
            })
            .fold(0.0, f64::max)
    }
}

#[inline]
fn lerp(u0: &[f64], u1: &[f64], f: f64, out: &mut [f64]) {
    for ((o, &a), &b) in out.iter_mut().zip(u0).zip(u1) {
        *o = a + f * (b - a);
    }
}
