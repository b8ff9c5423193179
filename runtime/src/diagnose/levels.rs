//! The measured levels as the diagnosis reads them: which signals are responses, the
//! levels' names, the records as level sources, and a model with a fit's values.

use super::types::DiagnoseError;
use crate::data::{DataError, LevelSource, RecordSource};
use crate::ident::Identification;
use crate::record::Record;
use dynid_ir::ir::{ModelIr, ParamKind, SignalKind};

/// The levels of a diagnosis: records, their names and the response signals compared.
pub(super) struct Data<'a> {
    pub(super) records: &'a [Record],
    pub(super) origins: &'a [String],
    pub(super) response: Vec<String>,
    /// The loudest level's displacement of every body, recorded or integrated from its
    /// acceleration (`candidates::displacements`): the backlash grid's spread.
    pub(super) displacements: Vec<Option<Vec<f64>>>,
}

/// Check what a diagnosis needs of the model and the levels (at least 2 levels, a nominal
/// value for every parameter, a response signal) and return the response signals and a
/// name for every level (`origins`, or "level k").
///
/// The responses: body signals, and in closed loop the inputs a law computes (the drive
/// force answers the plant as much as the position does). Open-loop inputs and
/// references are given, not responses.
pub(super) fn prepare(
    ir: &ModelIr,
    levels: &[Record],
    origins: &[String],
) -> Result<(Vec<String>, Vec<String>), DiagnoseError> {
    let n = levels.len();
    if n < 2 {
        return Err(DiagnoseError::TooFewLevels(n));
    }
    if let Some(p) = ir.params.iter().find(|p| p.nominal().is_none()) {
        return Err(DiagnoseError::MissingNominal(p.name.clone()));
    }
    let response: Vec<String> = ir
        .measured_signals()
        .iter()
        .map(|s| ir.signal(*s))
        .filter(|s| match s.kind {
            SignalKind::Position(_) | SignalKind::Velocity(_) | SignalKind::Acceleration(_) => true,
            SignalKind::Input(i) => ir.control_of(i).is_some(),
            SignalKind::Reference(_) => false,
        })
        .map(|s| s.name.clone())
        .collect();
    if response.is_empty() {
        return Err(DiagnoseError::NoResponse);
    }
    let origins: Vec<String> = (0..n)
        .map(|i| {
            origins
                .get(i)
                .cloned()
                .unwrap_or(format!("level {}", i + 1))
        })
        .collect();
    Ok((response, origins))
}

/// Read a level source into memory (the free-run comparison needs the whole record).
pub fn read_record(src: &dyn LevelSource, ir: &ModelIr) -> Result<Record, DataError> {
    let measured = ir.measured_signals();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); measured.len()];
    src.stream(8192, &mut |cols, len| {
        for (out, s) in columns.iter_mut().zip(&measured) {
            out.extend_from_slice(&cols[s.index()][..len]);
        }
    })?;
    Ok(Record {
        names: measured
            .iter()
            .map(|s| ir.signal(*s).name.clone())
            .collect(),
        columns,
        ts: src.ts(),
        t0: 0.0,
    })
}

/// The levels as sources of `ir`'s signals.
pub(super) fn sources<'r>(
    ir: &ModelIr,
    data: &'r Data,
) -> Result<Vec<RecordSource<'r>>, DataError> {
    data.records
        .iter()
        .zip(data.origins)
        .map(|(r, o)| RecordSource::new(r, ir, o.clone()))
        .collect()
}

/// The training levels when level `w` of `n` is withheld.
pub(super) fn training(n: usize, w: usize) -> Vec<usize> {
    (0..n).filter(|&i| i != w).collect()
}

/// Parameter values to simulate with: identified values for identified unknowns.
pub(super) fn with_values(ir: &ModelIr, id: &Identification) -> ModelIr {
    let mut out = ir.clone();
    for p in out.params.iter_mut() {
        if let ParamKind::Unknown { nominal } = &mut p.kind {
            if let Some(e) = id.param(&p.name) {
                *nominal = Some(e.value);
            } else if nominal.is_none() {
                *nominal = Some(0.0);
            }
        }
    }
    out
}

/// The SI unit of the signal `name` of `ir` (see [`super::SignalGap::unit`]).
pub(super) fn unit_of(ir: &ModelIr, name: &str) -> &'static str {
    match ir.signals.iter().find(|s| s.name == name).map(|s| s.kind) {
        Some(SignalKind::Position(_)) => "m",
        Some(SignalKind::Velocity(_)) => "m/s",
        Some(SignalKind::Input(_)) => "N",
        _ => "",
    }
}
