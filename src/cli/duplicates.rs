//! Level files given twice: the same file (or a copy of it) is one record, not two levels.
//!
//! Two paths name one record when they resolve to the same file or their contents are
//! byte for byte equal. The comparison reads both files only while they agree, so files
//! of different records part after a few lines; only equal sizes are compared at all.

use miette::miette;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// Whether the files at `a` and `b` hold the same bytes (`false` when either cannot be
/// read: the reader then reports that file with its own message).
fn same_content(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    if !(ma.is_file() && mb.is_file()) || ma.len() != mb.len() {
        return false;
    }
    let (Ok(fa), Ok(fb)) = (File::open(a), File::open(b)) else {
        return false;
    };
    let (mut ra, mut rb) = (BufReader::new(fa), BufReader::new(fb));
    let (mut ba, mut bb) = (vec![0u8; 1 << 16], vec![0u8; 1 << 16]);
    loop {
        let (Ok(na), Ok(nb)) = (read_full(&mut ra, &mut ba), read_full(&mut rb, &mut bb)) else {
            return false;
        };
        if na != nb || ba[..na] != bb[..nb] {
            return false;
        }
        if na == 0 {
            return true;
        }
    }
}

/// Fill `buf` as far as the reader goes; the count read (short only at the end).
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Pairs `(first, later)` of `paths` that hold one record: the same file, or equal
/// contents. Only regular files are compared (a stream cannot be read twice).
pub fn duplicate_levels(paths: &[PathBuf]) -> Vec<(usize, usize)> {
    let canon: Vec<Option<PathBuf>> = paths
        .iter()
        .map(|p| {
            std::fs::metadata(p)
                .ok()
                .filter(|m| m.is_file())
                .and_then(|_| std::fs::canonicalize(p).ok())
        })
        .collect();
    let mut out = Vec::new();
    for j in 1..paths.len() {
        let Some(cj) = &canon[j] else { continue };
        if let Some(i) = (0..j).find(|&i| {
            canon[i]
                .as_ref()
                .is_some_and(|ci| ci == cj || same_content(ci, cj))
        }) {
            out.push((i, j));
        }
    }
    out
}

/// Refuse level files that hold one record twice: for a command that compares levels
/// (detection tests whether a parameter changes between them; diagnosis withholds each
/// in turn), a copy is no second level.
pub fn refuse_duplicate_levels(paths: &[PathBuf], what: &str) -> miette::Result<()> {
    if let Some(&(i, j)) = duplicate_levels(paths).first() {
        let (a, b) = (&paths[i], &paths[j]);
        return Err(if a == b {
            miette!(
                code = "dynid::data::duplicate_level",
                help = "give each level's file once",
                "`{}` is given twice (levels {} and {}): {what}",
                a.display(),
                i + 1,
                j + 1
            )
        } else {
            miette!(
                code = "dynid::data::duplicate_level",
                help = "give each level's file once; a copy of a record is not a second level",
                "`{}` and `{}` hold the same record (levels {} and {}): {what}",
                a.display(),
                b.display(),
                i + 1,
                j + 1
            )
        });
    }
    Ok(())
}
