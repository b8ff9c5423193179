//! What an output path names, and whether it can be written: checked before any work.
//!
//! - A regular file (new, or existing, or reached through symbolic links) is replaced all
//!   or nothing: a temporary beside the file the links lead to, renamed over it. The links
//!   stay links.
//! - Anything else that exists — a character device (`/dev/null`), a FIFO, a socket, a
//!   process substitution `>(jq .)` (`/dev/fd/63`), `/dev/stdout` and every path through
//!   `/dev/fd/` or `/proc/` — is a stream: it is opened for writing and written through,
//!   never replaced, and its temporary lives in the system's temporary directory.
//! - Refused before the work: a directory; a missing directory; an existing file without
//!   the owner's write bit (`chmod a-w`: read-only, even for root, whom the kernel would let
//!   write); a directory without the owner's write bit (the same rule), or one where a
//!   probe file cannot be created (a read-only file system, another user's directory).

use miette::miette;
use std::path::{Component, Path, PathBuf};

/// Where and how an output is written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    /// A regular file at this path (symbolic links followed), replaced by a rename.
    File(PathBuf),
    /// A device, FIFO, socket or descriptor path: opened and written through.
    Stream(PathBuf),
}

/// The directory a file is written in (`.` for a bare file name).
pub fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Paths that name a descriptor of this process (`/dev/stdout`, `/dev/fd/N`,
/// `/proc/self/fd/N`): written through even when the descriptor is a regular file, which
/// the shell has opened (and may be appending to) already.
fn is_descriptor_path(path: &Path) -> bool {
    let s = path.as_os_str().to_string_lossy();
    ["/dev/fd/", "/dev/stdout", "/dev/stderr", "/proc/"]
        .iter()
        .any(|p| s.starts_with(p))
}

/// Classify `path`. A dangling symbolic link counts as a file at the path it leads to.
pub fn target(path: &Path) -> Target {
    if is_descriptor_path(path) {
        return Target::Stream(path.to_path_buf());
    }
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => {
            Target::File(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()))
        }
        Ok(m) if m.is_dir() => Target::File(path.to_path_buf()),
        Ok(_) => Target::Stream(path.to_path_buf()),
        Err(_) => Target::File(follow_dangling(path)),
    }
}

/// The path a chain of dangling symbolic links ends at (at most 40 links, as the kernel).
fn follow_dangling(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::read_link(&p) {
            Ok(next) => p = parent_dir(&p).join(next),
            Err(_) => break,
        }
    }
    p
}

/// The file a path names, as far as it can be resolved: the longest existing ancestor made
/// canonical (links followed), the rest joined as written (`.` dropped, `..` applied).
/// Two spellings of one file resolve alike even when its directory does not exist yet.
pub fn resolve(path: &Path) -> PathBuf {
    let path = match target(path) {
        Target::File(p) | Target::Stream(p) => p,
    };
    let abs = if path.is_absolute() {
        path
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut base = abs.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(c) = std::fs::canonicalize(base) {
            let mut out = c;
            for comp in rest.iter().rev() {
                match comp {
                    Component::ParentDir => {
                        out.pop();
                    }
                    Component::CurDir => {}
                    c => out.push(c.as_os_str()),
                }
            }
            return out;
        }
        match (base.parent(), base.components().next_back()) {
            (Some(parent), Some(last)) => {
                rest.push(last);
                base = parent;
            }
            _ => return abs.clone(),
        }
    }
}

fn mode_of(meta: &std::fs::Metadata) -> Option<u32> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        Some(meta.permissions().mode())
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        None
    }
}

