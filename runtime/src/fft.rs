//! Power spectra of real segments (diagnosis' spectral distance, the position spectrum that
//! sets a velocity estimate's bandwidth), with the real-input FFT of `realfft`.

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use std::sync::Arc;

/// `|X_k|²`, `k = 0 … n/2`, of real segments of one length `n`, with the plan and buffers
/// allocated once.
pub(crate) struct SegmentPower {
    fft: Arc<dyn RealToComplex<f64>>,
    input: Vec<f64>,
    output: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

impl SegmentPower {
    pub fn new(n: usize) -> SegmentPower {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        SegmentPower {
            input: fft.make_input_vec(),
            output: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
        }
    }

    /// The segment to transform; fill it before [`Self::add_power`].
    pub fn input_mut(&mut self) -> &mut [f64] {
        &mut self.input
    }

    /// Transform the segment (the transform overwrites it) and add `weight(k) · |X_k|²` to
    /// `acc[k]` for every bin `k = 0 … n/2` that `acc` holds.
    pub fn add_power(&mut self, acc: &mut [f64], weight: impl Fn(usize) -> f64) {
        // Lengths come from the plan itself, so the transform cannot refuse them.
        self.fft
            .process_with_scratch(&mut self.input, &mut self.output, &mut self.scratch)
            .expect("invariant: buffers made by the plan");
        for (k, (a, x)) in acc.iter_mut().zip(&self.output).enumerate() {
            *a += weight(k) * x.norm_sqr();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn power_matches_a_direct_transform() {
        for n in [16, 24] {
            let x: Vec<f64> = (0..n).map(|k| ((k * k) as f64 * 0.37).sin()).collect();
            let mut sp = SegmentPower::new(n);
            sp.input_mut().copy_from_slice(&x);
            let mut acc = vec![0.0; n / 2 + 1];
            sp.add_power(&mut acc, |_| 1.0);
            for (f, a) in acc.iter().enumerate() {
                let (mut re, mut im) = (0.0, 0.0);
                for (k, v) in x.iter().enumerate() {
                    let ang = -2.0 * PI * (f * k) as f64 / n as f64;
                    re += v * ang.cos();
                    im += v * ang.sin();
                }
                assert!((re * re + im * im - a).abs() < 1e-11, "{n} {f}");
            }
        }
    }
}
