//! The noise floors of the first pass, streamed per measured signal: the white-noise
//! variance ([`NoiseFloor`]) and the band where the signal stands above it ([`BandFloor`]).
//!
//! [`NoiseFloor`] streams the mean square `V_h` of the third difference at strides
//! `h = 1, 2, 3`, `Δ³_h y[k] = y[k] − 3y[k−h] + 3y[k−2h] − y[k−3h]`. White noise contributes
//! `20σ²` at every stride. A sampled continuous signal whose spectrum falls as `ω⁻²` (a
//! first-order form filter, a signal with a white derivative) contributes `∝ h`, one
//! falling as `ω⁻⁴` (a velocity) `∝ h³`, a position `∝ h⁵`. Where the floor is flat
//! (`V₂ ≤ 1.1 V₁`: noise dominates, as for measured positions and velocities) the estimate
//! is `σ² = (2 V₁ − V₂)/20`, which removes a residual `∝ h` part. Otherwise signal content
//! dominates the floor (the input of a low-pass form filter, which the plain `V₁/20` reads
//! as 24 % noise when clean — test `clean_form_filtered_input_reads_as_clean`); then
//! `σ² = (2.5 V₁ − 2 V₂ + 0.5 V₃)/20` removes the `h` and `h³` parts, but it is a small
//! difference of large numbers (5 % noise on such an input read as 3.8 %), so it is
//! reported as uncertain and never used for a correction. Estimates are clamped to
//! `[0, V₁/20]`.

/// `V₂ ≤ FLAT · V₁`: the third-difference floor counts as flat (white noise dominates).
const FLAT: f64 = 1.1;

/// Lanes of the floor's sums: sample `k` of the record adds to lane `k mod LANES`, so the
/// sums are independent chains (no wait on the previous addition) and still do not depend
/// on how the record is cut into chunks.
const LANES: usize = 4;

/// Streaming estimate of the white-noise variance of one signal from its high-frequency
/// floor (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct NoiseFloor {
    /// The last 10 samples, newest first.
    tail: [f64; 10],
    seen: usize,
    /// Per stride, the sums of squared third differences per lane.
    sums: [[f64; LANES]; 3],
    counts: [usize; 3],
}

impl NoiseFloor {
    /// Feed the next samples.
    pub fn push(&mut self, x: &[f64]) {
        // The first nine samples of the chunk reach back into the previous chunk (`tail`);
        // the rest read the chunk itself. Each lane's sum is taken sample by sample in
        // order, so the result does not depend on how the record is cut into chunks.
        let head = x.len().min(9);
        for &v in &x[..head] {
            self.tail.copy_within(0..9, 1);
            self.tail[0] = v;
            let lane = self.seen % LANES;
            self.seen += 1;
            for h in 1..=3 {
                if self.seen > 3 * h {
                    let t = &self.tail;
                    let d = t[0] - 3.0 * t[h] + 3.0 * t[2 * h] - t[3 * h];
                    self.sums[h - 1][lane] += d * d;
                    self.counts[h - 1] += 1;
                }
            }
        }
        if x.len() > head {
            // Ten samples or more have been seen from here on: every difference is taken.
            // The lanes rotated so that `acc[j]` takes samples `head + j, head + j + 4, …`.
            let phase = self.seen % LANES;
            let mut acc = [[0.0; LANES]; 3];
            for (a, s) in acc.iter_mut().zip(&self.sums) {
                for (j, v) in a.iter_mut().enumerate() {
                    *v = s[(phase + j) % LANES];
                }
            }
            let d3 = |i: usize, h: usize| x[i] - 3.0 * x[i - h] + 3.0 * x[i - 2 * h] - x[i - 3 * h];
            let body = &x[head..];
            let full = body.len() / LANES * LANES;
            for q in (0..full).step_by(LANES) {
                // Samples `i0 − 9 ..= i0 + 3` as an array: fixed offsets, no bounds checks,
                // the four lanes side by side.
                let i0 = head + q;
                let w: &[f64; 9 + LANES] = x[i0 - 9..i0 + LANES]
                    .try_into()
                    .expect("invariant: a window of 13 samples");
                for j in 0..LANES {
                    let at = |m: usize| w[9 + j - m];
                    let (d1, d2, d3) = (
                        at(0) - 3.0 * at(1) + 3.0 * at(2) - at(3),
                        at(0) - 3.0 * at(2) + 3.0 * at(4) - at(6),
                        at(0) - 3.0 * at(3) + 3.0 * at(6) - at(9),
                    );
                    acc[0][j] += d1 * d1;
                    acc[1][j] += d2 * d2;
                    acc[2][j] += d3 * d3;
                }
            }
            for j in 0..body.len() - full {
                let i = head + full + j;
                for (h, a) in acc.iter_mut().enumerate() {
                    let d = d3(i, h + 1);
                    a[j] += d * d;
                }
            }
            for (a, s) in acc.iter().zip(&mut self.sums) {
                for (j, v) in a.iter().enumerate() {
                    s[(phase + j) % LANES] = *v;
                }
            }
            let n = x.len() - head;
            self.counts.iter_mut().for_each(|c| *c += n);
            self.seen += n;
            for (k, t) in self.tail.iter_mut().enumerate() {
                *t = x[x.len() - 1 - k];
            }
        }
    }

