//! The document of a fleet's view.

use super::SCHEMA_VERSION;
use crate::fleet::{FleetError, FleetView, MachineEstimate};
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

/// `dynid fleet --json`: the fleet's view as the runtime states it, with the
/// between-machine covariance keyed by name (`{p: {q: Σ_pq}}`).
#[derive(Debug, Serialize)]
pub struct FleetDoc<'a> {
    pub schema_version: u32,
    #[serde(flatten)]
    pub view: &'a FleetView,
    pub between: Between<'a>,
}

impl<'a> FleetDoc<'a> {
    pub fn new(view: &'a FleetView) -> Self {
        FleetDoc {
            schema_version: SCHEMA_VERSION,
            view,
            between: Between(view),
        }
    }
}

/// The between-machine covariance of a fleet's view, keyed by name.
#[derive(Clone, Copy, Debug)]
pub struct Between<'a>(pub &'a FleetView);

impl Serialize for Between<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        struct Row<'a>(&'a FleetView, usize);
        impl Serialize for Row<'_> {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                let ps = &self.0.params;
                let mut m = s.serialize_map(Some(ps.len()))?;
                for (j, q) in ps.iter().enumerate() {
                    m.serialize_entry(&q.name, &self.0.between[self.1 * ps.len() + j])?;
                }
                m.end()
            }
        }
        let ps = &self.0.params;
        let mut m = s.serialize_map(Some(ps.len()))?;
        for (i, p) in ps.iter().enumerate() {
            m.serialize_entry(&p.name, &Row(self.0, i))?;
        }
        m.end()
    }
}

/// Reading a machine's estimate back from the document `dynid identify --json` wrote.
impl MachineEstimate {
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
}
