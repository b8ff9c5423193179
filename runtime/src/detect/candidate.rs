//! Candidate effects: a basis function φ(s, v; θ) that could hide in an element, and its
//! equivalent-linear gains.
//!
//! Statistical linearisation with s ~ N(0, σ_s²) and v ~ N(0, σ_v²) independent replaces
//! a force `p·φ(s, v)` by `p·h_k·s + p·h_d·v` with
//!
//! ```text
//! h_k = E[s φ] / σ_s²        h_d = E[v φ] / σ_v²
//! ```
//!
//! (the least-squares projection of φ on s and v). An effect that is even in s and v
//! (say s²) has both gains zero: it shifts the mean, not a linear parameter, and is
//! invisible to detection.

use super::quad::NormalRule;

/// The measured distribution of a signal at one level, standardised (z = (x − mean)/σ):
/// histogram bin centres with their probabilities. With it, the gains are the
/// least-squares projections over the data's own distribution instead of a Gaussian one
/// (see [`Candidate::gains_with`]).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Distribution {
    pub z: Vec<f64>,
    pub w: Vec<f64>,
}

impl Distribution {
    /// From histogram counts over equal bins `[lo + i·h, lo + (i+1)·h)` of the raw signal.
    pub fn from_counts(counts: &[u64], lo: f64, h: f64, mean: f64, sigma: f64) -> Self {
        let n: u64 = counts.iter().sum();
        let mut out = Self::default();
        if n == 0 || sigma.is_nan() || sigma <= 0.0 {
            return out;
        }
        for (i, &c) in counts.iter().enumerate() {
            if c > 0 {
                out.z.push((lo + (i as f64 + 0.5) * h - mean) / sigma);
                out.w.push(c as f64 / n as f64);
            }
        }
        out
    }

    /// E[f(Z)].
    pub fn expect(&self, f: impl Fn(f64) -> f64) -> f64 {
        self.z.iter().zip(&self.w).map(|(z, w)| w * f(*z)).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.z.is_empty()
    }
}

/// Which of the element's relative signals φ depends on; it decides whether the
/// expectation is one- or two-dimensional.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Dependence {
    /// φ(s) only; h_d = 0.
    S,
    /// φ(v) only; h_k = 0.
    V,
    /// Both (two-dimensional quadrature).
    SV,
}

/// A shape parameter θ of φ (the gap of a dead zone), fitted by a 1-D search.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShapeParam {
    /// Printed name, e.g. `g`.
    pub name: String,
    /// Search range relative to the median σ of the signal named by `scale_by`.
    pub lo_rel: f64,
    pub hi_rel: f64,
    /// Whether θ scales with σ_s (`Dependence::S`) or σ_v (`Dependence::V`).
    pub scale_by: Dependence,
    /// φ has kinks or jumps at s = ±θ (or v = ±θ); the quadrature then cuts there.
    pub kinks_at_pm_theta: bool,
}

type Phi = Box<dyn Fn(f64, f64, f64) -> f64 + Send + Sync>;

/// One candidate effect `p·φ(s, v; θ)` with unknown coefficient p.
pub struct Candidate {
    /// Name of the effect, e.g. `cubic stiffness`.
    pub name: String,
    /// Name of the coefficient p, e.g. `k3`.
    pub coef_name: String,
    /// The force term as a person writes it, e.g. `k3·s³`.
    pub formula: String,
    pub dependence: Dependence,
    pub shape: Option<ShapeParam>,
    /// Fixed kinks of φ in s and in v besides 0 (absolute units).
    pub kinks_s: Vec<f64>,
    pub kinks_v: Vec<f64>,
    /// Restrict to these elements; `None` = every element.
    pub elements: Option<Vec<String>>,
    /// The coefficient must be ≥ 0 for the effect to be physical (friction dissipates, a
    /// dead zone engages stiffness, a preload pushes outwards). This also keeps effects
    /// apart: a "backlash" with negative stiffness and a vanishing gap is exactly a
    /// prestress, and without the sign constraint every prestress would tie with it.
    pub positive: bool,
    phi: Phi,
}

