//! The force channel: where a model is driven by a recorded force, its equation residual
//! (the force the model needs for the measured motion, minus the recorded force) in
//! newtons. On a position-controlled record the measured position and the free run of a
//! model driven by the recorded force may agree to micrometres while the model misses the
//! force by tens of newtons: the force is what differs, and this gap says by how much.
//!
//! Per level: the positions and the recorded force are low-passed without phase (a
//! second-order Butterworth filter run forwards and backwards, corner [`band_hz`]); the
//! velocities and accelerations are central differences of the filtered positions; every
//! equation's terms are evaluated on them with the model's values. Rests (a body's speed at
//! most [`REST_FRACTION`] of its RMS speed for at least [`MIN_REST`]) are left out: there a
//! friction force lies anywhere within its bound. So are the filter's edges.

use super::types::ForceGapValue;
use crate::describe::std_dev;
use crate::ident::rests::{MIN_REST, REST_FRACTION};
use crate::record::Record;
use crate::tape::{Tape, TapeScratch};
use dynid_ir::ir::{Basis, ModelIr, SignalKind};

/// The upper corner of the force channel, in Hz: a twentieth of the sampling rate, at most
/// 50 Hz (a 1 µm encoder at 1 kHz adds about 0.2 N of quantisation to a 50 kg body's force
/// at 50 Hz; the double derivative grows with the corner's 2.5th power).
pub fn band_hz(ts: f64) -> f64 {
    (0.05 / ts).min(50.0)
}

/// The recorded forces of `ir` whose channel can be scored: inputs that no control law
/// computes, measured, on a model whose every body has a measured position. `(input, body)`
/// names.
pub fn channels(ir: &ModelIr) -> Vec<(String, String)> {
    let positions_measured = ir.bodies.iter().enumerate().all(|(b, _)| {
        ir.signals
            .iter()
            .any(|s| s.measured && matches!(s.kind, SignalKind::Position(p) if p.index() == b))
    });
    if !positions_measured {
        return Vec::new();
    }
    ir.inputs
        .iter()
        .enumerate()
        .filter(|(i, inp)| {
            ir.control_of(dynid_ir::ir::InputId(*i as u32)).is_none()
                && ir.signals.iter().any(|s| s.measured && s.name == inp.name)
        })
        .map(|(_, inp)| (inp.name.clone(), ir.bodies[inp.body.index()].name.clone()))
        .collect()
}

/// Zero-phase low-pass of `x` (in place): a second-order Butterworth section at `fc` Hz,
/// forwards then backwards, each pass starting at steady state on its first sample.
fn filtfilt(x: &mut [f64], fc: f64, ts: f64) {
    let k = (std::f64::consts::PI * fc * ts).tan();
    let norm = 1.0 / (1.0 + std::f64::consts::SQRT_2 * k + k * k);
    let b0 = k * k * norm;
    let (b1, b2) = (2.0 * b0, b0);
    let a1 = 2.0 * (k * k - 1.0) * norm;
    let a2 = (1.0 - std::f64::consts::SQRT_2 * k + k * k) * norm;
    let pass = |x: &mut dyn Iterator<Item = &mut f64>| {
        let mut first = true;
        let (mut z1, mut z2) = (0.0, 0.0);
        for v in x {
            let u = *v;
            if first {
                z2 = (b2 - a2) * u;
                z1 = u - b0 * u;
                first = false;
            }
            let y = b0 * u + z1;
            z1 = b1 * u - a1 * y + z2;
            z2 = b2 * u - a2 * y;
            *v = y;
        }
    };
    pass(&mut x.iter_mut());
    pass(&mut x.iter_mut().rev());
}