    /// A floor with no sums that continues after the samples `before` (oldest first, at
    /// least nine, the last being sample `seen − 1` of the record): its sums over the next
    /// samples are those [`NoiseFloor::push`] adds after `before`, so pieces of a record
    /// can be taken apart and joined with [`NoiseFloor::absorb`].
    pub fn resume(before: &[f64], seen: usize) -> Self {
        assert!(
            before.len() >= 9 && seen >= before.len(),
            "nine samples before"
        );
        let mut tail = [0.0; 10];
        for (t, v) in tail.iter_mut().zip(before.iter().rev()) {
            *t = *v;
        }
        NoiseFloor {
            tail,
            seen,
            ..Default::default()
        }
    }

    /// The same floor with its sums and counts set to zero (to take the next piece apart).
    pub fn emptied(&self) -> Self {
        NoiseFloor {
            tail: self.tail,
            seen: self.seen,
            ..Default::default()
        }
    }

    /// Add the sums of the piece that `part` took after this floor's samples (from
    /// [`NoiseFloor::resume`] or [`NoiseFloor::emptied`]), lane by lane. Pieces joined in
    /// order give the sums of one [`NoiseFloor::push`] over them to rounding (the additions
    /// are grouped by piece).
    pub fn absorb(&mut self, part: &NoiseFloor) {
        for (s, p) in self.sums.iter_mut().zip(&part.sums) {
            for (a, b) in s.iter_mut().zip(p) {
                *a += b;
            }
        }
        for (c, p) in self.counts.iter_mut().zip(&part.counts) {
            *c += p;
        }
        self.tail = part.tail;
        self.seen = part.seen;
    }

    /// Samples seen.
    pub fn seen(&self) -> usize {
        self.seen
    }

    /// Mean square of the third difference at stride `h` (1, 2 or 3).
    pub fn mean_square(&self, h: usize) -> f64 {
        let l = &self.sums[h - 1];
        ((l[0] + l[1]) + (l[2] + l[3])) / self.counts[h - 1].max(1) as f64
    }

    /// Whether the floor is flat (`V₂ ≤ 1.1 V₁`): white noise dominates the third
    /// difference and the estimate is sharp. Where signal content dominates (a form-filtered
    /// input) the estimate is a small difference of large numbers: reported, not used.
    pub fn flat(&self) -> bool {
        self.seen >= 10 && self.mean_square(2) <= FLAT * self.mean_square(1)
    }

