//! One measured signal's first pass, chunk by chunk: its sums, its zero crossings about a
//! reference band (the dominant frequency), its noise floors and its screen. A chunk is cut
//! into pieces taken in parallel and joined in order, with the results of one
//! sample-by-sample scan.

use super::floor::{BandFloor, NoiseFloor};
use super::screen::ColumnScreen;
use rayon::prelude::*;

/// Samples per piece of the first pass: a streamed chunk of a signal is cut into pieces
/// taken in parallel (over time, not only over signals) and joined in order.
const PIECE: usize = 2048;

/// The first pass's statistics of one measured signal, accumulated chunk by chunk.
#[derive(Default)]
pub(super) struct SignalPass {
    /// The first sample: sums are taken about it (no cancellation for a large mean).
    pub(super) shift: f64,
    pub(super) s1: f64,
    pub(super) s2: f64,
    /// Hysteresis zero-crossing count about a reference (mean, band) from the record's
    /// first [`REFERENCE_LEN`] samples.
    reference: (f64, f64),
    side: i8,
    pub(super) crossings: usize,
    pub(super) floor: NoiseFloor,
    /// Third differences at octave strides: the band above the noise floor.
    pub(super) band: BandFloor,
    pub(super) screen: ColumnScreen,
}

/// One piece's share of a [`SignalPass`]: its sums, its noise floor sums, and its side
/// changes as seen without knowing the side it starts on.
struct PiecePass {
    s1: f64,
    s2: f64,
    floor: NoiseFloor,
    /// The first and the last side met (0: none), and the changes of side after the first.
    first: i8,
    last: i8,
    changes: usize,
}

impl PiecePass {
    /// `c` is the piece, `floor` a floor ready to take it (its sums zero).
    fn of(c: &[f64], shift: f64, (above, below): (f64, f64), mut floor: NoiseFloor) -> Self {
        // Sums in four independent lanes (no wait on the previous addition).
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        let mut chunks = c.chunks_exact(4);
        for (q, ch) in (&mut chunks).enumerate() {
            if q % 2 == 0 {
                // The piece comes from memory, and is too short for the processor's own
                // prefetching to lock on.
                crate::prefetch::ahead(c, 4 * q);
            }
            for j in 0..4 {
                let d = ch[j] - shift;
                a[j] += d;
                b[j] += d * d;
            }
        }
        for (j, &v) in chunks.remainder().iter().enumerate() {
            let d = v - shift;
            a[j] += d;
            b[j] += d * d;
        }
        floor.push(c);
        // Side changes: a block of eight samples with none beyond the far side of the band
        // changes nothing (one vectorised test per block; a change of side is rare).
        let (mut first, mut side, mut changes) = (0i8, 0i8, 0usize);
        for block in c.chunks(8) {
            fn any(block: &[f64], f: impl Fn(f64) -> bool) -> bool {
                block.iter().fold(false, |a, &v| a | f(v))
            }
            let quiet = match side {
                1 => !any(block, |v| v < below),
                -1 => !any(block, |v| v > above),
                _ => !any(block, |v| v < below || v > above),
            };
            if quiet {
                continue;
            }
            for &v in block {
                let now = i8::from(v > above) - i8::from(v < below);
                if now != 0 && now != side {
                    if side != 0 {
                        changes += 1;
                    } else {
                        first = now;
                    }
                    side = now;
                }
            }
        }
        PiecePass {
            s1: (a[0] + a[1]) + (a[2] + a[3]),
            s2: (b[0] + b[1]) + (b[2] + b[3]),
            floor,
            first,
            last: side,
            changes,
        }
    }
}

/// Samples at the start of a record that give the zero-crossing count its reference (the
/// first chunk where a chunk is shorter), so that the count, and the filter corners
/// designed from it, do not depend on the chunk length above it.
const REFERENCE_LEN: usize = 8192;

impl SignalPass {
    pub(super) fn push(&mut self, c: &[f64], first: bool) {
        if first {
            self.shift = c[0];
            let r = &c[..c.len().min(REFERENCE_LEN)];
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / r.len() as f64;
            self.reference = (mean, 0.25 * var.sqrt());
        }
        let (mid, h) = self.reference;
        let band = (mid + h, mid - h);
        let (shift, seen) = (self.shift, self.floor.seen());
        // The pieces in parallel: the first continues this signal's floor, every other one
        // starts after the nine samples before it in the chunk (`PIECE` ≥ 9).
        let base = &self.floor;
        let parts: Vec<PiecePass> = (0..c.len().div_ceil(PIECE))
            .into_par_iter()
            .map(|p| {
                let a = p * PIECE;
                let piece = &c[a..(a + PIECE).min(c.len())];
                let floor = if a == 0 {
                    base.emptied()
                } else {
                    NoiseFloor::resume(&c[a - 9..a], seen + a)
                };
                PiecePass::of(piece, shift, band, floor)
            })
            .collect();
        // Joined in order: the same side changes as one sample-by-sample scan.
        for p in &parts {
            self.s1 += p.s1;
            self.s2 += p.s2;
            self.floor.absorb(&p.floor);
            if p.first != 0 {
                if self.side != 0 && p.first != self.side {
                    self.crossings += 1;
                }
                self.crossings += p.changes;
                self.side = p.last;
            }
        }
        self.band.push(c);
        self.screen.push(c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A smooth random signal with noise: many crossings, every side of the band.
    fn signal(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut u = 0.0;
        (0..n)
            .map(|_| {
                u = 0.98 * u + 0.2 * (rng.random::<f64>() - 0.5);
                3.0 + u + 0.01 * (rng.random::<f64>() - 0.5)
            })
            .collect()
    }

    #[test]
    fn pieces_give_the_crossings_and_floor_of_one_scan() {
        let x = signal(50_000, 5);
        let whole = {
            let mut f = NoiseFloor::default();
            f.push(&x);
            f
        };
        let mut long_chunks = None;
        for chunk in [50_000, 8192, 4097, 2048, 300, 7] {
            let mut sp = SignalPass::default();
            for (i, c) in x.chunks(chunk).enumerate() {
                sp.push(c, i == 0);
            }
            // Chunks of at least REFERENCE_LEN samples: one reference, so one count.
            if chunk >= REFERENCE_LEN {
                let got = (sp.reference, sp.crossings);
                assert_eq!(*long_chunks.get_or_insert(got), got, "chunks of {chunk}");
            }
            // The hysteresis count of a sample-by-sample scan about the same reference.
            let (mid, h) = sp.reference;
            let (mut side, mut crossings) = (0i8, 0usize);
            for &v in &x {
                let now = if v > mid + h {
                    1
                } else if v < mid - h {
                    -1
                } else {
                    0
                };
                if now != 0 && now != side {
                    crossings += usize::from(side != 0);
                    side = now;
                }
            }
            assert!(crossings > 50, "{crossings}");
            assert_eq!(
                (sp.crossings, sp.side),
                (crossings, side),
                "chunks of {chunk}"
            );
            assert_eq!(sp.floor.seen(), x.len());
            for h in 1..=3 {
                let (a, b) = (sp.floor.mean_square(h), whole.mean_square(h));
                assert!((a / b - 1.0).abs() < 1e-12, "chunks of {chunk}, stride {h}");
            }
            let mean = sp.shift + sp.s1 / x.len() as f64;
            let want = x.iter().sum::<f64>() / x.len() as f64;
            assert!((mean - want).abs() < 1e-12, "chunks of {chunk}");
        }
    }
}
