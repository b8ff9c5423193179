//! The driven simulation with forward sensitivities.
//!
//! The state `(x, v)` of every body carries, next to its value, its derivatives with
//! respect to `q` directions: the body states at the start of the sub-record (`2·nb`
//! directions) and the refined parameters. The right-hand side is evaluated in forward
//! mode (dual numbers over the same [`Tape`] the simulator uses), and the RK4 stages are
//! the same linear combinations for values and derivatives, so the derivatives are those
//! of the simulated trajectory itself (discrete sensitivities of RK4, which equal the
//! sensitivity equations integrated by the same RK4 steps). The value part repeats the
//! arithmetic of the simulator's `Rk4::advance` operation for operation (inputs linear
//! between samples, `substeps` steps per sample interval), so the values are those of
//! [`crate::sim::simulate_driven_from`] bit for bit (test
//! `values_match_the_driven_simulation`).

use crate::sim::mech::{lerp, max_magnitude, EquationTerms};
use crate::sim::SimError;
use crate::tape::{Op, Operand, Tape};
use dynid_ir::ir::{deadzone, saturate, BinaryOp, Coef, ModelIr, UnaryOp};

/// The equations of motion of a model with derivatives in `q` directions.
/// `(equation, root or body, coefficient value, Some((direction, ∂coef/∂param)))`.
type SensTerm = (usize, usize, f64, Option<(usize, f64)>);

#[derive(Clone, Debug)]
pub(super) struct SensModel {
    pub(super) nb: usize,
    n_inputs: usize,
    /// Number of derivative directions: `2·nb` initial states, then the parameters.
    pub(super) q: usize,
    tape: Tape,
    /// `(equation, root, coefficient value, Some((direction, ∂coef/∂param)))`.
    expr_terms: Vec<SensTerm>,
    /// The same for `Deriv{body, 1}` terms: `(equation, body, …)`.
    vel_terms: Vec<SensTerm>,
    /// Mass terms that depend on a refined parameter: `(equation, body, direction, scale)`.
    mass_terms: Vec<(usize, usize, usize, f64)>,
    minv: Vec<f64>,
    diagonal_mass: bool,
}

/// Scratch of [`SensModel::accel`].
pub(super) struct SensScratch {
    sig_val: Vec<f64>,
    sig_der: Vec<f64>,
    reg_val: Vec<f64>,
    reg_der: Vec<f64>,
    f_val: Vec<f64>,
    f_der: Vec<f64>,
}

impl SensModel {
    /// `params[p]` is the value of parameter `p`; `direction[p]` the derivative direction
    /// of a refined parameter (counted after the `2·nb` state directions).
    pub(super) fn new(
        ir: &ModelIr,
        params: &[f64],
        direction: &[Option<usize>],
    ) -> Result<Self, SimError> {
        let nb = ir.bodies.len();
        let n_dir = direction.iter().flatten().count();
        let q = 2 * nb + n_dir;
        let roots = ir.eval_roots();
        let split = EquationTerms::of(ir, &roots)?;
        let value = |c: Coef| c.scale * c.param.map_or(1.0, |p| params[p.index()]);
        let dir = |c: Coef| {
            c.param
                .and_then(|p| direction[p.index()])
                .map(|d| (2 * nb + d, c.scale))
        };
        let mut mass = nalgebra::DMatrix::<f64>::zeros(nb, nb);
        // shape: `mass` is `nb × nb` and every mass term names an equation and a body of
        // the same model.
        for &(i, body, c) in &split.mass {
            mass[(i, body)] += value(c);
        }
        let mass_terms = split
            .mass
            .iter()
            .filter_map(|&(i, body, c)| dir(c).map(|(d, s)| (i, body, d, s)))
            .collect();
        let expr_terms = split
            .expr
            .iter()
            .map(|&(i, r, c)| (i, r, value(c), dir(c)))
            .collect();
        let vel_terms = split
            .vel
            .iter()
            .map(|&(i, b, c)| (i, b, value(c), dir(c)))
            .collect();
        // The simulator's inverse (the same values, the same errors).
        let (minv, diagonal_mass) = crate::sim::mech::inverse_mass(ir, mass)?;
        Ok(SensModel {
            nb,
            n_inputs: ir.inputs.len(),
            q,
            tape: Tape::compile(ir, &roots),
            expr_terms,
            vel_terms,
            mass_terms,
            minv,
            diagonal_mass,
        })
    }

    pub(super) fn scratch(&self) -> SensScratch {
        let (q, ns, no) = (self.q, self.tape.n_signals, self.tape.ops.len());
        SensScratch {
            sig_val: vec![0.0; ns],
            sig_der: vec![0.0; ns * q],
            reg_val: vec![0.0; no],
            reg_der: vec![0.0; no * q],
            f_val: vec![0.0; self.nb],
            f_der: vec![0.0; self.nb * q],
        }
    }