    /// The estimated white-noise variance (0 for fewer than 10 samples).
    pub fn variance(&self) -> f64 {
        if self.seen < 10 {
            return 0.0;
        }
        let (v1, v2, v3) = (
            self.mean_square(1),
            self.mean_square(2),
            self.mean_square(3),
        );
        let est = if v2 <= FLAT * v1 {
            // A flat floor: noise dominates; remove a residual `∝ h` slope only.
            (2.0 * v1 - v2) / 20.0
        } else {
            (2.5 * v1 - 2.0 * v2 + 0.5 * v3) / 20.0
        };
        if est.is_finite() {
            est.clamp(0.0, v1 / 20.0)
        } else {
            0.0
        }
    }
}

/// Octave strides of [`BandFloor`]: `h = 1, 2, 4, …, 2^(OCTAVES − 1)`.
pub const OCTAVES: usize = 10;

/// Samples [`BandFloor`] keeps from one chunk to the next: the reach of its widest third
/// difference.
const BAND_REACH: usize = 3 << (OCTAVES - 1);

/// Streaming mean squares of the third difference of one signal at octave strides
/// `h = 2ᵏ`, from which the band where the signal stands above its white-noise floor is
/// read ([`BandFloor::info_bandwidth`]).
///
/// At stride `h` the third difference weighs the spectrum with `(2 sin(ωhTₛ/2))⁶`, which
/// peaks at `ω = π/(h Tₛ)`; white noise of variance `σ²` gives `20 σ²` at every stride,
/// spread evenly over `0 … π/Tₛ`, so the noise within the octave probed by stride `h` is
/// about `20 σ² / h`. A signal whose spectrum falls as a position's does (`ω⁻⁴` and
/// faster) gives a part `S_h = V_h − 20 σ²` that grows with `h`. The signal stands above
/// its floor at `π/(h Tₛ)` where `h S_h ≥ 20 σ²`.
#[derive(Clone, Debug)]
pub struct BandFloor {
    /// The last [`BAND_REACH`] samples, oldest first (fewer at the start of the record).
    tail: Vec<f64>,
    /// Samples taken so far: the record index of the next one.
    seen: usize,
    /// Per stride, the sums of squared third differences in [`BAND_LANES`] lanes, lane `j`
    /// taking the samples whose record index is `j` modulo [`BAND_LANES`], each in order: the
    /// same additions however the record is cut into chunks, without one chain of
    /// dependent additions through the whole record.
    lanes: [[f64; BAND_LANES]; OCTAVES],
    counts: [usize; OCTAVES],
}

/// Lanes of [`BandFloor`]'s sums: as [`LANES`], twice as many, since ten strides of
/// third differences make the band the first pass's largest share.
const BAND_LANES: usize = 8;

impl Default for BandFloor {
    fn default() -> Self {
        BandFloor {
            tail: Vec::new(),
            seen: 0,
            lanes: [[0.0; BAND_LANES]; OCTAVES],
            counts: [0; OCTAVES],
        }
    }
}

impl BandFloor {
    /// Feed the next samples.
    pub fn push(&mut self, x: &[f64]) {
        let mut all = std::mem::take(&mut self.tail);
        let start = all.len();
        all.extend_from_slice(x);
        // Record index of `all[0]`.
        let origin = self.seen - start;
        for (k, (lane, count)) in self.lanes.iter_mut().zip(&mut self.counts).enumerate() {
            let h = 1usize << k;
            let first = start.max(3 * h);
            if first < all.len() {
                third_difference_squares(&all, h, first, origin, lane);
                *count += all.len() - first;
            }
        }
        self.seen += x.len();
        let keep = all.len().min(BAND_REACH);
        all.drain(..all.len() - keep);
        self.tail = all;
    }

    /// Mean square of the third difference at stride `2ᵏ` (`None`: no difference taken).
    fn mean_square(&self, k: usize) -> Option<f64> {
        let l = &self.lanes[k];
        let sum = ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
        (self.counts[k] > 0).then(|| sum / self.counts[k] as f64)
    }

