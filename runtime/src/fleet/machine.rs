//! The machines of a fleet: one estimate each, from an identification in memory or from the
//! document `dynid identify --json` wrote.

use super::FleetError;
use crate::ident::Identification;
use crate::schema::SCHEMA_VERSION;
use std::collections::{BTreeMap, BTreeSet};

/// One machine's identified parameters with their covariance.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineEstimate {
    /// The identified parameters' names.
    pub names: Vec<String>,
    pub values: Vec<f64>,
    /// Row-major `names.len()²`.
    pub covariance: Vec<f64>,
    /// Parameters the identification could not determine, with the reason.
    pub unidentifiable: Vec<(String, String)>,
    /// The model's equations (to refuse machines of different models).
    pub equations: Vec<String>,
}

/// A machine of the fleet: its name and its estimate, or why its identification failed.
#[derive(Clone, Debug)]
pub struct Machine {
    pub name: String,
    pub estimate: Result<MachineEstimate, String>,
}

impl MachineEstimate {
    /// The estimate of an identification.
    pub fn from_identification(id: &Identification) -> MachineEstimate {
        let k = id.params.len();
        MachineEstimate {
            names: id.params.iter().map(|p| p.name.clone()).collect(),
            values: id.params.iter().map(|p| p.value).collect(),
            covariance: (0..k * k).map(|i| id.covariance(i / k, i % k)).collect(),
            unidentifiable: id
                .unidentifiable
                .iter()
                .map(|u| (u.name.clone(), u.reason.clone()))
                .collect(),
            equations: id.residual.iter().map(|r| r.equation.clone()).collect(),
        }
    }

    /// The estimate in the identification document `text` (`dynid identify --json`;
    /// docs/json.md) read from `origin`.
    pub fn from_document(text: &str, origin: &str) -> Result<MachineEstimate, FleetError> {
        let bad = |detail: String| FleetError::Document {
            origin: origin.into(),
            detail,
        };
        let v: serde_json::Value = serde_json::from_str(text).map_err(|e| {
            bad(format!(
                "not JSON (line {}, column {}): {e}",
                e.line(),
                e.column()
            ))
        })?;
        let doc = v
            .as_object()
            .ok_or_else(|| bad("not an identification document (not a JSON object)".into()))?;
        let version = doc
            .get("schema_version")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| bad("not an identification document (no `schema_version`)".into()))?;
        if version != u64::from(SCHEMA_VERSION) {
            return Err(FleetError::SchemaVersion {
                origin: origin.into(),
                found: version,
                expected: SCHEMA_VERSION,
            });
        }
        let params = doc
            .get("parameters")
            .and_then(|p| p.as_object())
            .ok_or_else(|| {
                bad(
                    "not an identification document (no `parameters`: a detection or diagnosis?)"
                        .into(),
                )
            })?;
        let number = |v: Option<&serde_json::Value>, what: String| {
            v.and_then(|v| v.as_f64())
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("{what} is not a finite number")))
        };
        let names: Vec<String> = params.keys().cloned().collect();
        let values = names
            .iter()
            .map(|n| number(params[n].get("value"), format!("`parameters.{n}.value`")))
            .collect::<Result<Vec<f64>, _>>()?;
        let cov = doc
            .get("covariance")
            .and_then(|c| c.as_object())
            .ok_or_else(|| FleetError::NoCovariance {
                origin: origin.into(),
            })?;
        let mut covariance = Vec::with_capacity(names.len() * names.len());
        for p in &names {
            for q in &names {
                let at = cov.get(p).and_then(|row| row.get(q));
                covariance.push(number(at, format!("`covariance.{p}.{q}`"))?);
            }
        }
        let unidentifiable = doc
            .get("unidentifiable")
            .and_then(|u| u.as_array())
            .map(|u| {
                u.iter()
                    .map(|e| {
                        let s =
                            |k: &str| e.get(k).and_then(|v| v.as_str()).unwrap_or("").to_string();
                        (s("name"), s("reason"))
                    })
                    .collect()
            })
            .unwrap_or_default();
        let equations = doc
            .get("residual")
            .and_then(|r| r.as_object())
            .map(|r| r.keys().cloned().collect())
            .unwrap_or_default();
        Ok(MachineEstimate {
            names,
            values,
            covariance,
            unidentifiable,
            equations,
        })
    }

    /// Every parameter of the model: identified or not, sorted by name.
    fn all_names(&self) -> BTreeSet<&str> {
        self.names
            .iter()
            .map(String::as_str)
            .chain(self.unidentifiable.iter().map(|(n, _)| n.as_str()))
            .collect()
    }

    /// The estimate in the order `names` (every one of which it identifies).
    pub(super) fn ordered(&self, names: &[String]) -> Ordered {
        let at: Vec<usize> = names
            .iter()
            .map(|n| {
                self.names
                    .iter()
                    .position(|m| m == n)
                    .expect("invariant: a tested machine identifies every parameter of the fleet")
            })
            .collect();
        let k = self.names.len();
        Ordered {
            values: at.iter().map(|&a| self.values[a]).collect(),
            covariance: nalgebra::DMatrix::from_fn(names.len(), names.len(), |i, j| {
                self.covariance[at[i] * k + at[j]]
            }),
        }
    }
}

/// A tested machine's estimate in the fleet's parameter order.
pub(super) struct Ordered {
    pub values: Vec<f64>,
    pub covariance: nalgebra::DMatrix<f64>,
}

/// The parameters of the fleet, in the order of the first machine that identified them
/// all; an error where two machines are not of one model (their parameters or equations
/// differ).
pub(super) fn parameter_set(machines: &[Machine]) -> Result<Vec<String>, FleetError> {
    let estimated: Vec<(&str, &MachineEstimate)> = machines
        .iter()
        .filter_map(|m| m.estimate.as_ref().ok().map(|e| (m.name.as_str(), e)))
        .collect();
    let Some(&(first, reference)) = estimated
        .iter()
        .find(|(_, e)| e.unidentifiable.is_empty())
        .or(estimated.first())
    else {
        return Ok(Vec::new());
    };
    let all = reference.all_names();
    let eqs: BTreeSet<&str> = reference.equations.iter().map(String::as_str).collect();
    for &(name, e) in &estimated {
        let other = e.all_names();
        let differ = |a: &BTreeSet<&str>, b: &BTreeSet<&str>| {
            let only = |x: &BTreeSet<&str>, y: &BTreeSet<&str>| {
                x.difference(y)
                    .map(|s| format!("`{s}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            match (only(a, b), only(b, a)) {
                (x, y) if x.is_empty() => format!("{y} only in {first}"),
                (x, y) if y.is_empty() => format!("{x} only in {name}"),
                (x, y) => format!("{x} only in {name}, {y} only in {first}"),
            }
        };
        let models = |detail: String| FleetError::Models {
            origin: name.into(),
            first: first.into(),
            detail,
        };
        if other != all {
            return Err(models(format!(
                "its parameters differ ({})",
                differ(&other, &all)
            )));
        }
        let theirs: BTreeSet<&str> = e.equations.iter().map(String::as_str).collect();
        if theirs != eqs {
            return Err(models(format!(
                "its equations differ ({})",
                differ(&theirs, &eqs)
            )));
        }
    }
    // The map keeps the first complete machine's order of the names.
    let order: BTreeMap<&str, usize> = reference
        .names
        .iter()
        .chain(reference.unidentifiable.iter().map(|(n, _)| n))
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let mut names: Vec<String> = all.iter().map(|s| s.to_string()).collect();
    names.sort_by_key(|n| order[n.as_str()]);
    Ok(names)
}
