//! Basis evaluation plus moment accumulation for `two_mass` over 10⁷ samples, three ways in
//! the same run: the code `include_model!` generates, a hand-written Rust version of the
//! same basis, and the runtime's interpreted tape.
//!
//! `cargo bench --bench codegen` (optionally `-- SAMPLES`). Targets: generated within 1.2×
//! of hand-written, tape within 2× of generated.
//!
//! The accumulation is identical for all three: `Σₙ gᵣ[n] · zₖ[n]` for the five basis
//! columns `g` and four instruments `z` (three signals and a first-order low-pass of the
//! input), streamed in blocks of 8192 samples as the runtime does.

use dynid::runtime::tape::Tape;
use dynid::runtime::BasisEval;
use std::hint::black_box;
use std::time::{Duration, Instant};

dynid::include_model!("models/two_mass.dyn");

#[path = "../runtime/benches/common/row.rs"]
mod row;

const BLOCK: usize = 8192;
const POOL_BLOCKS: usize = 8;
const N_ROOTS: usize = 5;
const N_INSTR: usize = 4;

/// The two-mass basis written by hand: `m1.x`, `s`, `s³`, `sign(v)`, `u` with
/// `s = m2.x − m1.x`, `v = m2.v − m1.v`.
struct HandWritten;

impl BasisEval for HandWritten {
    fn n_roots(&self) -> usize {
        N_ROOTS
    }
    fn eval_block(&self, signals: &[&[f64]], len: usize, out: &mut [f64], _: &mut Vec<f64>) {
        let (x1, v1, x2, v2, u) = (
            &signals[0][..len],
            &signals[1][..len],
            &signals[2][..len],
            &signals[3][..len],
            &signals[4][..len],
        );
        let (o_x1, rest) = out[..N_ROOTS * len].split_at_mut(len);
        let (o_s, rest) = rest.split_at_mut(len);
        let (o_s3, rest) = rest.split_at_mut(len);
        let (o_sign, o_u) = rest.split_at_mut(len);
        for i in 0..len {
            let s = x2[i] - x1[i];
            let v = v2[i] - v1[i];
            o_x1[i] = x1[i];
            o_s[i] = s;
            o_s3[i] = s * s * s;
            o_sign[i] = if v > 0.0 {
                1.0
            } else if v < 0.0 {
                -1.0
            } else {
                0.0
            };
            o_u[i] = u[i];
        }
    }
}

/// Synthetic, deterministic signals: smooth-ish random walks, a pool of `POOL_BLOCKS`
/// blocks that the run cycles through.
fn pool() -> Vec<Vec<f64>> {
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..5)
        .map(|_| {
            let mut y = 0.0;
            (0..POOL_BLOCKS * BLOCK)
                .map(|_| {
                    y = 0.99 * y + rnd();
                    y
                })
                .collect()
        })
        .collect()
}

/// Evaluate and accumulate `n` samples; returns the moments (so nothing is optimised away).
fn run(eval: &dyn BasisEval, pool: &[Vec<f64>], n: usize) -> [[f64; N_INSTR]; N_ROOTS] {
    let mut out = vec![0.0; N_ROOTS * BLOCK];
    let mut scratch = Vec::new();
    let mut acc = [[0.0; N_INSTR]; N_ROOTS];
    let mut lp = 0.0;
    let mut z = vec![[0.0; N_INSTR]; BLOCK];
    let mut done = 0;
    let mut b = 0;
    while done < n {
        let len = BLOCK.min(n - done);
        let off = b * BLOCK;
        let cols: Vec<&[f64]> = pool.iter().map(|c| &c[off..off + len]).collect();
        eval.eval_block(&cols, len, &mut out, &mut scratch);
        for (i, zi) in z[..len].iter_mut().enumerate() {
            lp += 0.05 * (cols[4][i] - lp);
            *zi = [cols[0][i], cols[2][i], cols[4][i], lp];
        }
        for (r, acc_r) in acc.iter_mut().enumerate() {
            let g = &out[r * len..(r + 1) * len];
            for (gi, zi) in g.iter().zip(&z[..len]) {
                for k in 0..N_INSTR {
                    acc_r[k] += gi * zi[k];
                }
            }
        }
        done += len;
        b = (b + 1) % POOL_BLOCKS;
    }
    acc
}

fn main() {
    let n: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(10_000_000);
    let model = TwoMass::new();
    let ir = model.ir();
    let tape = Tape::compile(ir, &ir.eval_roots());
    let pool = pool();

    // Same numbers from all three (the tape and the generated code bit for bit).
    let reference = run(&model, &pool, 100_000);
    assert_eq!(run(&tape, &pool, 100_000), reference);
    assert_eq!(run(&HandWritten, &pool, 100_000), reference);

    let variants: [(&str, &dyn BasisEval); 3] = [
        ("hand-written", &HandWritten),
        ("generated", &model),
        ("tape", &tape),
    ];
    let mut best = [Duration::MAX; 3];
    // Interleaved repetitions, best of each, so drift in machine load hits all alike.
    for _ in 0..5 {
        for (v, (_, eval)) in variants.iter().enumerate() {
            let t = Instant::now();
            black_box(run(*eval, black_box(&pool), n));
            best[v] = best[v].min(t.elapsed());
        }
    }
    println!("two_mass: basis evaluation + accumulation, {n} samples, best of 5");
    for ((name, _), t) in variants.iter().zip(best) {
        println!(
            "  {name:<13} {:8.1} ms  {:6.2} ns/sample",
            t.as_secs_f64() * 1e3,
            t.as_secs_f64() * 1e9 / n as f64
        );
    }
    let (hand, generated, tape) = (best[0], best[1], best[2]);
    println!(
        "  generated / hand-written = {:.3}   (target ≤ 1.2)",
        generated.as_secs_f64() / hand.as_secs_f64()
    );
    println!(
        "  tape / generated         = {:.3}   (target ≤ 2)",
        tape.as_secs_f64() / generated.as_secs_f64()
    );
    row::print_row(
        "codegen",
        &format!(
            "generated {:.2}× the hand-written basis, the tape {:.2}× the generated code",
            generated.as_secs_f64() / hand.as_secs_f64(),
            tape.as_secs_f64() / generated.as_secs_f64()
        ),
        "a hand-written Rust version of the same basis, in the same run",
        &format!("cargo bench --bench codegen -- {n}"),
    );
}