    /// The highest angular frequency (rad/s, sample interval `ts`) at which the signal's
    /// spectrum stands above the white-noise floor of variance `noise_var`: `π/(h Tₛ)` at
    /// the smallest stride `h` with `h (V_h − 20 σ²) ≥ 20 σ²`, interpolated between
    /// octaves on a log scale. `None` where the noise is zero (no floor to meet: the whole
    /// band carries information) or no stride reaches it (the record holds no band above
    /// the floor that these strides resolve).
    pub fn info_bandwidth(&self, noise_var: f64, ts: f64) -> Option<f64> {
        let floor = 20.0 * noise_var;
        if !(floor > 0.0 && floor.is_finite() && ts > 0.0) {
            return None;
        }
        // log of the ratio `h S_h / (20 σ²)` per octave (`None` once too few samples).
        let ratio = |k: usize| {
            self.mean_square(k)
                .map(|v| ((1usize << k) as f64 * (v - floor).max(0.0) / floor).max(1e-300))
        };
        let mut prev: Option<(usize, f64)> = None;
        for k in 0..OCTAVES {
            let r = ratio(k)?;
            if r >= 1.0 {
                let kk = match prev {
                    // Interpolate the crossing of 1 between octaves k − 1 and k in log ratio.
                    Some((j, rp)) if rp > 0.0 => {
                        let (a, b) = (rp.ln(), r.ln());
                        j as f64 + if b > a { -a / (b - a) } else { 1.0 }
                    }
                    _ => k as f64,
                };
                return Some(std::f64::consts::PI / (kk.exp2() * ts));
            }
            prev = Some((k, r));
        }
        None
    }
}

