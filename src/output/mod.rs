//! Writing output files, all or nothing. The numerics format (into any `io::Write`); only
//! this module writes output files.
//!
//! [`Staged`] is the one writer: every file of a command goes to a temporary file
//! (`tempfile`, keeping the extension, which some writers use to pick a format) and all are
//! put in place by [`Staged::commit`]. Dropping an uncommitted set deletes its temporaries,
//! so an error never leaves a partial output behind, and so does an interrupt
//! ([`cleanup`]). What "in place" means depends on what the path names ([`target`]): a
//! regular file is replaced by a rename of a temporary made beside it (through symbolic
//! links: the link stays); a device, FIFO or descriptor path (`/dev/null`, `/dev/stdout`,
//! `>(jq .)`) is written through, from a temporary in the system's temporary directory. A
//! new file gets the mode of the user's umask (0644 under `umask 022`); a replaced file
//! keeps its mode, and its owner and group where the process may set them.

pub mod cleanup;
mod sim;
pub mod target;

pub use sim::{
    csv_bytes, run_files, run_outputs, simulate_signal_to_dir, simulate_to_dir, stage_driven,
    stage_levels, write_simulation, LevelWritten,
};
pub use target::{check_out_dir, check_output, check_space, parent_dir, resolve, Target};

use dynid_runtime::record::Record;
use dynid_runtime::sim::write_csv;
use miette::miette;
use std::io::Write;
use std::path::{Path, PathBuf};
use tempfile::TempPath;

/// One staged output: its temporary, where it goes, and its registration for removal on an
/// interrupt (declared after the temporary, so it is dropped after the file is deleted).
struct Entry {
    tmp: TempPath,
    target: Target,
    shown: PathBuf,
    _registered: cleanup::Registered,
}

/// A set of output files written all or nothing.
#[derive(Default)]
pub struct Staged {
    files: Vec<Entry>,
    stale: Vec<PathBuf>,
}

impl Staged {
    pub fn new() -> Self {
        Self::default()
    }

    /// Create the (empty) temporary file for `target` and return its path; the caller
    /// writes it.
    pub fn temp_for(&mut self, path: &Path) -> miette::Result<PathBuf> {
        let name = path
            .file_name()
            .ok_or_else(|| {
                miette!(
                    code = "dynid::output::is_directory",
                    help = "give the path of a file",
                    "`{}` is not a file name",
                    path.display()
                )
            })?
            .to_string_lossy();
        let ext = path
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let target = target::target(path);
        let dir = match &target {
            Target::File(f) => parent_dir(f).to_path_buf(),
            Target::Stream(_) => std::env::temp_dir(),
        };
        let file = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(&format!(".tmp{ext}"))
            .tempfile_in(&dir)
            .map_err(|e| write_error(path, e))?;
        let tmp = file.into_temp_path();
        let p = tmp.to_path_buf();
        self.files.push(Entry {
            _registered: cleanup::register_file(&p),
            tmp,
            target,
            shown: path.to_path_buf(),
        });
        Ok(p)
    }

    /// Stage `bytes` as the content of `target`.
    pub fn write(&mut self, target: &Path, bytes: &[u8]) -> miette::Result<()> {
        self.write_with(target, |w| w.write_all(bytes))
    }