/// Fail before any work if `path` cannot be written as an output: see the module
/// documentation. (Writing can still fail later, e.g. on a full disk; [`super::Staged`]
/// then leaves nothing behind.)
pub fn check_output(path: &Path, what: &str) -> miette::Result<()> {
    if path.file_name().is_none() || path.is_dir() {
        return Err(miette!(
            code = "dynid::output::is_directory",
            help = "give the path of a file (it may be inside that directory)",
            "{what} `{}` is a directory, not a file",
            path.display()
        ));
    }
    let file = match target(path) {
        Target::Stream(_) => return Ok(()),
        Target::File(f) => f,
    };
    let dir = parent_dir(&file);
    if !dir.is_dir() {
        return Err(miette!(
            code = "dynid::output::no_directory",
            help = format!("create it first (`mkdir -p {}`)", dir.display()),
            "the directory of {what} `{}` does not exist",
            path.display()
        ));
    }
    if let Ok(meta) = std::fs::metadata(&file) {
        if mode_of(&meta).is_some_and(|m| m & 0o200 == 0) {
            return Err(miette!(
                code = "dynid::output::read_only",
                help = format!(
                    "it has no write permission: choose another path, or make it writable \
                     (`chmod u+w {}`) if it may be replaced",
                    path.display()
                ),
                "{what} `{}` is read-only",
                path.display()
            ));
        }
    }
    check_writable_dir(
        dir,
        &format!("the directory of {what} `{}`", path.display()),
    )
}

/// Fail unless files can be created in the existing directory `dir`: it has the owner's
/// write bit and a probe file can be made (and is removed at once).
pub fn check_writable_dir(dir: &Path, what: &str) -> miette::Result<()> {
    let refuse = |why: String| {
        miette!(
            code = "dynid::output::read_only",
            help = format!(
                "write somewhere else, or make it writable (`chmod u+w {}`)",
                dir.display()
            ),
            "{what} (`{}`) is not writable: {why}",
            dir.display()
        )
    };
    let meta = std::fs::metadata(dir).map_err(|e| refuse(e.to_string()))?;
    if mode_of(&meta).is_some_and(|m| m & 0o200 == 0) {
        return Err(refuse("it has no write permission".into()));
    }
    tempfile::Builder::new()
        .prefix(".dynid-probe.")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| refuse(e.to_string()))
}

/// Refuse, before any work, an output directory `dir` that exists and is not a directory
/// (or whose nearest existing ancestor is not one), or where files cannot be created.
pub fn check_out_dir(dir: &Path, flag: &str) -> miette::Result<()> {
    let mut p = Some(dir);
    while let Some(d) = p {
        let d = if d.as_os_str().is_empty() {
            Path::new(".")
        } else {
            d
        };
        if let Ok(meta) = std::fs::metadata(d) {
            if !meta.is_dir() {
                return Err(miette!(
                    code = "dynid::output::not_a_directory",
                    help = format!(
                        "`{flag}` names the directory that receives the files: give a new or \
                         an existing directory"
                    ),
                    "`{}` is a file, not a directory",
                    d.display()
                ));
            }
            return check_writable_dir(d, &format!("the directory of `{flag}`"));
        }
        p = d.parent();
    }
    Ok(())
}

/// The mode new files get: `0o666` less the process's umask (`0o644` under `umask 022`).
pub fn new_file_mode() -> u32 {
    static MODE: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *MODE.get_or_init(|| 0o666 & !umask())
}

/// The process's umask: from `/proc/self/status` where the kernel shows it (Linux 4.7 and
/// later), else by setting and restoring it (the usual trick; only this module creates
/// files, so nothing is created with the momentary mask).
fn umask() -> u32 {
    if let Ok(status) = std::fs::read_to_string("/proc/self/status") {
        if let Some(m) = status
            .lines()
            .find_map(|l| l.strip_prefix("Umask:"))
            .and_then(|v| u32::from_str_radix(v.trim(), 8).ok())
        {
            return m;
        }
    }
    #[cfg(unix)]
    {
        // SAFETY: `umask` cannot fail; the old mask is restored at once.
        unsafe {
            let old = libc::umask(0o022);
            libc::umask(old);
            old as u32
        }
    }
    #[cfg(not(unix))]
    {
        0o022
    }
}

/// Bytes free for an unprivileged user on the file system of `dir`, if known.
pub fn free_bytes(dir: &Path) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
        // SAFETY: `c` is a valid NUL-terminated path; `st` is written by statvfs.
        unsafe {
            let mut st: libc::statvfs = std::mem::zeroed();
            if libc::statvfs(c.as_ptr(), &mut st) != 0 {
                return None;
            }
            #[allow(clippy::unnecessary_cast)]
            Some((st.f_bavail as u64).saturating_mul(st.f_frsize as u64))
        }
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        None
    }
}