    /// Accelerations with derivatives. `x`, `v` and `a` hold per body the value followed by
    /// its `q` derivatives (stride `1 + q`); `u` are the input values.
    fn accel(&self, x: &[f64], v: &[f64], u: &[f64], s: &mut SensScratch, a: &mut [f64]) {
        let (nb, q) = (self.nb, self.q);
        let w = 1 + q;
        // shape: the sizes come from the model: `x` and `v` hold `nb` blocks of `1 + q`,
        // and `s` was sized for this model by `scratch`.
        for i in 0..nb {
            s.sig_val[2 * i] = x[i * w];
            s.sig_val[2 * i + 1] = v[i * w];
            s.sig_der[2 * i * q..(2 * i + 1) * q].copy_from_slice(&x[i * w + 1..(i + 1) * w]);
            s.sig_der[(2 * i + 1) * q..(2 * i + 2) * q].copy_from_slice(&v[i * w + 1..(i + 1) * w]);
        }
        s.sig_val[2 * nb..2 * nb + self.n_inputs].copy_from_slice(u);
        self.eval_tape(s);
        s.f_val.fill(0.0);
        s.f_der.fill(0.0);
        for &(eq, root, c, dir) in &self.expr_terms {
            let SensScratch {
                sig_val,
                sig_der,
                reg_val,
                reg_der,
                f_val,
                f_der,
                ..
            } = &mut *s;
            let (rv, rd) = match self.tape.roots[root] {
                Operand::Reg(r) => (
                    reg_val[r as usize],
                    Some(&reg_der[r as usize * q..(r as usize + 1) * q]),
                ),
                Operand::Sig(k) => (
                    sig_val[k as usize],
                    Some(&sig_der[k as usize * q..(k as usize + 1) * q]),
                ),
                Operand::Const(c) => (c, None),
            };
            f_val[eq] += c * rv;
            let fd = &mut f_der[eq * q..(eq + 1) * q];
            if let Some(rd) = rd {
                for (f, r) in fd.iter_mut().zip(rd) {
                    *f += c * r;
                }
            }
            if let Some((d, sc)) = dir {
                fd[d] += sc * rv;
            }
        }
        for &(eq, body, c, dir) in &self.vel_terms {
            s.f_val[eq] += c * v[body * w];
            let fd = &mut s.f_der[eq * q..(eq + 1) * q];
            for (f, r) in fd.iter_mut().zip(&v[body * w + 1..(body + 1) * w]) {
                *f += c * r;
            }
            if let Some((d, sc)) = dir {
                fd[d] += sc * v[body * w];
            }
        }
        // Values exactly as `Mechanics::accel`.
        if self.diagonal_mass {
            for i in 0..nb {
                a[i * w] = -self.minv[i * nb + i] * s.f_val[i];
            }
        } else {
            for i in 0..nb {
                a[i * w] = -self
                    .minv
                    .chunks_exact(nb)
                    .nth(i)
                    .expect("invariant: nb rows")
                    .iter()
                    .zip(&s.f_val)
                    .map(|(m, f)| m * f)
                    .sum::<f64>();
            }
        }
        // M a + f = 0  ⇒  ∂a = −M⁻¹ (∂f + ∂M a).
        for &(eq, body, d, sc) in &self.mass_terms {
            s.f_der[eq * q + d] += sc * a[body * w];
        }
        for i in 0..nb {
            for k in 0..q {
                let mut acc = 0.0;
                for j in 0..nb {
                    acc += self.minv[i * nb + j] * s.f_der[j * q + k];
                }
                a[i * w + 1 + k] = -acc;
            }
        }
    }

    /// The tape at one point, values and derivatives (forward mode).
    fn eval_tape(&self, s: &mut SensScratch) {
        let q = self.q;
        for (i, op) in self.tape.ops.iter().enumerate() {
            let (done, rest) = s.reg_der.split_at_mut(i * q);
            let dst = &mut rest[..q];
            let get = |o: Operand| -> (f64, Option<&[f64]>) {
                match o {
                    Operand::Reg(r) => (
                        s.reg_val[r as usize],
                        Some(&done[r as usize * q..(r as usize + 1) * q]),
                    ),
                    Operand::Sig(k) => (
                        s.sig_val[k as usize],
                        Some(&s.sig_der[k as usize * q..(k as usize + 1) * q]),
                    ),
                    Operand::Const(c) => (c, None),
                }
            };
            // Value, then derivative as a combination of the operands' derivatives.
            let (val, da, a_der, db, b_der) = match *op {
                Op::Unary(u, a) => {
                    let (av, ad) = get(a);
                    let val = u.apply(av);
                    let d = match u {
                        UnaryOp::Neg => -1.0,
                        UnaryOp::Abs => dynid_ir::ir::sign(av),
                        UnaryOp::Sign => 0.0,
                        UnaryOp::Tanh => 1.0 - val * val,
                        UnaryOp::Sqrt => 0.5 / val,
                        UnaryOp::Exp => val,
                        UnaryOp::Sin => av.cos(),
                        UnaryOp::Cos => -av.sin(),
                    };
                    (val, d, ad, 0.0, None)
                }
                Op::Binary(b, x, y) => {
                    let ((xv, xd), (yv, yd)) = (get(x), get(y));
                    let val = b.apply(xv, yv);
                    let (dx, dy) = match b {
                        BinaryOp::Add => (1.0, 1.0),
                        BinaryOp::Sub => (1.0, -1.0),
                        BinaryOp::Mul => (yv, xv),
                        BinaryOp::Div => (1.0 / yv, -val / yv),
                    };
                    (val, dx, xd, dy, yd)
                }
                Op::Powi(a, k) => {
                    let (av, ad) = get(a);
                    (av.powi(k), k as f64 * av.powi(k - 1), ad, 0.0, None)
                }
                Op::Deadzone(a, g) => {
                    let (av, ad) = get(a);
                    let d = if av.abs() > g { 1.0 } else { 0.0 };
                    (deadzone(av, g), d, ad, 0.0, None)
                }
                Op::Saturate(a, l) => {
                    let (av, ad) = get(a);
                    let d = if av.abs() < l { 1.0 } else { 0.0 };
                    (saturate(av, l), d, ad, 0.0, None)
                }
            };
            match (a_der, b_der) {
                (Some(a), Some(b)) => {
                    for ((o, x), y) in dst.iter_mut().zip(a).zip(b) {
                        *o = da * x + db * y;
                    }
                }
                (Some(a), None) => dst.iter_mut().zip(a).for_each(|(o, x)| *o = da * x),
                (None, Some(b)) => dst.iter_mut().zip(b).for_each(|(o, y)| *o = db * y),
                (None, None) => dst.fill(0.0),
            }
            s.reg_val[i] = val;
        }
    }
}

