//! Gap metrics between a simulated and a measured response (definitions in
//! `docs/diagnosis.md`): free-run NRMSE, relative error of the standard deviation, and a
//! Welch power-spectrum gap.

/// Root mean square of `a − b` divided by the standard deviation of `b`.
pub fn nrmse(sim: &[f64], meas: &[f64]) -> f64 {
    let n = sim.len().min(meas.len());
    if n == 0 {
        return f64::NAN;
    }
    let e2: f64 = sim
        .iter()
        .zip(meas)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / n as f64;
    let s = std_dev(&meas[..n]);
    if s > 0.0 {
        e2.sqrt() / s
    } else {
        f64::NAN
    }
}

pub use crate::describe::std_dev;

/// One-sided Welch power spectral density (Hann window, 50 % overlap) at bins
/// `k / (nseg · ts)`, `k = 0 … nseg/2`. Returns (frequencies in Hz, PSD).
pub fn welch(x: &[f64], ts: f64, nseg_max: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nseg = 16usize;
    while nseg * 2 <= nseg_max && nseg * 2 <= x.len() {
        nseg *= 2;
    }
    welch_with(x, ts, nseg)
}

/// Most samples of a segment of [`welch_fine`]: a 65536-bin spectrum.
const FINE_MAX: usize = 1 << 17;

/// The Welch PSD for a figure, with the finest resolution that still averages: segments of
/// half the record (three of them, half overlapping; even length, at most [`FINE_MAX`]),
/// so that a 25 s record resolves 0.08 Hz instead of the 0.24 Hz of the gap's 4096-sample
/// segments at 1 kHz.
pub fn welch_fine(x: &[f64], ts: f64) -> (Vec<f64>, Vec<f64>) {
    let nseg = (x.len() / 2 / 2 * 2).clamp(16, FINE_MAX);
    if nseg > x.len() {
        return welch(x, ts, 4096);
    }
    welch_with(x, ts, nseg)
}

/// Welch PSD of `x` with Hann segments of `nseg` samples, half overlapping.
fn welch_with(x: &[f64], ts: f64, nseg: usize) -> (Vec<f64>, Vec<f64>) {
    let nb = nseg / 2 + 1;
    let mut psd = vec![0.0; nb];
    let win: Vec<f64> = (0..nseg)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / nseg as f64).cos())
        .collect();
    let wsum: f64 = win.iter().map(|w| w * w).sum();
    let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
    let mut power = crate::fft::SegmentPower::new(nseg);
    let mut count = 0;
    let mut start = 0;
    while start + nseg <= x.len() {
        for (i, v) in power.input_mut().iter_mut().enumerate() {
            *v = (x[start + i] - mean) * win[i];
        }
        // One-sided: the bins between DC and Nyquist stand for two.
        power.add_power(
            &mut psd,
            |k| if k == 0 || k == nseg / 2 { 1.0 } else { 2.0 },
        );
        count += 1;
        start += nseg / 2;
    }
    let scale = ts / (wsum * count.max(1) as f64);
    psd.iter_mut().for_each(|p| *p *= scale);
    let freqs = (0..nb).map(|k| k as f64 / (nseg as f64 * ts)).collect();
    (freqs, psd)
}

/// Mean |log10(P_sim / P_meas)| over the bins (DC excluded) up to the frequency below
/// which the measured spectrum holds 99 % of its power.
pub fn psd_gap(p_sim: &[f64], p_meas: &[f64]) -> f64 {
    let total: f64 = p_meas.iter().skip(1).sum();
    if total <= 0.0 {
        return f64::NAN;
    }
    let mut acc = 0.0;
    let mut last = p_meas.len() - 1;
    for (k, p) in p_meas.iter().enumerate().skip(1) {
        acc += p;
        if acc >= 0.99 * total {
            last = k;
            break;
        }
    }
    let floor = 1e-12 * p_meas.iter().cloned().fold(0.0, f64::max);
    let n = last.max(1);
    (1..=n)
        .map(|k| ((p_sim[k] + floor) / (p_meas[k] + floor)).log10().abs())
        .sum::<f64>()
        / n as f64
}

/// The PSD gap `d` (mean |log10| power ratio) as an amplitude error in %:
/// `100 · (10^(d/2) − 1)`, the typical factor by which the simulated amplitude spectrum
/// misses the measured one (d = 0.1 is 12.2 %).
pub fn spectral_error(psd_gap: f64) -> f64 {
    100.0 * (10f64.powf(0.5 * psd_gap) - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welch_of_a_sine_peaks_at_its_frequency() {
        let ts = 0.01;
        let x: Vec<f64> = (0..8192)
            .map(|i| (2.0 * std::f64::consts::PI * 5.0 * i as f64 * ts).sin())
            .collect();
        let (f, p) = welch(&x, ts, 1024);
        let k = (0..p.len()).max_by(|a, b| p[*a].total_cmp(&p[*b])).unwrap();
        assert!((f[k] - 5.0).abs() < 0.1, "peak at {}", f[k]);
        // Parseval: the PSD integrates to the variance (0.5).
        let df = f[1] - f[0];
        let var: f64 = p.iter().sum::<f64>() * df;
        assert!((var - 0.5).abs() < 0.02, "variance {var}");
        assert!(psd_gap(&p, &p) < 1e-12);
    }

    #[test]
    fn the_report_spectrum_resolves_the_slow_band_of_a_short_record() {
        // 25 s at 1 kHz: the gap's 4096-sample segments give 0.24 Hz bins (4 below 1 Hz),
        // the report's half-record segments 0.08 Hz (12 below 1 Hz).
        let ts = 1e-3;
        let x: Vec<f64> = (0..25_001)
            .map(|i| (2.0 * std::f64::consts::PI * 0.162 * i as f64 * ts).sin())
            .collect();
        let below = |f: &[f64]| f.iter().skip(1).filter(|&&f| f < 1.0).count();
        let (coarse, _) = welch(&x, ts, 4096);
        let (fine, p) = welch_fine(&x, ts);
        assert_eq!(below(&coarse), 4);
        assert_eq!(below(&fine), 12);
        let k = (0..p.len()).max_by(|a, b| p[*a].total_cmp(&p[*b])).unwrap();
        assert!((fine[k] - 0.162).abs() < 0.05, "peak at {}", fine[k]);
        // Parseval holds as for the coarse estimate.
        let var: f64 = p.iter().sum::<f64>() * (fine[1] - fine[0]);
        assert!((var - 0.5).abs() < 0.05, "variance {var}");
    }

    #[test]
    fn nrmse_is_zero_for_identical_signals() {
        let x: Vec<f64> = (0..100).map(|i| (i as f64).sin()).collect();
        assert_eq!(nrmse(&x, &x), 0.0);
        let y: Vec<f64> = x.iter().map(|v| 0.0 * v).collect();
        assert!((nrmse(&y, &x) - 1.0).abs() < 0.05);
    }
}
