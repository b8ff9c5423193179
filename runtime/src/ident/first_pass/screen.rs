//! Screening of a level's columns in the first pass: a sample far outside the robust spread
//! of its column (a recording glitch, a lost exponent, a saturated channel) and a level
//! without any motion are refused before they spoil the moments.
//!
//! The robust spread is the larger of `1.4826 · MAD` (median absolute deviation about the
//! median, scaled to the standard deviation of a normal distribution) and the 99th
//! percentile of the absolute deviations divided by 2.576 (the same for a normal
//! distribution), taken over a strided subsample of at most [`KEEP`] values so memory stays
//! fixed for any record length. The percentile keeps a record that rests (sensor noise
//! only) for most of its length and then moves from being judged against its noise alone;
//! a recording glitch is a handful of samples and moves neither. A sample counts as an
//! outlier when it lies more than [`OUTLIER_RATIO`] robust standard deviations from the
//! median. Random-excitation records stay orders of magnitude below that, and so do the
//! bursts and moves from rest of the unit tests below; a genuine impulse on a background
//! that is almost silent for more than 99 % of the record could exceed it, and is then
//! refused too (there is no override).

/// Quantile of the kept absolute deviations that also sets the robust spread, and the
/// standard normal's quantile at the same probability (two-sided), which turns it into a
/// standard deviation.
const TAIL_QUANTILE: f64 = 0.99;
const TAIL_Z: f64 = 2.576;

/// Samples kept per column for the robust spread.
const KEEP: usize = 4096;

/// Distance from the median, in robust standard deviations, beyond which a sample is an
/// outlier.
pub(crate) const OUTLIER_RATIO: f64 = 1e5;

/// Running screen of one column.
#[derive(Clone, Debug)]
pub(crate) struct ColumnScreen {
    kept: Vec<f64>,
    stride: usize,
    seen: usize,
    /// (value, sample) of the smallest and the largest value.
    min: (f64, usize),
    max: (f64, usize),
}

impl Default for ColumnScreen {
    fn default() -> Self {
        ColumnScreen {
            kept: Vec::with_capacity(KEEP),
            stride: 1,
            seen: 0,
            min: (f64::INFINITY, 0),
            max: (f64::NEG_INFINITY, 0),
        }
    }
}

/// The smallest and the largest of `c` (infinities for an empty slice; NaN is never
/// either), in eight lanes so the comparisons vectorise.
fn extremes(c: &[f64]) -> (f64, f64) {
    let mut lo = [f64::INFINITY; 8];
    let mut hi = [f64::NEG_INFINITY; 8];
    let mut chunks = c.chunks_exact(8);
    for ch in &mut chunks {
        for j in 0..8 {
            lo[j] = if ch[j] < lo[j] { ch[j] } else { lo[j] };
            hi[j] = if ch[j] > hi[j] { ch[j] } else { hi[j] };
        }
    }
    for (j, &v) in chunks.remainder().iter().enumerate() {
        lo[j] = if v < lo[j] { v } else { lo[j] };
        hi[j] = if v > hi[j] { v } else { hi[j] };
    }
    let lo = lo
        .iter()
        .fold(f64::INFINITY, |a, &b| if b < a { b } else { a });
    let hi = hi
        .iter()
        .fold(f64::NEG_INFINITY, |a, &b| if b > a { b } else { a });
    (lo, hi)
}

/// A sample far out: its index, value, the column's median and robust standard deviation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Outlier {
    pub sample: usize,
    pub value: f64,
    pub median: f64,
    pub scale: f64,
}

