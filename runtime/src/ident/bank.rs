//! The filter bank a model needs, chosen from the options, the model's filter block and the
//! model's terms before any sample is read: which signals drive the chains, how many
//! sections each chain has (at least the relative degree the model's moments need) and how
//! many corners.

use super::types::{IdentifyError, IdentifyOptions};
use dynid_ir::ir::{ModelIr, SignalId, SignalKind};

/// Lowest degree of the chain state `J` of a band-pass instrument `J''`: the instrument
/// then holds sections 2 … of its chain, none of which weighs the current sample of the
/// driver (relative degree ≥ 2, as every other instrument).
pub(crate) const ACC_MIN_DEGREE: usize = 4;

/// Filter choices resolved from options, the model's filter block and the data.
#[derive(Clone, Debug)]
pub(crate) struct BankChoice {
    /// Drive chains by the nonlinear static columns too ([`super::plan::RootDriver`]).
    pub regressors: bool,
    /// Rows of the filtered equation ([`super::types::IdentifyOptions::filtered`]).
    pub filtered: bool,
    pub drivers: Vec<SignalId>,
    pub order: usize,
    pub min_degree: usize,
    pub n_corners: usize,
}

/// The filter bank a model needs: its drivers (the options', the model's, or every measured
/// position, input and acceleration), its order (at least the relative degree the model's
/// moments need) and its number of corners.
pub(crate) fn choose_bank(
    ir: &ModelIr,
    opts: &IdentifyOptions,
) -> Result<BankChoice, IdentifyError> {
    let spec = ir.filter.as_ref();
    let drivers = match (&opts.drivers, spec.map(|f| &f.driven_by)) {
        (Some(d), _) => d.clone(),
        (None, Some(d)) if !d.is_empty() => d.clone(),
        _ => ir
            .measured_signals()
            .into_iter()
            .filter(|s| {
                matches!(
                    ir.signal(*s).kind,
                    SignalKind::Position(_) | SignalKind::Input(_) | SignalKind::Acceleration(_)
                )
            })
            .collect(),
    };
    // Accelerations from positions alone need ι'' free of the driving signal: degree ≥ 3.
    let needs_second = ir.equations.iter().any(|eq| {
        eq.terms.iter().any(|t| match t.basis {
            dynid_ir::ir::Basis::Deriv { body, order: 2 } => !ir.signal(ir.velocity(body)).measured,
            _ => false,
        })
    });
    // Integrals of accelerations need band-pass instruments `ζᵢ''` with `i ≥ 4`.
    let accelerations =
        (0..ir.bodies.len()).any(|b| ir.acceleration_only(dynid_ir::ir::BodyId(b as u32)));
    let min_degree = if accelerations {
        ACC_MIN_DEGREE
    } else if needs_second {
        3
    } else {
        2
    };
    // The filtered equation with the inputs' delays: a steeper chain, so that its corner
    // can rise to 0.5/Tₛ (`filtered::FILTERED_DELAY_ORDER`).
    let fallback = match opts.filtered && opts.input_delay {
        true => (min_degree + 1).max(super::filtered::FILTERED_DELAY_ORDER),
        false => min_degree + 1,
    };
    let order = opts
        .order
        .or(spec.map(|f| f.order as usize))
        .unwrap_or(fallback);
    if order < min_degree || order > 8 {
        return Err(IdentifyError::BadOption {
            message: format!("filter order {order}"),
            help: format!("use an order between {min_degree} and 8 for this model"),
        });
    }
    let n_corners = match (&opts.corners, spec.map(|f| &f.corners)) {
        (Some(c), _) => c.len(),
        (None, Some(c)) if !c.is_empty() => c.len(),
        _ if opts.filtered => 1,
        _ => opts.n_corners,
    };
    Ok(BankChoice {
        regressors: opts.column_chains || opts.filtered,
        filtered: opts.filtered,
        drivers,
        order,
        min_degree,
        n_corners,
    })
}