    /// Stage the content of `target` as written by `fill` (buffered).
    pub fn write_with(
        &mut self,
        target: &Path,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> miette::Result<()> {
        let tmp = self.temp_for(target)?;
        (|| {
            let file = std::fs::File::create(&tmp)?;
            let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
            fill(&mut w)?;
            w.into_inner().map_err(|e| e.into_error())?.sync_all()
        })()
        .map_err(|e| write_error(target, e))
    }

    /// Remove `paths` (files of an earlier run that this set replaces) once every staged
    /// file is in place. A path that is missing by then is no error.
    pub fn remove_on_commit(&mut self, paths: impl IntoIterator<Item = PathBuf>) {
        self.stale.extend(paths);
    }

    /// Put every staged file in place: a file by a rename, a stream by writing it through.
    /// If one fails, the files not yet in place are deleted (those already in place stay:
    /// a rename cannot be undone).
    pub fn commit(mut self) -> miette::Result<()> {
        for e in std::mem::take(&mut self.files) {
            match &e.target {
                Target::File(f) => {
                    set_mode(&e.tmp, f);
                    std::fs::rename(&e.tmp, f).map_err(|err| write_error(&e.shown, err))?;
                    // The file is in place: nothing left to delete.
                    let _ = e.tmp.keep();
                }
                Target::Stream(s) => {
                    write_through(&e.tmp, s).map_err(|err| write_error(&e.shown, err))?;
                }
            }
        }
        for p in std::mem::take(&mut self.stale) {
            match std::fs::remove_file(&p) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(miette!(
                        code = "dynid::output::write",
                        help = "remove it by hand: it belongs to the run these files replaced",
                        "cannot remove `{}`: {e}",
                        p.display()
                    ))
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// Copy the temporary `tmp` into the stream `path`, opened for appending: nothing created,
/// nothing truncated, and `/dev/stdout` redirected to a file (`> out.txt`, which a new
/// open would write from its start) continues after what was printed. Standard output is
/// flushed first, so text printed before stays before.
fn write_through(tmp: &Path, path: &Path) -> std::io::Result<()> {
    std::io::stdout().flush()?;
    let mut src = std::fs::File::open(tmp)?;
    let mut dst = std::fs::OpenOptions::new().append(true).open(path)?;
    std::io::copy(&mut src, &mut dst)?;
    dst.flush()
}

/// Give the temporary `tmp` the mode it should have as `target`: the mode of the file it
/// replaces (and its owner and group, where the process may set them), else the user's
/// umask's. Best effort: a file that cannot be given them keeps tempfile's 0600.
fn set_mode(tmp: &Path, target: &Path) {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let mode = match std::fs::metadata(target) {
            Ok(old) => {
                if std::os::unix::fs::chown(tmp, Some(old.uid()), Some(old.gid())).is_err() {
                    let _ = std::os::unix::fs::chown(tmp, None, Some(old.gid()));
                }
                old.mode() & 0o7777
            }
            Err(_) => target::new_file_mode(),
        };
        let _ = std::fs::set_permissions(tmp, std::fs::Permissions::from_mode(mode));
    }
    #[cfg(not(unix))]
    let _ = (tmp, target);
}

/// The error of a failed write of `target`; a full disk is said so.
pub(crate) fn write_error(target: &Path, e: std::io::Error) -> miette::Report {
    if is_disk_full(&e) {
        return miette!(
            code = "dynid::output::write",
            help = "free some space or write elsewhere; nothing was written",
            "cannot write `{}`: the disk is full ({e})",
            target.display()
        );
    }
    miette!(
        code = "dynid::output::write",
        help = "check the permissions and the free space where it goes; nothing was written",
        "cannot write `{}`: {e}",
        target.display()
    )
}

fn is_disk_full(e: &std::io::Error) -> bool {
    e.kind() == std::io::ErrorKind::StorageFull || e.kind() == std::io::ErrorKind::QuotaExceeded
}

/// Write one file all or nothing.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> miette::Result<()> {
    let mut staged = Staged::new();
    staged.write(path, bytes)?;
    staged.commit()
}

/// Stage `record` as a CSV file (header `t,<signals>`, numbers in shortest round-trip form).
pub fn stage_csv(staged: &mut Staged, path: &Path, record: &Record) -> miette::Result<()> {
    staged.write_with(path, |w| write_csv(w, record))
}

/// Create an output directory (and its parents) if missing.
pub fn create_dir(dir: &Path) -> miette::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        miette!(
            code = "dynid::output::write",
            help = "check the permissions and the free space where it goes",
            "cannot create the output directory `{}`: {e}",
            dir.display()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut n: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        n.sort();
        n
    }

    #[test]
    fn a_failed_set_leaves_no_file_behind() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("a.json");
        let mut staged = Staged::new();
        staged.write(&good, b"{}").unwrap();
        let bad = dir.path().join("missing").join("b.json");
        assert!(staged.write(&bad, b"{}").is_err());
        drop(staged);
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn a_committed_set_is_in_place_without_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let mut staged = Staged::new();
        for n in ["a.json", "b.svg"] {
            staged.write(&dir.path().join(n), n.as_bytes()).unwrap();
        }
        staged.commit().unwrap();
        assert_eq!(names(dir.path()), ["a.json", "b.svg"]);
        let b = std::fs::read_to_string(dir.path().join("b.svg")).unwrap();
        assert_eq!(b, "b.svg");
    }