/// Refuse before the work if `bytes` (an estimate of what will be written into `dir`, or
/// its nearest existing ancestor) exceed the free space there.
pub fn check_space(dir: &Path, bytes: u64, what: &str) -> miette::Result<()> {
    let existing = dir
        .ancestors()
        .map(|d| {
            if d.as_os_str().is_empty() {
                Path::new(".")
            } else {
                d
            }
        })
        .find(|d| d.is_dir())
        .unwrap_or(Path::new("."));
    match free_bytes(existing) {
        Some(free) if free < bytes => Err(miette!(
            code = "dynid::output::no_space",
            help = "free some space, write elsewhere (`--out`), or ask for less (a shorter \
                    `--duration`, fewer levels, a longer `--sample`)",
            "{what} need about {} but only {} are free in `{}`",
            human(bytes),
            human(free),
            existing.display()
        )),
        _ => Ok(()),
    }
}

/// A byte count for people: `1.6 GB`, `512 kB` (powers of 1000).
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..1_000 => format!("{bytes} B"),
        1_000..1_000_000 => format!("{:.0} kB", b / 1e3),
        1_000_000..1_000_000_000 => format!("{:.0} MB", b / 1e6),
        _ => format!("{:.1} GB", b / 1e9),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_checked_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let e = check_output(&dir.path().join("nope").join("r.html"), "the report")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the directory of the report") && e.contains("does not exist"),
            "{e}"
        );
        let e = check_output(dir.path(), "the report")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a directory"), "{e}");
        assert!(check_output(&dir.path().join("r.html"), "the report").is_ok());
    }

    #[cfg(unix)]
    #[test]
    fn read_only_files_and_directories_are_refused() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("r.json");
        std::fs::write(&f, "{}").unwrap();
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o444)).unwrap();
        let e = check_output(&f, "the JSON output").unwrap_err().to_string();
        assert!(e.contains("is read-only"), "{e}");
        let sub = dir.path().join("ro");
        std::fs::create_dir(&sub).unwrap();
        std::fs::set_permissions(&sub, std::fs::Permissions::from_mode(0o555)).unwrap();
        let e = check_output(&sub.join("r.json"), "the JSON output")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is not writable"), "{e}");
        let e = check_out_dir(&sub.join("new"), "--out")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is not writable"), "{e}");
        // Nothing was left by the probe.
        std::fs::set_permissions(&sub, std::fs::Permissions::from_mode(0o755)).unwrap();
        assert_eq!(std::fs::read_dir(&sub).unwrap().count(), 0);
    }

    #[cfg(unix)]
    #[test]
    fn devices_and_descriptors_are_streams_links_lead_to_files() {
        assert_eq!(
            target(Path::new("/dev/null")),
            Target::Stream("/dev/null".into())
        );
        assert!(matches!(
            target(Path::new("/dev/stdout")),
            Target::Stream(_)
        ));
        assert!(matches!(target(Path::new("/dev/fd/1")), Target::Stream(_)));
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.json");
        std::fs::write(&real, "{}").unwrap();
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        assert_eq!(
            target(&link),
            Target::File(std::fs::canonicalize(&real).unwrap())
        );
        let dangling = dir.path().join("dangling.json");
        std::os::unix::fs::symlink("later.json", &dangling).unwrap();
        assert_eq!(
            target(&dangling),
            Target::File(dir.path().join("later.json"))
        );
    }

    #[test]
    fn spellings_of_a_missing_path_resolve_alike() {
        let dir = tempfile::tempdir().unwrap();
        let a = resolve(&dir.path().join("k").join("level_1.csv"));
        let b = resolve(
            &dir.path()
                .join("k")
                .join(".")
                .join("x")
                .join("..")
                .join("level_1.csv"),
        );
        assert_eq!(a, b);
        assert!(a.ends_with("k/level_1.csv"));
    }

    #[test]
    fn a_huge_estimate_is_refused_with_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let e = check_space(dir.path(), u64::MAX / 2, "the level files")
            .unwrap_err()
            .to_string();
        assert!(e.contains("need about") && e.contains("GB"), "{e}");
        assert!(check_space(dir.path(), 1, "the level files").is_ok());
        assert_eq!(human(1_600_000_000), "1.6 GB");
    }
}
