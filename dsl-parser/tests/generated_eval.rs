//! The generated evaluator, compiled and run: it must agree bit for bit with the
//! interpreter (`ModelIr::eval_scalar`) and the runtime's instruction tape.
//!
//! The generated files under `tests/generated/` are checked in (so that they can be
//! `include!`d here) and compared with fresh output of the generator; after a deliberate
//! change of the generator, rewrite them with `DYNID_BLESS=1 cargo test -p dsl-parser`.

mod fixtures;

use dsl_parser::codegen::{generate_pretty, CodegenOptions};
use dsl_parser::ir::ModelIr;
use dynid_runtime::tape::{Tape, TapeScratch};

/// Stands in for the `dynid` facade at the generated code's `crate_path`.
mod mock {
    pub mod dsl_parser {
        pub use ::dsl_parser::ir;

        /// The parser is not linked here; the fixtures play its part.
        pub fn compile_str(_name: &str, source: &str) -> Result<ir::ModelIr, String> {
            if source == crate::fixtures::SDOF_SOURCE {
                Ok(crate::fixtures::sdof())
            } else if source == crate::fixtures::TWO_MASS_SOURCE {
                Ok(crate::fixtures::two_mass())
            } else {
                Err("unknown source".into())
            }
        }
    }

    pub mod runtime {
        pub use ::dynid_runtime::*;
    }
}

// Not every generated item is used by these tests.
#[allow(dead_code)]
mod sdof {
    include!("generated/sdof.rs");
}
#[allow(dead_code)]
mod two_mass {
    include!("generated/two_mass.rs");
}

use mock::runtime::BasisEval;

fn opts() -> CodegenOptions {
    CodegenOptions {
        crate_path: syn::parse_quote!(crate::mock),
        source_name: None,
    }
}

#[test]
fn checked_in_generated_code_is_current() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/generated");
    let cases = [
        ("sdof.rs", fixtures::sdof(), fixtures::SDOF_SOURCE),
        (
            "two_mass.rs",
            fixtures::two_mass(),
            fixtures::TWO_MASS_SOURCE,
        ),
    ];
    for (file, ir, source) in cases {
        let fresh = generate_pretty(&ir, source, &opts());
        let path = dir.join(file);
        if std::env::var_os("DYNID_BLESS").is_some() {
            std::fs::write(&path, &fresh).unwrap();
            continue;
        }
        let stored = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            stored == fresh,
            "{} is stale; rerun with DYNID_BLESS=1 and review the diff",
            path.display()
        );
    }
}

/// A deterministic generator (xorshift64*), so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// Signal columns: random values over several scales plus the points where the piecewise
/// functions switch (0, ±gap, ±limit, the saturate offset) in every signal.
fn columns(n_signals: usize, len: usize, seed: u64) -> Vec<Vec<f64>> {
    let special = [
        0.0, -0.0, 0.01, -0.01, 0.5, -0.5, 0.1, 0.6, -0.4, 1e-300, -3.0,
    ];
    let mut rng = Rng(seed);
    (0..n_signals)
        .map(|s| {
            (0..len)
                .map(|i| {
                    if (i + s) % 7 == 0 {
                        special[(i / 7 + s) % special.len()]
                    } else {
                        rng.next() * [0.02, 1.0, 30.0][(i + 2 * s) % 3]
                    }
                })
                .collect()
        })
        .collect()
}

