//! The fleet's view: machines of one model, each identified on its own, compared with the
//! fleet they belong to.
//!
//! # The fleet's model
//!
//! Machine `i` gives an estimate `p_i` (`k` parameters) with covariance `C_i` (the
//! batch-means sandwich of its identification). Real machines of one design do not share one
//! parameter vector: masses, stiffnesses and friction scatter around the nominal from part
//! to part, typically by a few per cent, while a long record identifies each machine to a
//! fraction of a per cent. So `p_i = p̄ + b_i + e_i` with the machine's own deviation
//! `b_i ~ (0, Σ)` (the fleet's *between-machine* covariance) and its estimation error
//! `e_i ~ (0, C_i)`. A test of `p_i` against the pooled value with `C_i` alone would flag
//! nearly every healthy machine (the comparison of [`FleetOptions::between`] measures it).
//!
//! `p̄` and `Σ` are estimated from the machines by method of moments on a set of machines
//! held consistent, with hard rejection of the rest ([`spread`]):
//!
//! 1. start: the coordinate-wise median and the MAD scale `s_j = 1.4826 · MAD_j`; a machine
//!    is held when every `|p_ij − median_j| ≤ z* · s_j` (`z*` below);
//! 2. on the held machines, `p̄` their mean, `S` their sample covariance and `W` the mean of
//!    their `C_i`; `Σ = (S − W)₊`, the positive part (eigenvalues of the difference below
//!    zero set to zero, in the coordinates scaled by `√(S_jj + W_jj)`: a direction in which the
//!    machines scatter less than their own errors has no between-machine spread);
//! 3. every machine is tested against (`p̄`, `Σ`); the machines not flagged are the new held
//!    set, and 2–3 repeat until the set stays the same.
//!
//! Rejection happens only beyond the family-wise threshold, far in the tail, so the
//! truncation leaves `S` low by a negligible amount (below 0.1 % of a variance at the
//! default level) and is not corrected. `p̄` includes the machine tested: its variance
//! shrinks the test's denominator by a factor `1 − 1/n`, negligible for a fleet and
//! conservative.
//!
//! # The consistency test
//!
//! `d_i² = (p_i − p̄)ᵀ (Σ + C_i)⁻¹ (p_i − p̄)` is χ² with `k` degrees of freedom for a machine
//! of the fleet. It is solved by a Cholesky factorisation of `Σ + C_i` scaled to unit
//! diagonal, never by an inverse. Where the scaled matrix is singular or ill-conditioned
//! (condition above [`MAX_CONDITION`]; e.g. a covariance that is not positive definite), the
//! test is made in the `r` directions of its eigendecomposition whose eigenvalues are above
//! `λ_max / MAX_CONDITION`, with `r` degrees of freedom, and the machine says so. The
//! p-value is the χ² upper tail (`statrs`). A machine is flagged when its p-value is below
//! `α / n` (Bonferroni over the `n` machines tested: the chance that any healthy machine of
//! the fleet is flagged is at most `α`).
//!
//! For a flagged machine the parameters that moved are those with `|z_ij| > z*`,
//! `z_ij = (p_ij − p̄_j) / √(Σ_jj + C_i,jj)`, `z*` the two-sided normal quantile of
//! `α / (n k)` (Bonferroni over every parameter of every machine), largest first (or, where
//! none passes because the machine moved along a correlation, the largest one).
//!
//! Machines whose identification failed or left a parameter unidentified are listed with
//! the reason and take no part in the fleet's model or the test.

mod consistency;
mod machine;
mod spread;
#[cfg(test)]
mod tests;
mod text;

pub use consistency::{chi2_quantile, chi2_upper_tail, normal_quantile};
pub use machine::{Machine, MachineEstimate};

use consistency::Test;
use serde::Serialize;

/// Above this condition number (of `Σ + C_i` scaled to unit diagonal) the test is made in
/// the well-determined directions only.
pub const MAX_CONDITION: f64 = 1e12;

/// Choices of the fleet's view.
#[derive(Clone, Debug)]
pub struct FleetOptions {
    /// Family-wise level: the chance that any machine consistent with its fleet is flagged.
    pub alpha: f64,
    /// Estimate the between-machine covariance `Σ` (default). Off: every machine is tested
    /// against the pooled value (the mean of the machines held by the median screen, one
    /// round) with its own covariance alone — for comparison only; on a real fleet it flags
    /// machines that are merely different parts.
    pub between: bool,
}