    /// On a private null device (`mknod`, root only): a regression must not replace the
    /// system's /dev/null. Skipped where the node cannot be made.
    #[cfg(unix)]
    #[test]
    fn a_device_is_written_through_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let null = dir.path().join("null");
        let c = std::ffi::CString::new(null.to_str().unwrap()).unwrap();
        // SAFETY: a valid path; mknod only creates the node (1, 3: the null device).
        if unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, 3)) } != 0 {
            eprintln!("skipped: mknod needs root");
            return;
        }
        write_atomically(&null, b"{}").unwrap();
        let t = std::fs::symlink_metadata(&null).unwrap().file_type();
        assert!(t.is_char_device());
        assert_eq!(names(dir.path()), ["null"]);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_written_through_without_a_temporary_beside_it() {
        use std::io::Read;
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("out.json");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid path; mkfifo only creates the node.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
        let (tx, rx) = std::sync::mpsc::channel();
        {
            let fifo = fifo.clone();
            // A reader that never gets a writer blocks for good; the test stops waiting.
            std::thread::spawn(move || {
                let mut s = String::new();
                std::fs::File::open(&fifo)
                    .unwrap()
                    .read_to_string(&mut s)
                    .unwrap();
                tx.send(s)
            });
        }
        let mut staged = Staged::new();
        staged.write(&fifo, b"{\"a\": 1}").unwrap();
        assert_eq!(
            names(dir.path()),
            ["out.json"],
            "a temporary beside the FIFO"
        );
        staged.commit().unwrap();
        let got = rx.recv_timeout(std::time::Duration::from_secs(60));
        assert_eq!(got.as_deref(), Ok("{\"a\": 1}"));
        assert!(std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo());
    }

    #[cfg(unix)]
    #[test]
    fn a_link_to_a_file_writes_the_file_and_stays_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.json");
        std::fs::write(&real, "old").unwrap();
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink("real.json", &link).unwrap();
        write_atomically(&link, b"new").unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "new");
        assert_eq!(names(dir.path()), ["link.json", "real.json"]);
    }

    #[cfg(unix)]
    #[test]
    fn new_files_follow_the_umask_replaced_ones_keep_their_mode() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
        let new = dir.path().join("new.json");
        write_atomically(&new, b"{}").unwrap();
        assert_eq!(mode(&new), target::new_file_mode());
        assert_ne!(mode(&new), 0o600, "tempfile's private mode leaked");
        let shared = dir.path().join("shared.json");
        std::fs::write(&shared, "old").unwrap();
        std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(0o664)).unwrap();
        write_atomically(&shared, b"new").unwrap();
        assert_eq!(mode(&shared), 0o664);
    }

    #[test]
    fn a_full_disk_is_said_so() {
        let e = write_error(
            Path::new("d/level_1.csv"),
            std::io::Error::from(std::io::ErrorKind::StorageFull),
        );
        let text = format!("{e:?}");
        assert!(text.contains("the disk is full"), "{text}");
        assert!(text.contains("dynid::output::write"), "{text}");
    }

    #[test]
    fn a_temporary_keeps_the_extension() {
        let dir = tempfile::tempdir().unwrap();
        let mut staged = Staged::new();
        let tmp = staged.temp_for(&dir.path().join("curves.png")).unwrap();
        assert_eq!(tmp.extension().unwrap(), "png");
        assert!(tmp.exists());
        drop(staged);
        assert!(!tmp.exists());
    }

    #[test]
    fn csv_has_header_time_and_exact_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv");
        let rec = Record {
            names: vec!["m1.x".into(), "u".into()],
            columns: vec![vec![0.1, 1.0 / 3.0], vec![-2.0, 1e-9]],
            ts: 0.01,
            t0: 0.0,
        };
        let mut staged = Staged::new();
        stage_csv(&mut staged, &path, &rec).unwrap();
        staged.commit().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t,m1.x,u");
        assert_eq!(lines[1], "0.00,0.1,-2");
        let row: Vec<f64> = lines[2].split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(row, [0.01, 1.0 / 3.0, 1e-9]);
        assert_eq!(names(dir.path()), ["a.csv"]);
    }
}