/// Adds `d_i²`, `d_i = x_i − 3 x_{i−h} + 3 x_{i−2h} − x_{i−3h}`, for `i = first …`, to
/// `lane[(origin + i) mod BAND_LANES]`, in order within each lane.
///
/// The vector width is the processor's (AVX-512 or AVX where it has them); the additions
/// are the same, in the same order, so every path gives the same sums bit for bit.
fn third_difference_squares(
    x: &[f64],
    h: usize,
    first: usize,
    origin: usize,
    lane: &mut [f64; BAND_LANES],
) {
    #[cfg(target_arch = "x86_64")]
    {
        use crate::ident::filter::{has_avx512, has_avx_fma};
        if has_avx512() {
            // SAFETY: the processor has AVX-512F.
            return unsafe { squares_avx512(x, h, first, origin, lane) };
        }
        if has_avx_fma() {
            // SAFETY: the processor has AVX.
            return unsafe { squares_avx(x, h, first, origin, lane) };
        }
    }
    squares(x, h, first, origin, lane)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn squares_avx512(x: &[f64], h: usize, first: usize, origin: usize, lane: &mut [f64; BAND_LANES]) {
    squares(x, h, first, origin, lane)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn squares_avx(x: &[f64], h: usize, first: usize, origin: usize, lane: &mut [f64; BAND_LANES]) {
    squares(x, h, first, origin, lane)
}

/// [`third_difference_squares`], inlined into each vector path.
#[inline(always)]
fn squares(x: &[f64], h: usize, first: usize, origin: usize, lane: &mut [f64; BAND_LANES]) {
    let d = |i: usize| x[i] - 3.0 * x[i - h] + 3.0 * x[i - 2 * h] - x[i - 3 * h];
    let mut i = first;
    // Up to the first sample of lane 0, one by one.
    while i < x.len() && !(origin + i).is_multiple_of(BAND_LANES) {
        lane[(origin + i) % BAND_LANES] += d(i).powi(2);
        i += 1;
    }
    // Whole rounds of the lanes: four shifted slices, one running sum per lane.
    let whole = (x.len() - i) / BAND_LANES * BAND_LANES;
    let (a, b, c, e) = (
        &x[i..i + whole],
        &x[i - h..i - h + whole],
        &x[i - 2 * h..i - 2 * h + whole],
        &x[i - 3 * h..i - 3 * h + whole],
    );
    let mut acc = *lane;
    for (((a, b), c), e) in a
        .chunks_exact(BAND_LANES)
        .zip(b.chunks_exact(BAND_LANES))
        .zip(c.chunks_exact(BAND_LANES))
        .zip(e.chunks_exact(BAND_LANES))
    {
        for j in 0..BAND_LANES {
            let v = a[j] - 3.0 * b[j] + 3.0 * c[j] - e[j];
            acc[j] += v * v;
        }
    }
    *lane = acc;
    i += whole;
    for i in i..x.len() {
        lane[(origin + i) % BAND_LANES] += d(i).powi(2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slow sine with white noise of `sd`, 20 000 samples at 1 kHz (uniform noise from
    /// a fixed generator, scaled to `sd`).
    fn noisy_sine(sd: f64) -> Vec<f64> {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        (0..20_000)
            .map(|k| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                (20.0 * k as f64 * 1e-3).sin() + sd * u * 12f64.sqrt()
            })
            .collect()
    }

    #[test]
    fn band_sums_are_those_of_the_portable_path_bit_for_bit() {
        let x = noisy_sine(1e-3);
        for (h, first, origin) in [(1, 3, 0), (4, 12, 5), (64, 200, 3), (512, 1536, 7)] {
            let (mut fast, mut portable) = ([0.5; BAND_LANES], [0.5; BAND_LANES]);
            third_difference_squares(&x[..x.len() - 3], h, first, origin, &mut fast);
            squares(&x[..x.len() - 3], h, first, origin, &mut portable);
            assert_eq!(
                fast.map(f64::to_bits),
                portable.map(f64::to_bits),
                "stride {h}"
            );
        }
    }

    #[test]
    fn band_floor_falls_with_the_noise_and_ignores_chunks() {
        let width = |sd: f64, chunk: usize| {
            let x = noisy_sine(sd);
            let mut b = BandFloor::default();
            x.chunks(chunk).for_each(|c| b.push(c));
            b.info_bandwidth(sd * sd, 1e-3)
        };
        let (quiet, loud) = (width(1e-4, 20_000), width(1e-2, 20_000));
        let (quiet, loud) = (quiet.expect("a floor"), loud.expect("a floor"));
        assert!(loud < quiet, "{loud} {quiet}");
        // Within the strides' reach and below the Nyquist frequency.
        assert!(loud > std::f64::consts::PI / 1e-3 / 512.0 && quiet <= std::f64::consts::PI / 1e-3);
        assert_eq!(width(1e-2, 777), Some(loud));
        // No noise: no floor to meet.
        assert_eq!(width(1e-2, 20_000).map(|_| 0), Some(0));
        let mut b = BandFloor::default();
        b.push(&noisy_sine(0.0));
        assert_eq!(b.info_bandwidth(0.0, 1e-3), None);
    }
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    fn floor_of(x: &[f64], chunk: usize) -> NoiseFloor {
        let mut f = NoiseFloor::default();
        for c in x.chunks(chunk) {
            f.push(c);
        }
        f
    }

    #[test]
    fn white_noise_variance_is_recovered_across_chunks() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let x: Vec<f64> = (0..200_000)
            .map(|_| 0.3 * rng.sample::<f64, _>(StandardNormal))
            .collect();
        let one = floor_of(&x, x.len());
        for chunk in [1, 5, 9, 10, 11, 777] {
            let many = floor_of(&x, chunk);
            for h in 1..=3 {
                assert_eq!(
                    one.mean_square(h).to_bits(),
                    many.mean_square(h).to_bits(),
                    "chunks of {chunk}, stride {h}"
                );
            }
            assert_eq!(one.variance().to_bits(), many.variance().to_bits());
        }
        // Sample by sample, as the definition reads: sample `i` adds to lane `i mod 4`.
        let mut sums = [[0.0; LANES]; 3];
        for i in 0..x.len() {
            for h in 1..=3 {
                if i >= 3 * h {
                    let d = x[i] - 3.0 * x[i - h] + 3.0 * x[i - 2 * h] - x[i - 3 * h];
                    sums[h - 1][i % LANES] += d * d;
                }
            }
        }
        for h in 1..=3 {
            let l = &sums[h - 1];
            let want = ((l[0] + l[1]) + (l[2] + l[3])) / (x.len() - 3 * h) as f64;
            assert_eq!(one.mean_square(h).to_bits(), want.to_bits(), "stride {h}");
        }
        let sd = one.variance().sqrt();
        assert!(one.flat());
        // Measured: 0.2959 (−1.4 %).
        assert!((sd / 0.3 - 1.0).abs() < 0.03, "{sd}");
        assert!((one.mean_square(1) / (20.0 * 0.09) - 1.0).abs() < 0.02);
    }

    /// An exactly sampled Ornstein–Uhlenbeck process (the low-pass form filter of the
    /// simulator, corner `lam`), unit variance.
    fn ou(n: usize, lam: f64, ts: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let phi = (-lam * ts).exp();
        let q = (1.0 - phi * phi).sqrt();
        let mut u = rng.sample::<f64, _>(StandardNormal);
        (0..n)
            .map(|_| {
                u = phi * u + q * rng.sample::<f64, _>(StandardNormal);
                u
            })
            .collect()
    }

    #[test]
    fn clean_form_filtered_input_reads_as_clean() {
        // Corner 10 rad/s at Ts = 0.01 s: the plain third difference reads this as noise
        // of about 24 % of the std; the three-stride combination must not.
        let u = ou(200_000, 10.0, 0.01, 3);
        let f = floor_of(&u, 8192);
        let plain = (f.mean_square(1) / 20.0).sqrt();
        let est = f.variance().sqrt();
        eprintln!("OU input: plain {plain:.4}, three-stride {est:.4} (std 1)");
        assert!(plain > 0.15, "{plain}");
        assert!(!f.flat());
        assert!(est < 0.01, "{est}");
    }

    #[test]
    fn clean_smooth_signal_reads_as_clean() {
        let ts = 0.01;
        let x: Vec<f64> = (0..100_000)
            .map(|k| {
                let t = k as f64 * ts;
                (1.9 * t).sin() + 0.4 * (7.3 * t + 1.0).sin() + 0.1 * (31.0 * t).cos()
            })
            .collect();
        let est = floor_of(&x, 1000).variance().sqrt();
        // Measured: 4.7e-4 of an amplitude of 1.
        assert!(est < 1e-3, "{est}");
    }

    #[test]
    fn noise_on_a_smooth_signal_is_measured() {
        // A twice low-pass filtered OU process (position-like, corner 3 rad/s) with noise.
        let u = ou(200_000, 10.0, 0.01, 8);
        let (mut a, mut b) = (0.0, 0.0);
        let phi = (-3.0f64 * 0.01).exp();
        let x: Vec<f64> = u
            .iter()
            .map(|v| {
                a = phi * a + (1.0 - phi) * v;
                b = phi * b + (1.0 - phi) * a;
                b
            })
            .collect();
        let sd = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        for frac in [0.0, 0.05, 0.1] {
            let y: Vec<f64> = x
                .iter()
                .map(|v| v + frac * sd * rng.sample::<f64, _>(StandardNormal))
                .collect();
            let est = floor_of(&y, 4096).variance().sqrt() / sd;
            eprintln!("smooth + {frac} white: {est:.5}");
            assert!((est - frac).abs() < 0.02 * frac + 1e-3, "{frac}: {est}");
        }
    }
}