impl ColumnScreen {
    pub fn push(&mut self, c: &[f64]) {
        // The chunk's extremes in independent lanes (no branch per sample); the first
        // sample at an extreme is looked up only when it beats the record's so far, so
        // each is the first sample of the record at its value, as a sample-by-sample scan
        // finds it.
        let (lo, hi) = extremes(c);
        if lo < self.min.0 {
            let k = c.iter().position(|&v| v == lo).unwrap_or(0);
            self.min = (c[k], self.seen + k);
        }
        if hi > self.max.0 {
            let k = c.iter().position(|&v| v == hi).unwrap_or(0);
            self.max = (c[k], self.seen + k);
        }
        // Only the samples at multiples of the stride are visited.
        let end = self.seen + c.len();
        let mut at = self.seen.next_multiple_of(self.stride);
        while at < end {
            if self.kept.len() == KEEP {
                // Keep every other value and double the stride.
                let mut i = 0;
                self.kept.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
            if at.is_multiple_of(self.stride) {
                self.kept.push(c[at - self.seen]);
            }
            at = (at / self.stride + 1) * self.stride;
        }
        self.seen = end;
    }

    /// Whether every value was the same.
    pub fn constant(&self) -> bool {
        self.seen > 0 && self.min.0 == self.max.0
    }

    /// The most extreme sample, when it lies more than [`OUTLIER_RATIO`] robust standard
    /// deviations from the median. Columns whose robust spread is zero (a signal at rest
    /// for most of the record) are not judged.
    pub fn outlier(&self) -> Option<Outlier> {
        if self.kept.is_empty() {
            return None;
        }
        let mut v = self.kept.clone();
        let median = median_of(&mut v);
        v.iter_mut().for_each(|x| *x = (*x - median).abs());
        let mad = 1.4826 * median_of(&mut v);
        // The upper tail of the kept deviations, as a normal distribution's std: a stretch
        // at rest (sensor noise only) for most of the record leaves the MAD at the noise
        // while the motion after it reaches far out; a glitch is one sample, rarely kept
        // and never a percentile of the column.
        let k = ((TAIL_QUANTILE * v.len() as f64) as usize).min(v.len() - 1);
        let (_, q, _) = v.select_nth_unstable_by(k, f64::total_cmp);
        let scale = mad.max(*q / TAIL_Z);
        if scale.is_nan() || scale <= 0.0 {
            return None;
        }
        let (lo, hi) = (median - self.min.0, self.max.0 - median);
        let (value, sample, dist) = if hi >= lo {
            (self.max.0, self.max.1, hi)
        } else {
            (self.min.0, self.min.1, lo)
        };
        (dist > OUTLIER_RATIO * scale).then_some(Outlier {
            sample,
            value,
            median,
            scale,
        })
    }
}

fn median_of(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn screen(values: &[f64], chunk: usize) -> ColumnScreen {
        let mut s = ColumnScreen::default();
        for c in values.chunks(chunk) {
            s.push(c);
        }
        s
    }

    /// The screen's state as a sample-by-sample scan defines it.
    fn scan(values: &[f64]) -> (Vec<f64>, usize, (f64, usize), (f64, usize)) {
        let (mut kept, mut stride) = (Vec::new(), 1);
        let (mut min, mut max) = ((f64::INFINITY, 0), (f64::NEG_INFINITY, 0));
        for (k, &v) in values.iter().enumerate() {
            if v < min.0 {
                min = (v, k);
            }
            if v > max.0 {
                max = (v, k);
            }
            if k.is_multiple_of(stride) {
                if kept.len() == KEEP {
                    kept = kept.iter().copied().step_by(2).collect();
                    stride *= 2;
                }
                if k.is_multiple_of(stride) {
                    kept.push(v);
                }
            }
        }
        (kept, stride, min, max)
    }

    #[test]
    fn any_chunking_gives_the_sample_by_sample_scan() {
        // Ties at both extremes (first occurrence wins), signed zeros, enough samples to
        // halve the kept values twice.
        let x: Vec<f64> = (0..20_000)
            .map(|i| match i % 997 {
                13 => 5.0,
                14 => -5.0,
                500 => -0.0,
                _ => ((i * 7919) % 1000) as f64 / 1000.0 - 0.5,
            })
            .collect();
        let want = scan(&x);
        for chunk in [1, 3, 8, 9, 100, 4096, 20_000] {
            let s = screen(&x, chunk);
            assert_eq!(
                (s.kept.clone(), s.stride, s.min, s.max),
                want,
                "chunks of {chunk}"
            );
            assert_eq!(s.seen, x.len());
        }
        assert_eq!((want.2 .1, want.3 .1), (14, 13));
    }

    #[test]
    fn one_glitch_in_a_long_record_is_found_at_its_sample() {
        let mut x: Vec<f64> = (0..100_000).map(|i| (i as f64 * 0.37).sin()).collect();
        x[77_777] = 1e20;
        let o = screen(&x, 1000).outlier().expect("outlier");
        assert_eq!(o.sample, 77_777);
        assert_eq!(o.value, 1e20);
        assert!(
            o.median.abs() < 0.05 && (o.scale - 1.0).abs() < 0.1,
            "{o:?}"
        );
        // Without it, nothing is flagged, whatever the chunking.
        x[77_777] = 0.5;
        assert_eq!(screen(&x, 7).outlier(), None);
    }

    #[test]
    fn bursts_and_moves_from_rest_are_not_outliers() {
        // Noise at rest with a burst 1000× larger in a tenth of the record.
        let x: Vec<f64> = (0..50_000)
            .map(|i| {
                let noise = ((i * 7919) % 1000) as f64 / 1000.0 - 0.5;
                if (20_000..25_000).contains(&i) {
                    1000.0 * (i as f64 * 0.01).sin()
                } else {
                    noise
                }
            })
            .collect();
        assert_eq!(screen(&x, 4096).outlier(), None);
        // Sensor noise of 1e-7 for the first 60 % of the record, then motion of size one:
        // the MAD is the noise's, the motion 1e7 of it.
        let z: Vec<f64> = (0..50_000)
            .map(|i| {
                let noise = 1e-7 * (((i * 7919) % 1000) as f64 / 1000.0 - 0.5);
                if i < 30_000 {
                    noise
                } else {
                    (i as f64 * 0.013).sin() + noise
                }
            })
            .collect();
        assert_eq!(screen(&z, 4096).outlier(), None);
        // A glitch in the same record is still found.
        let mut g = z.clone();
        g[40_001] = 1e7;
        assert_eq!(screen(&g, 4096).outlier().map(|o| o.sample), Some(40_001));
        // A column at rest but for a few samples has no robust spread and is not judged.
        let mut y = vec![0.0; 10_000];
        y[5] = 1e9;
        let s = screen(&y, 100);
        assert_eq!(s.outlier(), None);
        assert!(!s.constant());
        assert!(screen(&[2.0; 300], 64).constant());
    }
}
