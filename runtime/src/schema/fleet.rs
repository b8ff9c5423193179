//! The document of a fleet's view.

use super::SCHEMA_VERSION;
use crate::fleet::FleetView;
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
