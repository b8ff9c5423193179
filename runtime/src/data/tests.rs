use super::*;
use crate::sim::test_models::{sdof, SdofParams};
use dynid_ir::ir::FormFilter;

/// The SDOF model (signals `m1.x`, `m1.v`, `u`), optionally without a measured velocity.
fn sdof_ir(measured_v: bool) -> ModelIr {
    let mut ir = sdof(
        &SdofParams::benchmark(),
        FormFilter::Lowpass { corner: 10.0 },
        vec![1.0],
    );
    ir.signals[1].measured = measured_v;
    ir
}
use std::io::Write;

fn file(body: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(body.as_bytes()).unwrap();
    f
}

fn rows(n: usize, ts: f64) -> String {
    let mut s = String::from("t,m1.x,m1.v,u\n");
    for k in 0..n {
        let t = k as f64 * ts;
        s.push_str(&format!("{t},{},{},{}\n", t.sin(), t.cos(), 0.5));
    }
    s
}

/// Open and stream; the error message of the first failure.
fn read(body: &str, opts: &CsvOptions) -> Result<usize, String> {
    let ir = sdof_ir(true);
    let f = file(body);
    let src = CsvSource::open(f.path(), &ir, opts).map_err(|e| e.to_string())?;
    let mut n = 0;
    src.stream(64, &mut |_, l| n += l)
        .map_err(|e| e.to_string())?;
    Ok(n)
}

#[test]
fn reads_a_valid_file_in_chunks() {
    assert_eq!(read(&rows(300, 0.01), &CsvOptions::default()), Ok(300));
}

/// One streamed chunk: its length and the chunk's columns.
type Chunk = (usize, Vec<Vec<f64>>);

/// Every chunk of one pass.
fn pass(src: &CsvSource, max_len: usize) -> Result<Vec<Chunk>, DataError> {
    let mut chunks = Vec::new();
    src.stream(max_len, &mut |cols, len| {
        chunks.push((len, cols.iter().map(|c| c.to_vec()).collect()));
    })?;
    Ok(chunks)
}

#[test]
fn later_passes_replay_exactly_what_the_first_parsed() {
    let ir = sdof_ir(true);
    let f = file(&rows(1000, 0.01));
    let src = CsvSource::open(f.path(), &ir, &CsvOptions::default()).unwrap();
    let uncopied = src.clone().without_replay();
    for max_len in [64, 1000, 4096, 7] {
        let first = pass(&src, max_len).unwrap();
        assert!(src.replay.lock().unwrap().is_some(), "no copy kept");
        assert_eq!(pass(&src, max_len).unwrap(), first, "max_len {max_len}");
        assert_eq!(pass(&uncopied, max_len).unwrap(), first);
        assert_eq!(first.iter().map(|c| c.0).sum::<usize>(), 1000);
    }
    assert!(uncopied.replay.lock().unwrap().is_none());
}

#[test]
fn a_failed_pass_keeps_no_copy_and_fails_again() {
    let ir = sdof_ir(true);
    let body = rows(300, 0.01) + "3.0,1,nan,0\n";
    let f = file(&body);
    let src = CsvSource::open(f.path(), &ir, &CsvOptions::default()).unwrap();
    for _ in 0..2 {
        let e = pass(&src, 64).unwrap_err().to_string();
        assert!(e.contains("line 302"), "{e}");
        assert!(src.replay.lock().unwrap().is_none());
    }
}

#[test]
fn missing_column_lists_what_is_there() {
    let body = rows(300, 0.01).replace("m1.v", "vel");
    let e = read(&body, &CsvOptions::default()).unwrap_err();
    assert!(
        e.contains("no column for the measured signal `m1.v` (columns: t, m1.x, vel, u)"),
        "{e}"
    );
    // ... and a renaming fixes it.
    let opts = CsvOptions {
        map: vec![("vel".into(), "m1.v".into())],
        ts: None,
        ..Default::default()
    };
    assert_eq!(read(&body, &opts), Ok(300));
}

#[test]
fn unmeasured_signals_are_not_required() {
    let ir = sdof_ir(false);
    let body = rows(300, 0.01).replace(",m1.v,", ",other,");
    let f = file(&body);
    assert!(CsvSource::open(f.path(), &ir, &CsvOptions::default()).is_ok());
}

