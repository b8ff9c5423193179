//! The document of an identification.

use super::{NoRefinement, SCHEMA_VERSION};
use crate::ident::{
    EquationResidual, FilterSummary, FitWarning, Identification, LevelInfo, ParamEstimate,
    ShapeEstimate, Unidentifiable, VelocityEstimate, Warning,
};
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

/// `dynid identify --json` and `Identification.to_dict()`: the parameters keyed by name
/// (`{value, stderr, significant}`), the residual per equation keyed by the equation, and
/// the identification's diagnostics as the runtime states them.
#[derive(Debug, Serialize)]
pub struct IdentifyDoc<'a, R: Serialize = NoRefinement> {
    pub schema_version: u32,
    #[serde(serialize_with = "parameters")]
    pub parameters: &'a [ParamEstimate],
    /// `{p: {q: cov(p, q)}}` over the identified parameters (added in version 2).
    pub covariance: Covariance<'a>,
    pub condition: f64,
    pub rows: usize,
    #[serde(serialize_with = "residual")]
    pub residual: &'a [EquationResidual],
    /// `{equation: [what noise alone would leave, per level]}` (added within version 2: a
    /// new key, which readers that do not know it ignore).
    #[serde(serialize_with = "residual_noise")]
    pub residual_noise: &'a [EquationResidual],
    pub levels: &'a [LevelInfo],
    pub unidentifiable: &'a [Unidentifiable],
    pub warnings: &'a [Warning],
    pub fit_warnings: &'a [FitWarning],
    pub filter: &'a FilterSummary,
    pub estimated: &'a [VelocityEstimate],
    pub shapes: &'a [ShapeEstimate],
    /// The output-error refinement that started from this estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined: Option<&'a R>,
    /// A recorded column that looks like the set point of a controller the model lacks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closed_loop_hint: Option<&'a str>,
}

impl<'a> IdentifyDoc<'a, NoRefinement> {
    /// The document of `id`, without a refinement or hint.
    pub fn new(id: &'a Identification) -> Self {
        IdentifyDoc {
            schema_version: SCHEMA_VERSION,
            parameters: &id.params,
            covariance: Covariance(id),
            condition: id.condition,
            rows: id.rows,
            residual: &id.residual,
            residual_noise: &id.residual,
            levels: &id.levels,
            unidentifiable: &id.unidentifiable,
            warnings: &id.warnings,
            fit_warnings: &id.fit_warnings,
            filter: &id.filter,
            estimated: &id.estimated,
            shapes: &id.shapes,
            refined: None,
            closed_loop_hint: None,
        }
    }
}

impl<'a, R: Serialize> IdentifyDoc<'a, R> {
    /// The same document with the refinement `refined` (or none).
    pub fn with_refined<S: Serialize>(self, refined: Option<&'a S>) -> IdentifyDoc<'a, S> {
        IdentifyDoc {
            schema_version: self.schema_version,
            parameters: self.parameters,
            covariance: self.covariance,
            condition: self.condition,
            rows: self.rows,
            residual: self.residual,
            residual_noise: self.residual_noise,
            levels: self.levels,
            unidentifiable: self.unidentifiable,
            warnings: self.warnings,
            fit_warnings: self.fit_warnings,
            filter: self.filter,
            estimated: self.estimated,
            shapes: self.shapes,
            refined,
            closed_loop_hint: self.closed_loop_hint,
        }
    }
}

/// `{name: {value, stderr, significant}}`, in the model's order.
fn parameters<S: Serializer>(ps: &&[ParamEstimate], s: S) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Entry {
        value: f64,
        stderr: f64,
        significant: bool,
    }
    let mut m = s.serialize_map(Some(ps.len()))?;
    for p in ps.iter() {
        m.serialize_entry(
            &p.name,
            &Entry {
                value: p.value,
                stderr: p.stderr,
                significant: p.significant,
            },
        )?;
    }
    m.end()
}

/// `{equation: [residual per level]}`.
fn residual<S: Serializer>(rs: &&[EquationResidual], s: S) -> Result<S::Ok, S::Error> {
    let mut m = s.serialize_map(Some(rs.len()))?;
    for r in rs.iter() {
        m.serialize_entry(&r.equation, &r.per_level)?;
    }
    m.end()
}

/// `{equation: [noise share per level]}` ([`EquationResidual::noise`]; an empty list where
/// it was not estimated).
fn residual_noise<S: Serializer>(rs: &&[EquationResidual], s: S) -> Result<S::Ok, S::Error> {
    let mut m = s.serialize_map(Some(rs.len()))?;
    for r in rs.iter() {
        m.serialize_entry(&r.equation, &r.noise)?;
    }
    m.end()
}

/// The covariance of an identification's estimates, serialised as `{p: {q: cov(p, q)}}`
/// (keyed by name, like `parameters`).
#[derive(Clone, Copy, Debug)]
pub struct Covariance<'a>(pub &'a Identification);

impl Serialize for Covariance<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        struct Row<'a>(&'a Identification, usize);
        impl Serialize for Row<'_> {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                let ps = &self.0.params;
                let mut m = s.serialize_map(Some(ps.len()))?;
                for (j, q) in ps.iter().enumerate() {
                    m.serialize_entry(&q.name, &self.0.covariance(self.1, j))?;
                }
                m.end()
            }
        }
        let id = self.0;
        let full = id.covariance.len() == id.params.len() * id.params.len();
        let n = if full { id.params.len() } else { 0 };
        let mut m = s.serialize_map(Some(n))?;
        for (i, p) in id.params.iter().enumerate().take(n) {
            m.serialize_entry(&p.name, &Row(id, i))?;
        }
        m.end()
    }
}
