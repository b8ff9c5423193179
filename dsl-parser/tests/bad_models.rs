//! One bad model per error kind: each fails with the expected diagnostic codes, the
//! rendered report (snapshot) points at `file:line:column`, and no input makes the front
//! end panic.

use dsl_parser::{compile_file, compile_str, ErrorKind};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

fn bad_models() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_models");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "dyn"))
        .collect();
    files.sort();
    files
}

/// The codes listed on the first line: `// expect: dyn::a dyn::b`.
fn expected_codes(src: &str) -> Vec<String> {
    let first = src.lines().next().unwrap_or_default();
    let list = first
        .strip_prefix("// expect:")
        .expect("a bad model starts with `// expect: dyn::code`");
    list.split_whitespace().map(String::from).collect()
}

#[test]
fn every_bad_model_reports_its_error_with_line_and_column() {
    let mut covered = HashSet::new();
    for path in bad_models() {
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let src = std::fs::read_to_string(&path).unwrap();
        let name = format!("bad_models/{stem}.dyn");
        let errs = match compile_str(&name, &src) {
            Ok(_) => panic!("{stem}.dyn compiled but should not"),
            Err(e) => e,
        };
        let codes: Vec<&str> = errs.kinds().iter().map(|k| k.code()).collect();
        for want in expected_codes(&src) {
            assert!(
                codes.contains(&want.as_str()),
                "{stem}: expected {want}, got {codes:?}"
            );
        }
        covered.extend(errs.kinds());
        let text = errs.render_plain(100);
        for e in &errs.errors {
            let span = e.span().expect("every model error has a span");
            let line = src[..span.start].matches('\n').count() + 1;
            let col = span.start - src[..span.start].rfind('\n').map_or(0, |i| i + 1) + 1;
            let at = format!("{name}:{line}:{col}");
            assert!(text.contains(&at), "{stem}: `{at}` not in\n{text}");
            assert!(
                !e.help_text().is_empty(),
                "{stem}: {} has no help",
                e.message()
            );
        }
        insta::assert_snapshot!(format!("bad_{stem}"), text);
    }
    for kind in ErrorKind::ALL {
        if *kind != ErrorKind::Io {
            assert!(
                covered.contains(kind),
                "no bad model exercises {}",
                kind.code()
            );
        }
    }
}

