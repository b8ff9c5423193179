//! The bank's layout in memory, which every path reads: every driver's chains in blocks of
//! [`LANES`] side by side, their coefficients and states (structure of arrays).

/// Chains of one driver updated together by one vector operation.
pub const LANES: usize = 4;

/// `LANES` chains side by side.
pub type Lane = [f64; LANES];

/// Largest filter order of the bank (the order check of identification enforces it).
pub const MAX_ORDER: usize = 8;

/// The whole bank in structure-of-arrays form: every driver's chains (one per corner) in
/// blocks of [`LANES`], so that one sample updates a block with a few straight-line vector
/// operations whatever the number of corners (a partial last block runs on zero
/// coefficients and stays zero).
///
/// Each chain follows the recursion of [`super::ChainDisc::run`], with the sums of a step taken
/// in another order and fused (see `super::kernel::step`): the outputs agree to rounding. Where the
/// processor has them, 512-bit (eight chains) or 256-bit (four chains, one block) vector
/// instructions do the work ([`FilterBank::advance`]), with the same operations in the same
/// order as the portable code: the outputs are the same bit for bit on every processor.
///
/// Outputs are written sample-major: at sample `k`, row [`FilterBank::row`]`(d, c, i)` of
/// `out[k · stride ..]` receives state `ζᵢ₊₁` of the chain of driver `d` and corner `c`,
/// the corners of one driver and state side by side (no padding rows). Sample-major is
/// what the moment accumulation multiplies with, and stores a sample's states in a few
/// contiguous runs.
#[derive(Clone, Debug)]
pub struct FilterBank {
    pub(super) order: usize,
    pub(super) n_drivers: usize,
    pub(super) n_corners: usize,
    /// Blocks per driver, `⌈n_corners / LANES⌉`.
    pub(super) blocks_per_driver: usize,
    /// Per block: `Φ` (full `order × order`, row-major), `Γ₀`, `Γ₁`, each entry a lane.
    pub(super) coef: Vec<Lane>,
    /// `Φ^(2^j)` per block (full `order × order`, row-major), `j = 0, 1, …`: the free
    /// response over any number of samples by binary powering.
    pub(super) pow: Vec<Vec<Lane>>,
}

/// The state of a [`FilterBank`] after some sample: `ζ` of every chain and the driving
/// values at that sample (the `s[k]` of the next step).
#[derive(Clone, Debug, PartialEq)]
pub struct BankState {
    /// Per block, per state `i`: one lane.
    pub(super) z: Vec<Lane>,
    pub(super) prev: Vec<f64>,
}

impl BankState {
    /// The state of chain `(d, c)`, `ζ₁ … ζ_order`.
    pub fn chain(&self, bank: &FilterBank, d: usize, c: usize) -> Vec<f64> {
        let blk = d * bank.blocks_per_driver + c / LANES;
        (0..bank.order)
            .map(|i| self.z[blk * bank.order + i][c % LANES])
            .collect()
    }

    /// The driving values at the sample of this state.
    pub fn prev(&self) -> &[f64] {
        &self.prev
    }
}