/// Central differences of `x` (first and second), one-sided at the ends.
fn derivatives(x: &[f64], ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut v = vec![0.0; n];
    let mut a = vec![0.0; n];
    for k in 1..n.saturating_sub(1) {
        v[k] = (x[k + 1] - x[k - 1]) / (2.0 * ts);
        a[k] = (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (ts * ts);
    }
    if n >= 3 {
        v[0] = v[1];
        v[n - 1] = v[n - 2];
        a[0] = a[1];
        a[n - 1] = a[n - 2];
    }
    (v, a)
}

/// The filtered signals of one level, shared by every model scored on it: one column per
/// signal of the IR (empty where the tape needs none), and the samples kept (in motion,
/// away from the filter's edges).
pub(super) struct Channel {
    columns: Vec<Vec<f64>>,
    /// Accelerations per body.
    accel: Vec<Vec<f64>>,
    keep: Vec<bool>,
}

/// The filtered level `rec` for the force channel of `ir`; `None` when a column is missing
/// or the record is too short for the filter.
pub(super) fn channel(ir: &ModelIr, rec: &Record) -> Option<Channel> {
    let n = rec.len();
    let ts = rec.ts;
    let fc = band_hz(ts);
    let edge = (3.0 / (fc * ts)).ceil() as usize;
    if n < 4 * edge + 3 {
        return None;
    }
    let filtered = |name: &str| -> Option<Vec<f64>> {
        let mut c = rec.column(name)?.to_vec();
        filtfilt(&mut c, fc, ts);
        Some(c)
    };
    let mut columns = vec![Vec::new(); ir.signals.len()];
    let mut accel = vec![Vec::new(); ir.bodies.len()];
    let mut keep = vec![true; n];
    for k in (0..edge).chain(n - edge..n) {
        keep[k] = false;
    }
    for (b, body) in ir.bodies.iter().enumerate() {
        let x = filtered(&format!("{}.x", body.name))?;
        let (v, a) = derivatives(&x, ts);
        // Rests of this body: a speed of at most REST_FRACTION of the RMS speed for at least
        // MIN_REST.
        let rms = (v.iter().map(|s| s * s).sum::<f64>() / n as f64).sqrt();
        let still: Vec<bool> = v.iter().map(|s| s.abs() <= REST_FRACTION * rms).collect();
        let min_run = (MIN_REST / ts).round() as usize;
        let mut k = 0;
        while k < n {
            if !still[k] {
                k += 1;
                continue;
            }
            let start = k;
            while k < n && still[k] {
                k += 1;
            }
            if k - start >= min_run {
                keep[start..k].iter_mut().for_each(|s| *s = false);
            }
        }
        for (i, s) in ir.signals.iter().enumerate() {
            match s.kind {
                SignalKind::Position(p) if p.index() == b => columns[i] = x.clone(),
                SignalKind::Velocity(p) if p.index() == b => columns[i] = v.clone(),
                _ => {}
            }
        }
        accel[b] = a;
    }
    for (i, s) in ir.signals.iter().enumerate() {
        if matches!(s.kind, SignalKind::Input(_) | SignalKind::Reference(_)) {
            if let Some(c) = filtered(&s.name) {
                columns[i] = c;
            }
        }
    }
    Some(Channel {
        columns,
        accel,
        keep,
    })
}

/// The force-channel gap of `ir` (its nominal values) for the input `input` acting on
/// `body`, on one level's [`Channel`]: RMS of the equation residual of `body` over the kept
/// samples, and that as % of the std of the recorded force there. `None` when the model
/// cannot be evaluated, nothing is kept, or the force does not vary.
pub(super) fn gap(ir: &ModelIr, ch: &Channel, input: &str, body: &str) -> Option<(f64, f64)> {
    if ch.columns.len() != ir.signals.len() {
        return None;
    }
    let values = crate::sim::parameter_values(ir).ok()?;
    let b = ir.bodies.iter().position(|x| x.name == body)?;
    let eq = ir.equations.iter().find(|e| e.body.index() == b)?;
    let u = ch.columns[ir.signals.iter().position(|s| s.name == input)?].as_slice();
    let n = ch.keep.len();
    let roots: Vec<_> = eq
        .terms
        .iter()
        .filter_map(|t| match t.basis {
            Basis::Expr(e) => Some(e),
            Basis::Deriv { .. } => None,
        })
        .collect();
    let tape = Tape::compile(ir, &roots);
    // Every signal the tape reads has its column (a measured acceleration column is never
    // read by a force).
    let cols: Vec<&[f64]> = ch.columns.iter().map(Vec::as_slice).collect();
    if ir.signals.iter().enumerate().any(|(i, _)| {
        roots
            .iter()
            .any(|&r| ir.expr_signals(r).iter().any(|s| s.index() == i))
            && cols[i].len() < n
    }) {
        return None;
    }
    let mut out = vec![0.0; roots.len() * n];
    tape.eval_block(&cols, n, &mut out, &mut TapeScratch::default());
    let coef = |c: dynid_ir::ir::Coef| c.scale * c.param.map_or(1.0, |p| values[p.index()]);
    let velocity = |body: usize| -> Option<&[f64]> {
        let i = ir
            .signals
            .iter()
            .position(|s| matches!(s.kind, SignalKind::Velocity(p) if p.index() == body))?;
        Some(ch.columns[i].as_slice()).filter(|c| c.len() == n)
    };
    let mut residual = vec![0.0; n];
    let mut root = 0;
    for t in &eq.terms {
        let c = coef(t.coef);
        let column: &[f64] = match t.basis {
            Basis::Expr(_) => {
                root += 1;
                &out[(root - 1) * n..root * n]
            }
            Basis::Deriv { body, order: 1 } => velocity(body.index())?,
            Basis::Deriv { body, order: 2 } => ch.accel[body.index()].as_slice(),
            Basis::Deriv { .. } => return None,
        };
        for (r, x) in residual.iter_mut().zip(column) {
            *r += c * x;
        }
    }
    let kept: Vec<f64> = residual
        .iter()
        .zip(&ch.keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| *r)
        .collect();
    let force: Vec<f64> = u
        .iter()
        .zip(&ch.keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| *r)
        .collect();
    if kept.len() < 3 {
        return None;
    }
    let rms = (kept.iter().map(|r| r * r).sum::<f64>() / kept.len() as f64).sqrt();
    let spread = std_dev(&force);
    (rms.is_finite() && spread.is_finite() && spread > 0.0).then(|| (rms, 100.0 * rms / spread))
}

/// Means over the levels of per-level `(rms, %)` pairs; `None` when no level has one.
pub(super) fn mean(v: &[Option<(f64, f64)>]) -> Option<ForceGapValue> {
    let got: Vec<(f64, f64)> = v.iter().flatten().copied().collect();
    let n = got.len() as f64;
    (!got.is_empty()).then(|| ForceGapValue {
        rms: got.iter().map(|g| g.0).sum::<f64>() / n,
        percent: got.iter().map(|g| g.1).sum::<f64>() / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_zero_phase_filter_passes_slow_signals_unshifted_and_stops_fast_ones() {
        let ts = 1e-3;
        let n = 4000;
        // 2 Hz passes (no lag: the peak stays where it is), 400 Hz is stopped.
        let slow: Vec<f64> = (0..n)
            .map(|k| (2.0 * std::f64::consts::TAU * k as f64 * ts).sin())
            .collect();
        let mut x: Vec<f64> = slow
            .iter()
            .enumerate()
            .map(|(k, s)| s + (400.0 * std::f64::consts::TAU * k as f64 * ts).sin())
            .collect();
        filtfilt(&mut x, 50.0, ts);
        let err = x[500..3500]
            .iter()
            .zip(&slow[500..3500])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 0.02, "{err}");
    }

    #[test]
    fn a_model_that_holds_has_no_force_gap_and_a_missing_damper_has_its_force() {
        // m ẍ + d ẋ = u on a smooth motion: the residual of the right model is the
        // filter's error only; without the damper it is d·v.
        let src =
            |d: &str| format!("model a {{ body m ~ 2\n input u on m\n measure m.x, u\n {d} }}");
        let ts = 1e-3;
        let n = 5000;
        let w = std::f64::consts::TAU * 1.5;
        let x: Vec<f64> = (0..n).map(|k| (w * k as f64 * ts).sin()).collect();
        let u: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * ts;
                -2.0 * w * w * (w * t).sin() + 10.0 * w * (w * t).cos()
            })
            .collect();
        let rec = Record {
            names: vec!["m.x".into(), "u".into()],
            columns: vec![x, u],
            ts,
            t0: 0.0,
        };
        let right = dsl_parser::compile_str("a", &src("damper d (ground, m) ~ 10")).unwrap();
        assert_eq!(channels(&right), vec![("u".to_string(), "m".to_string())]);
        let ch = channel(&right, &rec).expect("channel");
        let (rms, pct) = gap(&right, &ch, "u", "m").expect("gap");
        assert!(pct < 0.5, "{rms} N, {pct} %");
        let wrong = dsl_parser::compile_str("a", &src("")).unwrap();
        let ch = channel(&wrong, &rec).expect("channel");
        let (rms, _) = gap(&wrong, &ch, "u", "m").expect("gap");
        // d·v has RMS 10·w/√2.
        let want = 10.0 * w / 2f64.sqrt();
        assert!((rms / want - 1.0).abs() < 0.02, "{rms} vs {want}");
        // A force a control law computes is a response, not a channel.
        let closed = dsl_parser::compile_str(
            "a",
            "model a { body m ~ 2\n input u on m\n reference r\n measure m.x, u\n \
             control u = 100 * (r - m.x) - 10 * m.v\n damper d (ground, m) ~ 10 }",
        )
        .unwrap();
        assert!(channels(&closed).is_empty());
    }
}