#[test]
fn nan_and_text_cells_name_line_and_column() {
    // Sample 5 (file line 7, after the header) gets a NaN position.
    let bad_line = 7;
    let body: String = rows(300, 0.01)
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i + 1 == bad_line {
                "0.05,NaN,1,0.5".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let e = read(&body, &CsvOptions::default()).unwrap_err();
    assert!(
        e.contains(&format!(
            "line {bad_line}, column `m1.x`: NaN is not a finite number"
        )),
        "{e}"
    );
    let body2 = body.replace("0.05,NaN,", "0.05,abc,");
    let e = read(&body2, &CsvOptions::default()).unwrap_err();
    assert!(
        e.contains(&format!(
            "line {bad_line}, column `m1.x`: `abc` is not a number"
        )),
        "{e}"
    );
}

#[test]
fn ragged_row_is_reported() {
    let mut body = rows(300, 0.01);
    body.push_str("3.0,1,2\n");
    let e = read(&body, &CsvOptions::default()).unwrap_err();
    assert!(
        e.contains("line 302: expected 4 fields as in the header, found 3"),
        "{e}"
    );
}

#[test]
fn empty_and_header_only_files() {
    let e = read("", &CsvOptions::default()).unwrap_err();
    assert!(e.contains("the file is empty"), "{e}");
    let e = read("t,m1.x,m1.v,u\n", &CsvOptions::default()).unwrap_err();
    assert!(e.contains("has a header but no samples"), "{e}");
}

#[test]
fn too_few_samples_says_how_many() {
    let e = read(&rows(50, 0.01), &CsvOptions::default()).unwrap_err();
    assert!(
        e.contains("only 50 samples; at least 100 are needed"),
        "{e}"
    );
}

#[test]
fn non_uniform_time_names_the_first_bad_line() {
    let body: String = rows(300, 0.01)
        .lines()
        .enumerate()
        .filter(|(i, _)| *i != 120) // drop one sample: a gap of 2 Tₛ
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let e = read(&body, &CsvOptions::default()).unwrap_err();
    assert!(
        e.contains("line 121: a sample is missing between t = 1.18 s and t = 1.2 s"),
        "{e}"
    );
    // A step that is no whole number of intervals: a non-uniform clock.
    let body = rows(300, 0.01).replace("\n1.2,", "\n1.2049,");
    let e = read(&body, &CsvOptions::default()).unwrap_err();
    assert!(e.contains("line 122: the time step is"), "{e}");
}

#[test]
fn sample_interval_is_required_without_t() {
    let body: String = rows(300, 0.01)
        .lines()
        .map(|l| l.split_once(',').unwrap().1.to_string() + "\n")
        .collect();
    let e = read(&body, &CsvOptions::default()).unwrap_err();
    assert!(e.contains("no sample interval"), "{e}");
    let opts = CsvOptions {
        map: vec![],
        ts: Some(0.01),
        ..Default::default()
    };
    assert_eq!(read(&body, &opts), Ok(300));
}

#[test]
fn a_trailing_comma_is_not_a_column() {
    // As written by some exporters (the Silverbox file): `"V1","V2",` and `a,b,`.
    let f = file("\"V1\",\"V2\",\n0.5,1.5,\n-0.25,2,\n0,0,\n");
    let opts = CsvOptions {
        map: vec![],
        ts: Some(0.1),
        ..Default::default()
    };
    let rec = read_record(f.path(), &opts).unwrap();
    assert_eq!(rec.names, ["V1", "V2"]);
    assert_eq!(rec.column("V2").unwrap(), [1.5, 2.0, 0.0]);
}

#[test]
fn a_semicolon_or_tab_separated_file_is_named_as_such() {
    let opts = CsvOptions {
        map: vec![],
        ts: Some(0.1),
        ..Default::default()
    };
    for (sep, name) in [(";", ";"), ("\t", "\\t")] {
        let f = file(&format!("t{sep}x\n0{sep}1,5\n0.1{sep}2,5\n"));
        let e = read_record(f.path(), &opts).unwrap_err();
        assert!(matches!(e, DataError::Separator { .. }), "{e:?}");
        assert!(e.to_string().contains(&format!("uses `{name}`")), "{e}");
    }
}

/// The seed records of the CSV fuzzing: a valid level, and one without a time column.
fn fuzz_seeds() -> Vec<Vec<u8>> {
    let no_t: String = rows(150, 0.01)
        .lines()
        .map(|l| l.split_once(',').map_or(l, |(_, rest)| rest).to_string() + "\n")
        .collect();
    vec![rows(150, 0.01).into_bytes(), no_t.into_bytes()]
}

#[test]
fn the_csv_readers_survive_thousands_of_mutated_files() {
    // A deterministic miniature of `fuzz/fuzz_targets/csv.rs`: mutations of valid files
    // (byte flips, inserted separators, line breaks and special numbers, cuts) through
    // `fuzz::check_csv_bytes`, which panics if a reader breaks its contract.
    use rand::{Rng, SeedableRng};
    const PIECES: &[&[u8]] = &[
        b",", b"\n", b"\r\n", b";", b"\"", b"NaN", b"inf", b"-1e999", b"1e308", b"0,5", b"",
        b"\xff", b"t", b"m1.x", b"  ", b"#",
    ];
    let ir = sdof_ir(false);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("level.csv");
    let mut rng = rand::rngs::StdRng::seed_from_u64(17);
    let seeds = fuzz_seeds();
    for _ in 0..1500 {
        let mut b = seeds[rng.random_range(0..seeds.len())].clone();
        for _ in 0..rng.random_range(1..4) {
            let at = rng.random_range(0..=b.len());
            match rng.random_range(0..4) {
                0 if at < b.len() => b[at] = rng.random(),
                1 => {
                    let p = PIECES[rng.random_range(0..PIECES.len())];
                    b.splice(at..at, p.iter().copied());
                }
                2 => b.truncate(at),
                _ => {
                    let end = (at + rng.random_range(1..40)).min(b.len());
                    b.drain(at..end);
                }
            }
        }
        fuzz::check_csv_bytes(&path, &b, &ir);
    }
}

/// A file of `n` rows large enough to be cut into many pieces and blocks.
fn big_rows(n: usize) -> String {
    let mut s = String::from("t,m1.x,m1.v,u\n");
    for k in 0..n {
        let t = k as f64 * 0.01;
        // Shortest round-trip text of irregular values, as the simulator writes them.
        let x = (t * 1.7).sin() * 1e-3 + (k as f64).sqrt() * 1e-9;
        s.push_str(&format!(
            "{t:.2},{x},{},{}\n",
            (t * 0.3).cos(),
            -(k as f64) / 7.0
        ));
    }
    s
}

#[test]
fn a_large_file_parses_to_the_same_numbers_as_the_standard_parser() {
    // 300 000 rows are about 15 MB: several blocks, each cut into pieces parsed in parallel.
    let body = big_rows(300_000);
    let f = file(&body);
    let ir = sdof_ir(true);
    let src = CsvSource::open(f.path(), &ir, &CsvOptions::default()).unwrap();
    let mut got: Vec<Vec<f64>> = vec![Vec::new(); 3];
    src.stream(10_000, &mut |cols, len| {
        for (g, c) in got.iter_mut().zip(cols) {
            g.extend_from_slice(&c[..len]);
        }
    })
    .unwrap();
    let mut expected: Vec<Vec<f64>> = vec![Vec::new(); 3];
    for line in body.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
        for (e, &x) in expected.iter_mut().zip(&v[1..]) {
            e.push(x);
        }
    }
    // Signal order of the model: m1.x, m1.v, u.
    for (g, e) in got.iter().zip(&expected) {
        assert_eq!(g.len(), 300_000);
        assert!(g.iter().zip(e).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

#[test]
fn errors_deep_in_a_large_file_name_their_line() {
    let body = big_rows(250_000);
    let mut lines: Vec<String> = body.lines().map(str::to_string).collect();
    // A text cell on line 200 001 (after the header), far into a later block.
    let mut bad = lines.clone();
    let t = bad[200_000].split(',').next().unwrap().to_string();
    bad[200_000] = format!("{t},x1,0,0");
    let broken = bad.join("\n");
    let err = read(&broken, &CsvOptions::default()).unwrap_err();
    assert!(err.contains("line 200001"), "{err}");
    assert!(err.contains("`x1`"), "{err}");
    // A missing row: the time step doubles at line 123 457.
    lines.remove(123_456);
    let err = read(&lines.join("\n"), &CsvOptions::default()).unwrap_err();
    assert!(err.contains("line 123457"), "{err}");
    assert!(err.contains("step"), "{err}");
    // A short row.
    let mut short = body.lines().map(str::to_string).collect::<Vec<_>>();
    short[99_999] = "999.99,1,2".into();
    let err = read(&short.join("\n"), &CsvOptions::default()).unwrap_err();
    assert!(err.contains("line 100000"), "{err}");
}

#[test]
fn crlf_quotes_blank_lines_and_no_final_line_break_are_read() {
    let mut body = String::from("t,m1.x,m1.v,u\r\n");
    for k in 0..200 {
        let t = k as f64 * 0.01;
        if k == 50 {
            body.push_str("\r\n  \r\n");
        }
        body.push_str(&format!("{t:.2}, \"{}\" ,{},{}\r\n", k, -(k as f64), 0.5));
    }
    body.pop();
    body.pop();
    let ir = sdof_ir(true);
    let f = file(&body);
    let src = CsvSource::open(f.path(), &ir, &CsvOptions::default()).unwrap();
    let chunks = pass(&src, 1000).unwrap();
    assert_eq!(chunks.len(), 1);
    let (len, cols) = &chunks[0];
    assert_eq!(*len, 200);
    assert_eq!(cols[0][199], 199.0);
    assert_eq!(cols[1][199], -199.0);
}

// ---- Messages that quote the file ----

/// Open and stream; the error of the first failure.
fn read_err(bytes: &[u8], opts: &CsvOptions) -> DataError {
    let ir = sdof_ir(true);
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(bytes).unwrap();
    let src = match CsvSource::open(f.path(), &ir, opts) {
        Ok(src) => src,
        Err(e) => return e,
    };
    src.stream(64, &mut |_, _| {})
        .expect_err("the file is refused")
}

fn code(e: &DataError) -> String {
    miette::Diagnostic::code(e).map_or(String::new(), |c| c.to_string())
}

#[test]
fn a_byte_order_mark_at_the_start_is_read() {
    let body = format!("\u{feff}{}", rows(300, 0.01));
    assert_eq!(read(&body, &CsvOptions::default()), Ok(300));
}

#[test]
fn utf16_files_are_named_as_such() {
    let text = rows(300, 0.01);
    for bom in [true, false] {
        let units = bom
            .then_some(0xfeff_u16)
            .into_iter()
            .chain(text.encode_utf16());
        let bytes: Vec<u8> = units.flat_map(u16::to_le_bytes).collect();
        let e = read_err(&bytes, &CsvOptions::default());
        assert_eq!(code(&e), "dynid::data::encoding", "{e}");
        assert!(e.to_string().contains("UTF-16"), "{e}");
    }
}

#[test]
fn old_mac_line_ends_are_named() {
    let body = rows(300, 0.01).replace('\n', "\r");
    let e = read_err(body.as_bytes(), &CsvOptions::default());
    assert_eq!(code(&e), "dynid::data::line_ends", "{e}");
    // Windows line ends are read.
    let body = rows(300, 0.01).replace('\n', "\r\n");
    assert_eq!(read(&body, &CsvOptions::default()), Ok(300));
}

#[test]
fn invisible_and_control_characters_are_escaped_and_named() {
    // A zero-width space in a column name.
    let body = rows(300, 0.01).replacen("m1.x", "m1.x\u{200b}", 1);
    let e = read_err(body.as_bytes(), &CsvOptions::default());
    assert_eq!(code(&e), "dynid::data::missing_column", "{e}");
    let msg = e.to_string();
    assert!(msg.contains("m1.x\\u{200b}"), "{msg}");
    assert!(msg.contains("a zero-width space"), "{msg}");
    assert!(!msg.contains('\u{200b}'), "{msg}");
    // An escape sequence and a NUL in a number.
    // (A NUL byte makes the file binary: refused by the line reader before any parse.)
    for (bad, name, expected) in [
        (
            "\x1b[31m",
            "an escape character",
            "dynid::data::not_a_number",
        ),
        ("\0", "a NUL byte", "dynid::data::binary"),
    ] {
        let body = rows(300, 0.01).replacen("\n0.29,", &format!("\n0.29,{bad}"), 1);
        let e = read_err(body.as_bytes(), &CsvOptions::default());
        assert_eq!(code(&e), expected, "{e}");
        let msg = e.to_string();
        assert!(msg.contains(name), "{msg}");
        assert!(!msg.contains(bad), "{msg:?}");
        assert!(!msg.contains('\x1b') && !msg.contains('\0'), "{msg:?}");
    }
}

#[test]
fn sample_conflicting_with_the_t_column_says_so() {
    let opts = CsvOptions {
        map: vec![],
        ts: Some(0.02),
        ..Default::default()
    };
    let e = read_err(rows(300, 0.01).as_bytes(), &opts);
    assert_eq!(code(&e), "dynid::data::sample_conflict", "{e}");
    // An agreeing `--sample` is accepted.
    let opts = CsvOptions {
        map: vec![],
        ts: Some(0.01),
        ..Default::default()
    };
    assert_eq!(read(&rows(300, 0.01), &opts), Ok(300));
}

#[test]
fn map_messages_name_the_real_problem() {
    let ir = sdof_ir(true);
    let e = CsvOptions::parse_map("=m1.x", &ir).unwrap_err();
    assert_eq!(code(&e), "dynid::data::bad_map");
    assert!(
        e.to_string().contains("column name before `=` is empty"),
        "{e}"
    );
    let e = CsvOptions::parse_map("t=m1.x", &ir).unwrap_err();
    assert!(e.to_string().contains("`t` is the time column"), "{e}");
    // `m1.x=t` parses (it names the time column of a file without `t`), but a file that
    // has its own `t` refuses it.
    let map = CsvOptions::parse_map("m1.x=t", &ir).unwrap();
    let opts = CsvOptions {
        map: vec![map],
        ts: None,
        ..Default::default()
    };
    let e = read_err(rows(300, 0.01).as_bytes(), &opts);
    assert_eq!(code(&e), "dynid::data::bad_map", "{e}");
    assert!(matches!(e, DataError::MapOntoTime { .. }), "{e}");
}