impl std::fmt::Debug for Candidate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Candidate")
            .field("name", &self.name)
            .field("formula", &self.formula)
            .field("dependence", &self.dependence)
            .field("shape", &self.shape)
            .finish_non_exhaustive()
    }
}

impl Candidate {
    /// A user-declared term `coef_name · φ(s, v)`; φ is evaluated by quadrature, so any
    /// function works (for an `ExprId` of the IR, wrap `ModelIr::eval_scalar` in the
    /// closure). Declare kinks other than 0 with [`Candidate::with_kinks`].
    pub fn custom(
        name: impl Into<String>,
        coef_name: impl Into<String>,
        formula: impl Into<String>,
        dependence: Dependence,
        phi: impl Fn(f64, f64) -> f64 + Send + Sync + 'static,
    ) -> Self {
        Self {
            name: name.into(),
            coef_name: coef_name.into(),
            formula: formula.into(),
            dependence,
            shape: None,
            kinks_s: Vec::new(),
            kinks_v: Vec::new(),
            elements: None,
            positive: false,
            phi: Box::new(move |s, v, _| phi(s, v)),
        }
    }

    /// A user-declared term with a shape parameter θ: `coef_name · φ(s, v; θ)`.
    pub fn custom_shaped(
        name: impl Into<String>,
        coef_name: impl Into<String>,
        formula: impl Into<String>,
        dependence: Dependence,
        shape: ShapeParam,
        phi: impl Fn(f64, f64, f64) -> f64 + Send + Sync + 'static,
    ) -> Self {
        Self {
            name: name.into(),
            coef_name: coef_name.into(),
            formula: formula.into(),
            dependence,
            shape: Some(shape),
            kinks_s: Vec::new(),
            kinks_v: Vec::new(),
            elements: None,
            positive: false,
            phi: Box::new(phi),
        }
    }

    pub fn with_kinks(mut self, kinks_s: Vec<f64>, kinks_v: Vec<f64>) -> Self {
        self.kinks_s = kinks_s;
        self.kinks_v = kinks_v;
        self
    }

    /// Require a coefficient ≥ 0 (see [`Candidate::positive`]).
    pub fn positive(mut self) -> Self {
        self.positive = true;
        self
    }

    pub fn only_for(mut self, elements: Vec<String>) -> Self {
        self.elements = Some(elements);
        self
    }

    pub fn applies_to(&self, element: &str) -> bool {
        match &self.elements {
            None => true,
            Some(e) => e.iter().any(|n| n == element),
        }
    }

    /// φ(s, v; θ).
    pub fn phi(&self, s: f64, v: f64, theta: f64) -> f64 {
        (self.phi)(s, v, theta)
    }

    /// Cubic stiffness `k3·s³`: k_eq = k + 3 k3 σ_s².
    pub fn cubic_stiffness() -> Self {
        Self::custom("cubic stiffness", "k3", "k3·s³", Dependence::S, |s, _| {
            s * s * s
        })
    }

    /// Coulomb friction `r·sign(v)`: d_eq = d + r √(2/π)/σ_v.
    pub fn coulomb() -> Self {
        Self::custom(
            "Coulomb friction",
            "r",
            "r·sign(v)",
            Dependence::V,
            |_, v| dynid_ir::ir::sign(v),
        )
        .positive()
    }

    /// Quadratic damping `c·v|v|`: d_eq = d + c √(8/π) σ_v.
    pub fn quadratic_damping() -> Self {
        Self::custom(
            "quadratic damping",
            "c",
            "c·v|v|",
            Dependence::V,
            |_, v| v * v.abs(),
        )
        .positive()
    }

    /// Prestress / preload `f0·sign(s)`: k_eq = k + f0 √(2/π)/σ_s.
    pub fn prestress() -> Self {
        Self::custom("prestress", "f0", "f0·sign(s)", Dependence::S, |s, _| {
            dynid_ir::ir::sign(s)
        })
        .positive()
    }