impl Default for FleetOptions {
    fn default() -> Self {
        FleetOptions {
            alpha: 0.01,
            between: true,
        }
    }
}

/// Errors of the fleet's view.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum FleetError {
    #[error("invalid option: {message}")]
    #[diagnostic(code(dynid::fleet::option), help("{help}"))]
    BadOption { message: String, help: String },
    #[error("{origin}: {detail}")]
    #[diagnostic(
        code(dynid::fleet::document),
        help("give the documents that `dynid identify MODEL DATA… --json FILE` writes, one per machine")
    )]
    Document { origin: String, detail: String },
    #[error("{origin}: schema version {found}; this version of dynid reads version {expected}")]
    #[diagnostic(
        code(dynid::fleet::schema_version),
        help("identify the machine again with this version of dynid (`dynid identify … --json FILE`)")
    )]
    SchemaVersion {
        origin: String,
        found: u64,
        expected: u32,
    },
    #[error("{origin}: the document has no `covariance` of its estimates (it was written before identifications reported it)")]
    #[diagnostic(
        code(dynid::fleet::no_covariance),
        help("identify the machine again with this version of dynid (`dynid identify … --json FILE`): the test needs the full covariance, not only the standard errors")
    )]
    NoCovariance { origin: String },
    #[error("{origin} is not of the same model as {first}: {detail}")]
    #[diagnostic(
        code(dynid::fleet::models),
        help("compare machines of one model: identify every machine with the same .dyn file")
    )]
    Models {
        origin: String,
        first: String,
        detail: String,
    },
    #[error("two machines are named `{name}`")]
    #[diagnostic(
        code(dynid::fleet::duplicate),
        help(
            "name every machine once (`NAME=FILE` names a machine other than by its file's stem)"
        )
    )]
    DuplicateName { name: String },
    #[error("{usable} machine(s) with every parameter identified{which}; the fleet's model of {k} parameter(s) needs at least {need}")]
    #[diagnostic(
        code(dynid::fleet::too_few),
        help("the between-machine covariance has k(k+1)/2 entries: give more machines, or identify the failed ones again")
    )]
    TooFewMachines {
        usable: usize,
        which: String,
        k: usize,
        need: usize,
    },
}

/// What became of a machine.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Consistent with its fleet.
    Consistent,
    /// Inconsistent with its fleet at the family-wise level.
    Flagged,
    /// Its identification left parameters unidentified: not tested.
    RankDeficient,
    /// Its identification failed: not tested.
    Failed,
}

/// One parameter of the fleet's model.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FleetParam {
    pub name: String,
    /// The centre `p̄`: the mean over the machines held consistent.
    pub value: f64,
    /// Standard error of the centre, `√(S_jj / n_held)`.
    pub stderr: f64,
    /// The between-machine standard deviation `√Σ_jj`.
    pub spread: f64,
    /// The machines' own standard errors, root mean square over the held machines.
    pub within: f64,
}

/// One parameter of one machine against its fleet.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct MachineParam {
    pub name: String,
    pub value: f64,
    pub stderr: f64,
    /// `value / p̄` (absent where the fleet's value is zero).
    pub ratio: Option<f64>,
    /// `(value − p̄) / √(Σ_jj + C_jj)` (0 where both vanish).
    pub z: f64,
}

/// The χ² consistency test of one machine.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Consistency {
    pub d2: f64,
    /// Degrees of freedom: the parameters, or fewer where `Σ + C_i` is singular.
    pub dof: usize,
    /// Upper tail of χ²(dof) at `d2`.
    pub p_value: f64,
    /// Condition number of `Σ + C_i` scaled to unit diagonal.
    pub condition: f64,
}

/// One machine's verdict.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct MachineVerdict {
    pub name: String,
    pub status: Status,
    /// The machine's identified parameters against the fleet, in the fleet's order.
    pub params: Vec<MachineParam>,
    /// The consistency test (absent for machines not tested).
    pub test: Option<Consistency>,
    /// A flagged machine's parameters that moved, largest `|z|` first; empty otherwise.
    pub moved: Vec<MachineParam>,
    /// Why a machine was not tested, or how its test was restricted.
    pub note: Option<String>,
}

