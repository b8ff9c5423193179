//! The machines of a fleet: one estimate each, from an identification in memory or from the
//! document `dynid identify --json` wrote (read back by `crate::schema`, where the
//! documents live).

use super::FleetError;
use crate::ident::Identification;
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
