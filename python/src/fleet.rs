//! The fleet's view from Python: machines of one model, each identified on its own (their
//! identification documents), tested against their fleet — `dynid fleet` (docs/fleet.md).

use crate::errors::{guarded, runtime_error};
use crate::model::json;
use dynid::runtime::fleet::{assess, FleetOptions, Machine, MachineEstimate};
use dynid::runtime::schema::FleetDoc;
use pyo3::prelude::*;

/// `(json, text)` of the fleet's view of `machines`, `(name, identification JSON)` each.
#[pyfunction]
#[pyo3(name = "fleet", signature = (machines, alpha=0.01))]
pub(crate) fn fleet_view(
    py: Python<'_>,
    machines: Vec<(String, String)>,
    alpha: f64,
) -> PyResult<(String, String)> {
    guarded(py, || {
        let mut parsed = Vec::with_capacity(machines.len());
        for (name, doc) in &machines {
            let estimate = MachineEstimate::from_document(doc, &format!("machine `{name}`"))
                .map_err(|e| runtime_error(py, &e))?;
            parsed.push(Machine {
                name: name.clone(),
                estimate: Ok(estimate),
            });
        }
        let opts = FleetOptions {
            alpha,
            ..Default::default()
        };
        let view = py
            .detach(|| assess(&parsed, &opts))
            .map_err(|e| runtime_error(py, &e))?;
        Ok((json(&FleetDoc::new(&view))?, view.table()))
    })
}