/// The fleet's view: its model and every machine's verdict.
#[derive(Clone, Debug, Serialize)]
pub struct FleetView {
    /// Family-wise level.
    pub alpha: f64,
    /// Machines tested (the Bonferroni count).
    pub tested: usize,
    /// Machines held consistent, on which the fleet's model rests.
    pub held: usize,
    /// `d²` above which a machine with every direction tested is flagged
    /// (the χ²(k) quantile of `1 − α/n`).
    pub critical_d2: f64,
    /// `|z|` above which a flagged machine's parameter counts as moved.
    pub critical_z: f64,
    /// Whether the between-machine covariance was estimated ([`FleetOptions::between`]).
    pub between_estimated: bool,
    /// Directions in which the machines scatter less than their own errors (no
    /// between-machine spread there).
    pub between_clipped: usize,
    /// Rounds of the held set until it stayed the same.
    pub rounds: usize,
    /// `Some(n)` when the held set never settled: it alternated between `n` sets (or
    /// wandered for [`MAX_ROUNDS`] rounds over `n`), and the fleet's model rests on the
    /// machines held in all of them. `None`: it settled.
    pub alternated: Option<usize>,
    pub params: Vec<FleetParam>,
    /// The between-machine covariance `Σ` (row-major, `params.len()²`).
    #[serde(skip)]
    pub between: Vec<f64>,
    pub machines: Vec<MachineVerdict>,
}

impl FleetView {
    /// The flagged machines, in input order.
    pub fn flagged(&self) -> impl Iterator<Item = &MachineVerdict> {
        self.machines.iter().filter(|m| m.status == Status::Flagged)
    }

    /// The machine named `name`.
    pub fn machine(&self, name: &str) -> Option<&MachineVerdict> {
        self.machines.iter().find(|m| m.name == name)
    }
}

/// The fleet's view of `machines` (see the module doc): its model, and every machine tested
/// against it.
pub fn assess(machines: &[Machine], opts: &FleetOptions) -> Result<FleetView, FleetError> {
    if !(opts.alpha > 0.0 && opts.alpha < 1.0) {
        return Err(FleetError::BadOption {
            message: format!("the level α = {} is not between 0 and 1", opts.alpha),
            help: "give a family-wise level such as 0.01".into(),
        });
    }
    let mut seen = std::collections::BTreeSet::new();
    for m in machines {
        if !seen.insert(m.name.as_str()) {
            return Err(FleetError::DuplicateName {
                name: m.name.clone(),
            });
        }
    }
    let names = machine::parameter_set(machines)?;
    let k = names.len();
    let testable: Vec<(usize, &MachineEstimate)> = machines
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match &m.estimate {
            Ok(e) if e.unidentifiable.is_empty() => Some((i, e)),
            _ => None,
        })
        .collect();
    // The fleet's covariance has k(k+1)/2 entries: twice the parameters plus two machines
    // leave it some degrees of freedom (and the median a majority to stand on).
    let need = 2 * k + 2;
    let too_few = |usable: usize, which: &str| FleetError::TooFewMachines {
        usable,
        which: which.into(),
        k,
        need,
    };
    if testable.len() < need {
        return Err(too_few(testable.len(), ""));
    }
    let n = testable.len();
    let ests: Vec<&MachineEstimate> = testable.iter().map(|(_, e)| *e).collect();
    let ordered: Vec<machine::Ordered> = ests.iter().map(|e| e.ordered(&names)).collect();
    let critical_z = normal_quantile(1.0 - opts.alpha / (2.0 * (n * k) as f64));
    let level = opts.alpha / n as f64;
    let fit_and_test = |held: &[bool]| -> Result<(spread::FleetModel, Vec<Test>), FleetError> {
        let count = held.iter().filter(|&&h| h).count();
        if count < need {
            return Err(too_few(count, " held consistent"));
        }
        let model = spread::fit(&ordered, held, opts.between);
        let tests = ordered
            .iter()
            .map(|o| consistency::test(o, &model))
            .collect();
        Ok((model, tests))
    };
    // Without the between-machine spread the machines that are merely different parts
    // would be rejected round after round: one round from the screened set is the
    // comparison.
    let max_rounds = if opts.between { MAX_ROUNDS } else { 1 };
    let (held, settling) = settle(spread::screen(&ordered, critical_z), max_rounds, |held| {
        let (_, tests) = fit_and_test(held)?;
        Ok(tests.iter().map(|t| t.p_value >= level).collect())
    })?;
    let (model, tests) = fit_and_test(&held)?;
    let mut verdicts: Vec<MachineVerdict> = machines
        .iter()
        .map(|m| untested(m, &names, &model))
        .collect();
    for ((i, _), (o, t)) in testable.iter().zip(ordered.iter().zip(&tests)) {
        let flagged = t.p_value < level;
        let params = consistency::machine_params(o, &names, &model);
        let moved = if flagged {
            consistency::moved(&params, critical_z)
        } else {
            Vec::new()
        };
        verdicts[*i] = MachineVerdict {
            name: machines[*i].name.clone(),
            status: if flagged {
                Status::Flagged
            } else {
                Status::Consistent
            },
            params,
            test: Some(Consistency {
                d2: t.d2,
                dof: t.dof,
                p_value: t.p_value,
                condition: t.condition,
            }),
            moved,
            note: (t.dof < k).then(|| {
                format!(
                    "the covariance of its estimate and the fleet's is singular (condition {}): tested in {} of {k} directions",
                    dynid_ir::num::sig(t.condition, 2, false),
                    t.dof
                )
            }),
        };
    }
    let held_count = tests.iter().filter(|t| t.p_value >= level).count();
    Ok(FleetView {
        alpha: opts.alpha,
        tested: n,
        held: held_count,
        critical_d2: chi2_quantile(1.0 - level, k),
        critical_z,
        between_estimated: opts.between,
        between_clipped: model.clipped,
        rounds: settling.rounds,
        alternated: settling.alternated,
        params: names
            .iter()
            .enumerate()
            .map(|(j, name)| FleetParam {
                name: name.clone(),
                value: model.centre[j],
                stderr: model.centre_se[j],
                spread: model.between[(j, j)].max(0.0).sqrt(),
                within: model.within[j],
            })
            .collect(),
        between: (0..k * k).map(|i| model.between[(i / k, i % k)]).collect(),
        machines: verdicts,
    })
}

