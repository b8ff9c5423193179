//! The header of a CSV file: its columns renamed by `--map` and checked (one column that
//! holds another separator, a renaming onto `t`, duplicates), the measured signals found
//! in it, and the sample interval settled from the first two time stamps or `--sample`.

use super::super::{CsvOptions, DataError, TIME_TOL};
use dynid_ir::ir::ModelIr;
use std::path::Path;

/// The header's column names after the `opts.map` renamings, checked: a single column
/// whose name holds another usual separator (`;` or tab-separated data read as CSV), a
/// renaming of a column that is not there, a renaming onto `t` while the file keeps its
/// own `t` column, and duplicate names are errors.
pub(super) fn renamed(
    path: &Path,
    header: &[String],
    opts: &CsvOptions,
    delimiter: u8,
) -> Result<Vec<String>, DataError> {
    let p = path.display().to_string();
    // One column whose name holds another usual separator: `;` or tab-separated data.
    if let [only] = header {
        if let Some(sep) = [",", ";", "\t"]
            .into_iter()
            .filter(|s| s.as_bytes() != [delimiter])
            .find(|s| only.contains(s))
        {
            return Err(DataError::Separator {
                path: p,
                header: dynid_ir::text::escape(only),
                separator: if sep == "\t" {
                    "\\t".into()
                } else {
                    sep.into()
                },
            });
        }
    }
    let mut names = header.to_vec();
    for (c, s) in &opts.map {
        if let Some(k) = header.iter().position(|h| h == c) {
            names[k] = s.clone();
        } else {
            return Err(DataError::MissingColumn {
                path: p,
                signal: dynid_ir::text::escape(c),
                present: present_columns(header, c),
            });
        }
    }
    // A renaming onto `t` when the file keeps its own `t` column.
    let keeps_t = header.iter().any(|h| h == "t") && !opts.map.iter().any(|(c, _)| c == "t");
    let onto_t = opts.map.iter().find(|(c, s)| s == "t" && c != "t");
    if let (true, Some((c, _))) = (keeps_t, onto_t) {
        return Err(DataError::MapOntoTime {
            path: p,
            spec: format!("{}=t", dynid_ir::text::escape(c)),
            column: dynid_ir::text::escape(c),
        });
    }
    for (k, n) in names.iter().enumerate() {
        if names[..k].contains(n) {
            return Err(DataError::DuplicateColumn {
                path: p,
                column: dynid_ir::text::quote(n),
            });
        }
    }
    Ok(names)
}

/// The sample interval: `ts_option` (`--sample`), which must agree with the step of the
/// first two time stamps `first_t` where the file has a `t` column (`has_t`), else that
/// step, which must be positive.
pub(super) fn sample_interval(
    path: &Path,
    ts_option: Option<f64>,
    first_t: &[f64],
    has_t: bool,
    min_samples: usize,
) -> Result<f64, DataError> {
    let p = path.display().to_string();
    let ts = match (ts_option, first_t) {
        (Some(ts), [a, b]) => {
            // `--sample` with a `t` column: the two must agree.
            let step = b - a;
            if step.is_finite() && step > 0.0 && (step - ts).abs() > TIME_TOL * ts {
                return Err(DataError::SampleConflict { path: p, ts, step });
            }
            ts
        }
        (Some(ts), _) => ts,
        (None, [a, b]) => {
            let ts = b - a;
            if ts.is_nan() || ts <= 0.0 {
                return Err(DataError::TimeNotIncreasing {
                    path: p,
                    line: 3,
                    t: *b,
                    previous: *a,
                });
            }
            ts
        }
        (None, _) if has_t => {
            return Err(DataError::TooFewSamples {
                path: p,
                n: first_t.len(),
                need: min_samples,
            })
        }
        (None, _) => return Err(DataError::NoSampleInterval { path: p }),
    };
    Ok(ts)
}

/// The header's columns for a message (invisible characters escaped), with a note when one
/// of them is `wanted` but for invisible characters.
fn present_columns(header: &[String], wanted: &str) -> String {
    let escaped: Vec<String> = header.iter().map(|h| dynid_ir::text::escape(h)).collect();
    let mut out = columns_in_words(&escaped);
    let clean = |h: &str| -> String {
        h.chars()
            .filter(|&c| dynid_ir::text::invisible_name(c).is_none())
            .collect()
    };
    if let Some(h) = header
        .iter()
        .find(|h| h.as_str() != wanted && clean(h) == wanted)
    {
        let what = dynid_ir::text::describe_invisibles(h).unwrap_or_default();
        out += &format!(
            "; column `{}` is `{wanted}` with an invisible character: {what}; remove it",
            dynid_ir::text::escape(h)
        );
    }
    out
}

/// The header's columns for a message: all of them, or the first few and how many there
/// are (a header can be up to [`super::MAX_LINE`] long; a message should not be).
fn columns_in_words(header: &[String]) -> String {
    const SHOWN: usize = 400;
    let all = header.join(", ");
    if all.len() <= SHOWN {
        return all;
    }
    let mut cut = SHOWN;
    while !all.is_char_boundary(cut) {
        cut -= 1;
    }
    format!("{}… ({} columns)", &all[..cut], header.len())
}

/// The `(slot, column)` pairs of the measured signals of `ir` in a header (`names` after
/// the renamings), and the number of slots.
pub(super) fn select_measured(
    path: &Path,
    ir: &ModelIr,
    names: &[String],
    header: &[String],
) -> Result<(Vec<(usize, usize)>, usize), DataError> {
    let mut wanted = Vec::new();
    for s in ir.measured_signals() {
        let name = &ir.signal(s).name;
        match names.iter().position(|n| n == name) {
            Some(k) => wanted.push((s.index(), k)),
            None => {
                return Err(DataError::MissingColumn {
                    path: path.display().to_string(),
                    signal: name.clone(),
                    present: present_columns(header, name),
                })
            }
        }
    }
    Ok((wanted, ir.signals.len()))
}