    /// Backlash / dead zone `kb·dz(s, g)`: by Stein's lemma k_eq = k + kb·erfc(g/(σ_s√2)),
    /// rising from k towards k + kb as σ_s outgrows the gap.
    pub fn backlash() -> Self {
        Self::custom_shaped(
            "backlash",
            "kb",
            "kb·dz(s, g)",
            Dependence::S,
            ShapeParam {
                name: "g".into(),
                lo_rel: 0.02,
                hi_rel: 5.0,
                scale_by: Dependence::S,
                kinks_at_pm_theta: true,
            },
            |s, _, g| dynid_ir::ir::deadzone(s, g),
        )
        .positive()
    }

    /// The built-in effects of the detection table.
    pub fn builtins() -> Vec<Candidate> {
        vec![
            Self::cubic_stiffness(),
            Self::coulomb(),
            Self::quadratic_damping(),
            Self::backlash(),
            Self::prestress(),
        ]
    }

    /// Equivalent-linear gains as projections over measured distributions of s and v
    /// (standardised, see [`Distribution`]): h_k = E[s φ]/E[s²], h_d = E[v φ]/E[v²] with
    /// the expectations taken over the data. An effect that reshapes the motion (a
    /// hardening spring makes s light-tailed, stick–slip piles v up near zero) then gets
    /// the gain it has on that motion rather than on a Gaussian one. `None` (or an
    /// effect of both s and v, whose joint distribution is not kept) falls back to the
    /// Gaussian [`Candidate::gains`].
    pub fn gains_with(
        &self,
        sigma_s: f64,
        sigma_v: f64,
        theta: f64,
        s_dist: Option<&Distribution>,
        v_dist: Option<&Distribution>,
    ) -> (f64, f64) {
        match (self.dependence, s_dist, v_dist) {
            (Dependence::S, Some(d), _) if !d.is_empty() => {
                let num = d.expect(|z| z * self.phi(sigma_s * z, 0.0, theta));
                let den = d.expect(|z| z * z);
                (num / (den * sigma_s), 0.0)
            }
            (Dependence::V, _, Some(d)) if !d.is_empty() => {
                let num = d.expect(|z| z * self.phi(0.0, sigma_v * z, theta));
                let den = d.expect(|z| z * z);
                (0.0, num / (den * sigma_v))
            }
            _ => self.gains(sigma_s, sigma_v, theta),
        }
    }

    /// Equivalent-linear gains (h_k, h_d) at intensities (σ_s, σ_v) and shape θ, for
    /// Gaussian s and v.
    pub fn gains(&self, sigma_s: f64, sigma_v: f64, theta: f64) -> (f64, f64) {
        let breaks = |fixed: &[f64], sigma: f64, shaped: bool| {
            let mut b: Vec<f64> = fixed.iter().map(|k| k / sigma).collect();
            if shaped && self.shape.as_ref().is_some_and(|s| s.kinks_at_pm_theta) {
                b.push(theta / sigma);
                b.push(-theta / sigma);
            }
            NormalRule::with_breaks(&b)
        };
        let shaped_s = self
            .shape
            .as_ref()
            .is_some_and(|s| s.scale_by == Dependence::S);
        let shaped_v = self
            .shape
            .as_ref()
            .is_some_and(|s| s.scale_by == Dependence::V);
        match self.dependence {
            Dependence::S => {
                let r = breaks(&self.kinks_s, sigma_s, shaped_s);
                let hk = r.expect(|z| z * self.phi(sigma_s * z, 0.0, theta)) / sigma_s;
                (hk, 0.0)
            }
            Dependence::V => {
                let r = breaks(&self.kinks_v, sigma_v, shaped_v);
                let hd = r.expect(|z| z * self.phi(0.0, sigma_v * z, theta)) / sigma_v;
                (0.0, hd)
            }
            Dependence::SV => {
                let rs = breaks(&self.kinks_s, sigma_s, shaped_s);
                let rv = breaks(&self.kinks_v, sigma_v, shaped_v);
                let (mut es, mut ev) = (0.0, 0.0);
                for (&zs, &ws) in rs.z.iter().zip(&rs.w) {
                    for (&zv, &wv) in rv.z.iter().zip(&rv.w) {
                        let f = self.phi(sigma_s * zs, sigma_v * zv, theta);
                        es += ws * wv * zs * f;
                        ev += ws * wv * zv * f;
                    }
                }
                (es / sigma_s, ev / sigma_v)
            }
        }
    }
}