fn check_parity(ir: &ModelIr, eval: &dyn BasisEval) {
    let roots = ir.eval_roots();
    assert_eq!(eval.n_roots(), roots.len());
    let tape = Tape::compile(ir, &roots);
    for (len, seed) in [(1, 1), (37, 2), (1000, 3)] {
        let cols = columns(ir.signals.len(), len, seed);
        let signals: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        let mut got = vec![f64::NAN; roots.len() * len];
        eval.eval_block(&signals, len, &mut got, &mut Vec::new());
        let mut want = vec![f64::NAN; roots.len() * len];
        tape.eval_block(&signals, len, &mut want, &mut TapeScratch::default());
        let mut point = vec![0.0; ir.signals.len()];
        for (r, &root) in roots.iter().enumerate() {
            for i in 0..len {
                for (p, c) in point.iter_mut().zip(&cols) {
                    *p = c[i];
                }
                let (g, t) = (got[r * len + i], want[r * len + i]);
                let scalar = ir.eval_scalar(root, &point);
                assert_eq!(
                    g.to_bits(),
                    t.to_bits(),
                    "root {r}, sample {i}: {g} vs tape {t}"
                );
                assert_eq!(
                    g.to_bits(),
                    scalar.to_bits(),
                    "root {r}, sample {i}: {g} vs {scalar}"
                );
            }
        }
    }
}

#[test]
fn sdof_evaluator_matches_the_interpreter_bit_for_bit() {
    check_parity(&fixtures::sdof(), &sdof::Sdof::new());
}

#[test]
fn two_mass_evaluator_matches_the_interpreter_bit_for_bit() {
    check_parity(&fixtures::two_mass(), &two_mass::TwoMass::new());
}

#[test]
fn evaluator_writes_only_the_roots_of_its_block() {
    let ir = fixtures::sdof();
    let len = 5;
    let x: Vec<f64> = (0..len).map(|i| i as f64 - 2.0).collect();
    // Columns may be longer than the block.
    let v = vec![0.5; len + 2];
    let u = vec![2.0; len];
    let mut out = vec![-7.0; 4 * len + 3];
    sdof::Sdof.eval_block(&[&x, &v, &u], len, &mut out, &mut Vec::new());
    // Roots in first-use order: the input term, then the spring's s and s³, then sign(v).
    assert_eq!(ir.eval_roots().len(), 4);
    assert_eq!(&out[..len], &u[..]);
    assert_eq!(&out[len..2 * len], &x[..]);
    assert_eq!(&out[2 * len..3 * len], &[-8.0, -1.0, 0.0, 1.0, 8.0]);
    assert_eq!(&out[3 * len..4 * len], &[1.0; 5]);
    assert_eq!(&out[4 * len..], &[-7.0; 3]);
}

#[test]
fn params_struct_follows_the_unknowns() {
    use two_mass::{TwoMass, TwoMassParams};
    let ir = fixtures::two_mass();
    let names: Vec<&str> = ir
        .unknowns()
        .iter()
        .map(|p| ir.params[p.index()].name.as_str())
        .collect();
    assert_eq!(TwoMass::PARAM_NAMES, &names[..]);
    let p = TwoMassParams::default();
    assert_eq!((p.m2, p.k5, p.h, p.c), (0.5, 1e3, -0.7, 0.0));
    let values: Vec<f64> = (0..names.len()).map(|i| i as f64 * 1.5).collect();
    assert_eq!(TwoMassParams::from_slice(&values).to_vec(), values);
}

#[test]
fn model_struct_exposes_layout_and_its_ir() {
    use two_mass::TwoMass;
    let ir = fixtures::two_mass();
    let names: Vec<&str> = ir.signals.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(TwoMass::SIGNAL_NAMES, &names[..]);
    assert_eq!(
        [
            TwoMass::M1_X,
            TwoMass::M1_V,
            TwoMass::M2_X,
            TwoMass::M2_V,
            TwoMass::U
        ],
        [0, 1, 2, 3, 4]
    );
    assert_eq!(TwoMass::NAME, "two_mass");
    assert_eq!(TwoMass::SOURCE, fixtures::TWO_MASS_SOURCE);
    assert_eq!(TwoMass::N_ROOTS, ir.eval_roots().len());
    let model = TwoMass::new();
    assert_eq!(model.ir(), &ir);
    assert!(std::ptr::eq(model.ir(), TwoMass.ir()), "parsed once");
}