#[test]
fn many_errors_are_reported_together_in_source_order() {
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_models/many_errors.dyn"),
    )
    .unwrap();
    let errs = compile_str("many.dyn", &src).unwrap_err();
    assert!(errs.errors.len() >= 4, "{:?}", errs.kinds());
    let starts: Vec<usize> = errs
        .errors
        .iter()
        .filter_map(|e| e.span())
        .map(|s| s.start)
        .collect();
    assert!(starts.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn unreadable_file_is_a_diagnostic() {
    let errs = compile_file(Path::new("/nonexistent/model.dyn")).unwrap_err();
    assert_eq!(errs.kinds(), vec![ErrorKind::Io]);
    assert!(errs.errors[0].message().contains("/nonexistent/model.dyn"));
}

#[test]
fn unmeasured_term_names_the_term_and_the_signal() {
    // A static term in an unmeasured position cannot be formed; the linear damper can.
    let src = "model no_position {\n body m = 1.0\n input u on m\n measure m.v, u\n \
               damper d (ground, m) ~ 0.4\n force h (ground, m) = k3 ~ 2.0 * s^3\n}\n";
    let errs = compile_str("u.dyn", src).unwrap_err();
    assert_eq!(
        errs.errors.len(),
        1,
        "the linear damper is accepted: {errs:?}"
    );
    let msg = errs.errors[0].message();
    assert!(msg.contains("m.x^3") && msg.contains("`m.x`"), "{msg}");
}

#[test]
fn nonlinear_velocity_term_compiles_when_the_position_is_measured() {
    // Identification estimates `m.v` from `m.x` for `sign(v)`.
    let src = "model no_velocity {\n body m = 1.0\n input u on m\n measure m.x, u\n \
               spring k (ground, m) ~ 4.0\n damper d (ground, m) ~ 0.4\n \
               force friction (ground, m) = r ~ 0.3 * sign(v)\n}\n";
    let ir = compile_str("v.dyn", src).unwrap_or_else(|e| panic!("{e:?}"));
    assert!(!ir.signal(ir.signal_id("m.v").unwrap()).measured);
}

/// Deterministic mutations of every model (deleting, duplicating and swapping bytes,
/// inserting tokens): the front end returns a result or diagnostics, never panics, and
/// every diagnostic span lies inside the source.
#[test]
fn mutated_models_never_panic() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    let mut seeds: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| std::fs::read_to_string(e.unwrap().path()).unwrap())
        .collect();
    seeds.sort();
    const TOKENS: &[&str] = &[
        "(",
        ")",
        "*",
        "^",
        "-",
        "~",
        "=",
        ",",
        "[",
        "]",
        "{",
        "}",
        ".",
        "s",
        "v",
        "t",
        "k",
        "m",
        "ground",
        "sign(",
        "deadzone(",
        "^-3",
        "1e999",
        "0",
        "/0",
        "body",
        "force",
        "measure",
        "excite",
        "levels",
        "// ",
        "\n",
        "é",
        "m.x",
        "(((",
        "k ~ 1 *",
    ];
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut compiled = 0;
    for round in 0..4000 {
        let mut s: Vec<char> = seeds[round % seeds.len()].chars().collect();
        for _ in 0..1 + next() % 4 {
            if s.is_empty() {
                break;
            }
            let i = (next() as usize) % s.len();
            match next() % 4 {
                0 => {
                    let n = 1 + (next() as usize) % 8;
                    s.drain(i..(i + n).min(s.len()));
                }
                1 => {
                    let t = TOKENS[(next() as usize) % TOKENS.len()];
                    for (k, c) in t.chars().enumerate() {
                        s.insert(i + k, c);
                    }
                }
                2 => {
                    let j = (next() as usize) % s.len();
                    s.swap(i, j);
                }
                _ => {
                    let j = (next() as usize) % s.len();
                    let (a, b) = (i.min(j), i.max(j));
                    let chunk: Vec<char> = s[a..b.min(a + 40)].to_vec();
                    for (k, c) in chunk.into_iter().enumerate() {
                        s.insert(b + k, c);
                    }
                }
            }
        }
        let text: String = s.into_iter().collect();
        match compile_str("fuzz.dyn", &text) {
            Ok(ir) => {
                compiled += 1;
                ir.check_invariants().unwrap();
                let _ = dsl_parser::print::render_report(&ir);
            }
            Err(errs) => {
                assert!(!errs.errors.is_empty());
                for e in &errs.errors {
                    if let Some(sp) = e.span() {
                        assert!(sp.start <= sp.end && sp.end <= text.len(), "{text}");
                    }
                }
                let _ = errs.render_plain(100);
            }
        }
    }
    // The mutations are small, so some models still compile.
    assert!(compiled > 50, "{compiled}");
}

#[test]
fn hostile_inputs_are_rejected_without_overflow() {
    let deep = format!(
        "model d {{ body m = 1 force f (ground, m) = k * {}s{} }}",
        "(".repeat(5000),
        ")".repeat(5000)
    );
    assert!(compile_str("d.dyn", &deep).is_err());
    let long = format!(
        "model l {{ body m = 1 input u on m force f (ground, m) = k * s{} }}",
        " + s".repeat(100_000)
    );
    assert!(compile_str("l.dyn", &long).is_err());
    let negs = format!(
        "model n {{ body m = 1 input u on m force f (ground, m) = k * {}s }}",
        "-".repeat(100_000)
    );
    assert!(compile_str("n.dyn", &negs).is_ok());
    assert!(compile_str("e.dyn", "").is_err());
    assert!(compile_str("e.dyn", "model").is_err());
}

// ---- Text a terminal does not show, and the messages that quote it ----

/// A file name of this test process in the temporary directory.
fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("dynid-bad-models-{}-{name}", std::process::id()))
}

fn sdof(line: &str) -> String {
    format!(
        "model sdof {{\n    body m = 1.0\n    input u on m\n    {line}\n    damper d (ground, m) ~ 0.4\n}}\n"
    )
}