/// Rounds of the held set before it counts as not settling.
pub const MAX_ROUNDS: usize = 50;

/// How the held set ended ([`settle`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Settling {
    rounds: usize,
    alternated: Option<usize>,
}

/// Iterates `step` (the held set of the next round, given this round's) from `start` until
/// the set repeats itself or `max_rounds` have run. It settles when a round gives back its
/// own set (or at `max_rounds == 1`). Where it returns to an earlier set instead — a fit
/// on A rejects what B holds and a fit on B what A holds — no set is the fleet, and the
/// machines held in every set of the cycle are kept: the fleet's model rests only on what
/// every round agreed on. The same holds for the sets visited when the bound ends the
/// rounds.
pub(crate) fn settle<E>(
    start: Vec<bool>,
    max_rounds: usize,
    mut step: impl FnMut(&[bool]) -> Result<Vec<bool>, E>,
) -> Result<(Vec<bool>, Settling), E> {
    let mut seen: Vec<Vec<bool>> = Vec::new();
    let mut held = start;
    for rounds in 1..=max_rounds {
        let next = step(&held)?;
        if next == held || max_rounds == 1 {
            let settled = Settling {
                rounds,
                alternated: None,
            };
            return Ok((held, settled));
        }
        seen.push(held);
        if let Some(first) = seen.iter().position(|s| *s == next) {
            let cycle = &seen[first..];
            let kept = common(cycle);
            let alternated = Some(cycle.len());
            return Ok((kept, Settling { rounds, alternated }));
        }
        held = next;
    }
    seen.push(held);
    let alternated = Some(seen.len());
    let kept = common(&seen);
    let rounds = max_rounds;
    Ok((kept, Settling { rounds, alternated }))
}

/// The machines held in every one of `sets`.
fn common(sets: &[Vec<bool>]) -> Vec<bool> {
    (0..sets[0].len())
        .map(|i| sets.iter().all(|s| s[i]))
        .collect()
}

/// The verdict of a machine that is not tested (failed, or rank-deficient: its identified
/// parameters are still compared with the fleet one by one).
fn untested(m: &Machine, names: &[String], model: &spread::FleetModel) -> MachineVerdict {
    let (status, params, note) = match &m.estimate {
        Err(why) => (
            Status::Failed,
            Vec::new(),
            format!("identification failed: {why}"),
        ),
        Ok(e) => {
            let params = consistency::partial_params(e, names, model);
            let missing: Vec<String> = e
                .unidentifiable
                .iter()
                .map(|(n, why)| format!("`{n}` ({why})"))
                .collect();
            (
                Status::RankDeficient,
                params,
                format!("not identified: {}", missing.join("; ")),
            )
        }
    };
    MachineVerdict {
        name: m.name.clone(),
        status,
        params,
        test: None,
        moved: Vec::new(),
        note: Some(note),
    }
}
