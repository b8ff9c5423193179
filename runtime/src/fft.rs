//! The discrete Fourier transform used for spectra (diagnosis' spectral distance, the
//! position spectrum that sets a velocity estimate's bandwidth).

use std::f64::consts::PI;

/// In-place radix-2 FFT of (re, im); the length must be a power of two.
pub(crate) fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * PI / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (s, c) = (ang * k as f64).sin_cos();
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * c - im[b] * s;
                let ti = re[b] * s + im[b] * c;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
            }
        }
        len <<= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_matches_a_direct_transform() {
        let n = 16;
        let x: Vec<f64> = (0..n).map(|k| ((k * k) as f64 * 0.37).sin()).collect();
        let (mut re, mut im) = (x.clone(), vec![0.0; n]);
        fft(&mut re, &mut im);
        for f in 0..n {
            let (mut a, mut b) = (0.0, 0.0);
            for (k, v) in x.iter().enumerate() {
                let ang = -2.0 * PI * (f * k) as f64 / n as f64;
                a += v * ang.cos();
                b += v * ang.sin();
            }
            assert!((a - re[f]).abs() < 1e-12 && (b - im[f]).abs() < 1e-12);
        }
    }
}