#[test]
fn a_byte_order_mark_at_the_start_is_skipped() {
    let src = format!("\u{feff}{}", sdof("spring k (ground, m) ~ 4.0"));
    let ir = compile_str("bom.dyn", &src).unwrap_or_else(|e| panic!("{e:?}"));
    assert_eq!(ir.unknowns().len(), 2);
    // The same through a file.
    let path = scratch("bom.dyn");
    std::fs::write(&path, &src).unwrap();
    let result = compile_file(&path);
    let _ = std::fs::remove_file(&path);
    result.unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn invisible_characters_are_escaped_and_named() {
    for (c, name) in [
        ('\u{feff}', "a byte-order mark"),
        ('\u{200b}', "a zero-width space"),
        ('\u{202e}', "a bidirectional embedding or override"),
        ('\x1b', "an escape character"),
        ('\0', "a NUL byte"),
    ] {
        let src = sdof(&format!("spring k{c} (ground, m) ~ 4.0"));
        let errs = compile_str("inv.dyn", &src).unwrap_err();
        assert_eq!(errs.kinds(), vec![ErrorKind::Syntax]);
        let msg = errs.errors[0].message();
        let escaped = dsl_parser::text::escape_char(c);
        assert!(msg.contains(&format!("`{escaped}`")), "{msg}");
        assert!(msg.contains(name), "{msg}");
        assert!(!msg.contains(c), "raw {c:?} in {msg:?}");
        // The excerpt of the source shows a stand-in, never the character itself.
        let text = errs.render_plain(100);
        assert!(!text.contains(c), "raw {c:?} in the report:\n{text}");
        assert!(text.contains("inv.dyn:4:13"), "{text}");
    }
}

#[test]
fn a_utf16_model_is_named_as_such() {
    let src = sdof("spring k (ground, m) ~ 4.0");
    for (bom, le) in [(true, true), (false, true), (true, false)] {
        let mut bytes: Vec<u8> = Vec::new();
        let units = (bom.then_some(0xfeff_u16).into_iter()).chain(src.encode_utf16());
        for u in units {
            bytes.extend(if le { u.to_le_bytes() } else { u.to_be_bytes() });
        }
        let path = scratch("u16.dyn");
        std::fs::write(&path, &bytes).unwrap();
        let result = compile_file(&path);
        let _ = std::fs::remove_file(&path);
        let errs = result.unwrap_err();
        assert_eq!(errs.kinds(), vec![ErrorKind::Io]);
        let msg = errs.errors[0].message();
        assert!(msg.contains("is UTF-16"), "{msg}");
        let text = errs.render_plain(100);
        assert!(!text.contains('\0'), "NUL bytes echoed:\n{text}");
    }
}

#[test]
fn a_prime_is_explained_not_listed() {
    let src = sdof("spring k (ground, m) ~ 4.0\n    force f (ground, m) = c ~ 1.0 * sign(x')");
    let errs = compile_str("prime.dyn", &src).unwrap_err();
    assert_eq!(errs.kinds(), vec![ErrorKind::Syntax]);
    let (msg, help) = (errs.errors[0].message(), errs.errors[0].help_text());
    assert!(msg.contains("`'` is not part of the language"), "{msg}");
    assert!(!msg.contains("expected"), "{msg}");
    assert!(help.contains("`v`") && help.contains("`m.v`"), "{help}");
}

#[test]
fn a_control_law_divided_by_zero_is_refused_like_a_force() {
    let model = |law: &str| {
        format!(
            "model servo {{\n    body m ~ 50\n    input u on m\n    reference xr\n    \
             measure m.x, u\n    control u = {law}\n    damper d (ground, m) ~ 120\n    \
             excite xr: white levels [1]\n}}\n"
        )
    };
    for law in [
        "80000 * (xr - m.x) / 0",
        "80000 * (xr - m.x) - 2680 * m.v / 0",
    ] {
        let errs = compile_str("law.dyn", &model(law)).unwrap_err();
        assert_eq!(errs.kinds(), vec![ErrorKind::InvalidValue], "{law}");
        assert!(errs.errors[0].message().contains("control law"), "{law}");
    }
    // The same force term has always been refused.
    let force = sdof("spring k (ground, m) ~ 4.0\n    force f (ground, m) = c ~ 1.0 * s / 0");
    assert_eq!(
        compile_str("f.dyn", &force).unwrap_err().kinds(),
        vec![ErrorKind::InvalidValue]
    );
    compile_str("ok.dyn", &model("80000 * (xr - m.x) - 2680 * m.v")).unwrap();
}