/// RK4 state with sensitivities (per body: value, then `q` derivatives).
pub(super) struct SensRk4 {
    pub(super) x: Vec<f64>,
    pub(super) v: Vec<f64>,
    a1: Vec<f64>,
    a2: Vec<f64>,
    a3: Vec<f64>,
    a4: Vec<f64>,
    v2: Vec<f64>,
    v3: Vec<f64>,
    v4: Vec<f64>,
    xt: Vec<f64>,
    u: Vec<f64>,
    scratch: SensScratch,
}

impl SensRk4 {
    /// At positions `x0` and velocities `v0`; the derivatives start as the identity in the
    /// state directions and zero in the parameter directions.
    pub(super) fn new(m: &SensModel, x0: &[f64], v0: &[f64]) -> Self {
        let w = 1 + m.q;
        let z = vec![0.0; m.nb * w];
        let (mut x, mut v) = (z.clone(), z.clone());
        for b in 0..m.nb {
            x[b * w] = x0[b];
            v[b * w] = v0[b];
            x[b * w + 1 + b] = 1.0;
            v[b * w + 1 + m.nb + b] = 1.0;
        }
        SensRk4 {
            x,
            v,
            a1: z.clone(),
            a2: z.clone(),
            a3: z.clone(),
            a4: z.clone(),
            v2: z.clone(),
            v3: z.clone(),
            v4: z.clone(),
            xt: z,
            u: vec![0.0; m.n_inputs],
            scratch: m.scratch(),
        }
    }

    /// One sample interval, inputs linear from `u0` to `u1` (as `Rk4::advance`).
    pub(super) fn advance(
        &mut self,
        m: &SensModel,
        u0: &[f64],
        u1: &[f64],
        ts: f64,
        substeps: usize,
    ) {
        let h = ts / substeps as f64;
        let (h2, h6) = (0.5 * h, h / 6.0);
        let n = substeps as f64;
        let len = self.x.len();
        for j in 0..substeps {
            let j = j as f64;
            lerp(u0, u1, j / n, &mut self.u);
            m.accel(&self.x, &self.v, &self.u, &mut self.scratch, &mut self.a1);
            for i in 0..len {
                self.xt[i] = self.x[i] + h2 * self.v[i];
                self.v2[i] = self.v[i] + h2 * self.a1[i];
            }
            lerp(u0, u1, (j + 0.5) / n, &mut self.u);
            m.accel(&self.xt, &self.v2, &self.u, &mut self.scratch, &mut self.a2);
            for i in 0..len {
                self.xt[i] = self.x[i] + h2 * self.v2[i];
                self.v3[i] = self.v[i] + h2 * self.a2[i];
            }
            m.accel(&self.xt, &self.v3, &self.u, &mut self.scratch, &mut self.a3);
            for i in 0..len {
                self.xt[i] = self.x[i] + h * self.v3[i];
                self.v4[i] = self.v[i] + h * self.a3[i];
            }
            lerp(u0, u1, (j + 1.0) / n, &mut self.u);
            m.accel(&self.xt, &self.v4, &self.u, &mut self.scratch, &mut self.a4);
            for i in 0..len {
                self.x[i] += h6 * (self.v[i] + 2.0 * self.v2[i] + 2.0 * self.v3[i] + self.v4[i]);
                self.v[i] += h6 * (self.a1[i] + 2.0 * self.a2[i] + 2.0 * self.a3[i] + self.a4[i]);
            }
        }
    }

    /// Largest magnitude of the state values, infinity if one is not finite.
    pub(super) fn magnitude(&self, w: usize) -> f64 {
        max_magnitude(
            self.x
                .iter()
                .step_by(w)
                .chain(self.v.iter().step_by(w))
                .copied(),
        )
    }
}
