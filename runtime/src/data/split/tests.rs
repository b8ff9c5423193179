use super::*;
use rand::{Rng, SeedableRng};

/// A record of a lightly damped oscillation (ω ≈ 2 rad/s) driven by noise, whose
/// envelope follows `gain(t)`, at Ts = 0.05 s.
fn oscillation(n: usize, seed: u64, gain: impl Fn(f64) -> f64) -> Record {
    let ts = 0.05;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let (w, zeta) = (2.0f64, 0.1);
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let mut col = Vec::with_capacity(n);
    for k in 0..n {
        let f: f64 = rng.random_range(-1.0..1.0) * 3.0;
        // Semi-implicit Euler with 10 sub-steps: plenty for a test signal.
        for _ in 0..10 {
            v += (f - 2.0 * zeta * w * v - w * w * x) * ts / 10.0;
            x += v * ts / 10.0;
        }
        col.push(gain(k as f64 * ts) * x + 0.3);
    }
    Record {
        names: vec!["m.x".into(), "u".into()],
        columns: vec![col, vec![0.0; n]],
        ts,
        t0: 2.0,
    }
}

#[test]
fn steps_of_amplitude_are_found_and_sorted() {
    // Three plateaus, loud – quiet – middle, 200 s each.
    let rec = oscillation(12_000, 1, |t| match t {
        t if t < 200.0 => 8.0,
        t if t < 400.0 => 1.0,
        _ => 3.0,
    });
    let s = split_record(&rec, "r", "m.x", &SplitOptions::default()).unwrap();
    assert!((s.omega - 2.0).abs() < 0.3, "{}", s.omega);
    let starts: Vec<usize> = s.segments.iter().map(|g| g.start).collect();
    // Quietest first: the middle plateau, then the last, then the first.
    assert_eq!(starts[2], 0);
    for (seg, at) in [(&s.segments[0], 4000), (&s.segments[1], 8000)] {
        // Boundaries within one window of the true step.
        assert!(seg.start.abs_diff(at) <= s.window, "{} vs {at}", seg.start);
    }
    assert!(s.segments.windows(2).all(|p| p[0].sigma < p[1].sigma));
    assert_eq!(s.segments.iter().map(|g| g.len).sum::<usize>(), 12_000);
    let recs = s.records(&rec);
    assert_eq!(recs[2].t0, 2.0);
    assert!((recs[0].t0 - (2.0 + s.segments[0].start as f64 * 0.05)).abs() < 1e-9);
    assert_eq!(recs[1].len(), s.segments[1].len);
    let table = s.table();
    assert!(
        table.contains("`m.x`") && table.lines().count() == 5,
        "{table}"
    );
}

#[test]
fn a_ramp_is_cut_into_pieces_of_equal_log_amplitude() {
    // The envelope rises by ×27 over 600 s: three pieces of ×3 each, 200 s apiece.
    let rec = oscillation(12_000, 2, |t| 27f64.powf(t / 600.0));
    let s = split_record(&rec, "r", "m.x", &SplitOptions::default()).unwrap();
    let mut by_time = s.segments.clone();
    by_time.sort_by_key(|g| g.start);
    assert_eq!(by_time, s.segments, "a rising ramp is sorted by time too");
    for (g, at) in s.segments.iter().zip([0, 4000, 8000]) {
        // Random envelopes wander: boundaries within 15 % of a piece.
        assert!(g.start.abs_diff(at) <= 600, "{:?}", s.segments);
    }
    let r = s.segments[2].sigma / s.segments[0].sigma;
    assert!(r > 5.0, "σ ratio {r}");
}

#[test]
fn every_segment_is_long_enough_for_identification() {
    let rec = oscillation(12_000, 3, |t| 27f64.powf(t / 600.0));
    let opts = SplitOptions {
        segments: 8,
        ..Default::default()
    };
    let s = split_record(&rec, "r", "m.x", &opts).unwrap();
    // 80 / ω₀ with ω₀ ≈ 2 rad/s: about 40 s, 800 samples.
    assert!((700..=950).contains(&s.min_len), "{}", s.min_len);
    assert!(s.segments.iter().all(|g| g.len >= s.min_len));
    assert_eq!(s.segments.len(), 8);
}

#[test]
fn errors_name_the_problem() {
    let rec = oscillation(2_000, 4, |_| 1.0);
    let e = split_record(&rec, "r.csv", "m.x", &SplitOptions::default()).unwrap_err();
    let SplitError::TooShort { min_len, .. } = &e else {
        panic!("{e}")
    };
    assert!(e.to_string().contains("too short for 3 segments"), "{e}");
    // 2000 samples hold two segments of ~800.
    assert!(2 * min_len <= 2000);
    let two = SplitOptions {
        segments: 2,
        ..Default::default()
    };
    assert!(split_record(&rec, "r.csv", "m.x", &two).is_ok());
    let e = split_record(&rec, "r.csv", "m.y", &two).unwrap_err();
    assert!(matches!(e, SplitError::UnknownSignal { .. }), "{e}");
    assert!(e.to_string().contains("m.x, u"), "{e}");
    let e = split_record(&rec, "r.csv", "u", &two).unwrap_err();
    assert!(matches!(e, SplitError::NoOscillation { .. }), "{e}");
    let one = SplitOptions {
        segments: 1,
        ..Default::default()
    };
    let e = split_record(&rec, "r.csv", "m.x", &one).unwrap_err();
    assert!(matches!(e, SplitError::TooFewSegments { .. }), "{e}");
    let mut bad = rec.clone();
    bad.columns[0][7] = f64::NAN;
    let e = split_record(&bad, "r.csv", "m.x", &two).unwrap_err();
    assert!(matches!(e, SplitError::NonFinite { sample: 8, .. }), "{e}");
}

#[test]
fn the_default_response_is_the_first_measured_position() {
    let ir = dsl_parser::compile_str(
        "m",
        "model m {\n body a = 1.0\n body b = 1.0\n input u on a\n damper d (ground, a) ~ 1.0\n spring k (ground, b) ~ 1.0\n measure a.v, b.x, u\n}\n",
    );
    let ir = match ir {
        Ok(ir) => ir,
        Err(e) => panic!("{e:?}"),
    };
    assert_eq!(default_response(&ir).as_deref(), Some("b.x"));
}
