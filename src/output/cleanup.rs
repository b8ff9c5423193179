//! Temporaries removed when the process is interrupted (SIGINT, SIGTERM, SIGHUP).
//!
//! Every temporary file of [`super::Staged`] (and an output directory a run created) is
//! registered here while it exists. The first registration installs a handler for the
//! three signals that unlinks the registered files, removes the registered directories if
//! they are empty, and ends the process with the exit code `128 + signal` (130 for Ctrl-C),
//! as a shell reports a process ended by that signal. A signal that was ignored when the
//! handler would be installed (`nohup` ignores SIGHUP) stays ignored.
//!
//! A signal handler may only call async-signal-safe functions (`unlink`, `rmdir`,
//! `_exit`) and must not take a lock or allocate, so the paths live in fixed tables of
//! atomic pointers to C strings made when they are registered. A string is never freed once
//! published: the handler may be reading it on another thread at any moment. That costs
//! one path's bytes per output file of a run, for the life of the process.

use std::ffi::{c_char, CString};
use std::path::Path;
use std::sync::atomic::{AtomicPtr, Ordering};

/// Files (temporaries) and directories removed by the handler. A path beyond the table's
/// size is not registered: it is still removed on every normal exit and error, only not on
/// a signal.
const SLOTS: usize = 1024;

static FILES: [AtomicPtr<c_char>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];
static DIRS: [AtomicPtr<c_char>; 16] = [const { AtomicPtr::new(std::ptr::null_mut()) }; 16];

/// A registration: forget it (the path was moved into place or deleted) by dropping it.
#[derive(Debug)]
pub struct Registered {
    table: &'static [AtomicPtr<c_char>],
    slot: Option<usize>,
}

impl Drop for Registered {
    fn drop(&mut self) {
        if let Some(i) = self.slot {
            // The string stays allocated (see the module documentation).
            self.table[i].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }
}

/// Remove the temporary `path` if the process is interrupted before the registration is
/// dropped.
pub fn register_file(path: &Path) -> Registered {
    register(&FILES, path)
}

/// Remove the directory `path` (if it is empty by then) if the process is interrupted
/// before the registration is dropped.
pub fn register_dir(path: &Path) -> Registered {
    register(&DIRS, path)
}

fn register(table: &'static [AtomicPtr<c_char>], path: &Path) -> Registered {
    install();
    let slot = c_path(path).and_then(|c| {
        let p = c.into_raw();
        let slot = table.iter().position(|s| {
            s.compare_exchange(std::ptr::null_mut(), p, Ordering::SeqCst, Ordering::SeqCst)
                .is_ok()
        });
        if slot.is_none() {
            // SAFETY: `p` came from `CString::into_raw` just above and was never published.
            drop(unsafe { CString::from_raw(p) });
        }
        slot
    });
    Registered { table, slot }
}

#[cfg(unix)]
fn c_path(path: &Path) -> Option<CString> {
    use std::os::unix::ffi::OsStrExt;
    // A relative path stays right: nothing in dynid changes the working directory.
    CString::new(path.as_os_str().as_bytes()).ok()
}

#[cfg(not(unix))]
fn c_path(_: &Path) -> Option<CString> {
    None
}

#[cfg(unix)]
fn install() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            // SAFETY: `on_signal` only calls async-signal-safe functions and reads atomics;
            // the structs are zeroed (a valid `sigaction`) and filled before use.
            unsafe {
                let mut old: libc::sigaction = std::mem::zeroed();
                let mut new: libc::sigaction = std::mem::zeroed();
                new.sa_sigaction = on_signal as *const () as libc::sighandler_t;
                libc::sigemptyset(&mut new.sa_mask);
                if libc::sigaction(sig, &new, &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN {
                    libc::sigaction(sig, &old, std::ptr::null_mut());
                }
            }
        }
    });
}

#[cfg(not(unix))]
fn install() {}

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    for s in &FILES {
        let p = s.load(Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: a published pointer is a NUL-terminated string that is never freed.
            unsafe { libc::unlink(p) };
        }
    }
    for s in &DIRS {
        let p = s.load(Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: as above.
            unsafe { libc::rmdir(p) };
        }
    }
    // SAFETY: `_exit` is async-signal-safe and ends the process without running anything.
    unsafe { libc::_exit(128 + sig) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_registration_frees_its_slot() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.tmp");
        let r = register_file(&path);
        let i = r.slot.unwrap();
        assert!(!FILES[i].load(Ordering::SeqCst).is_null());
        drop(r);
        assert!(FILES[i].load(Ordering::SeqCst).is_null());
    }
}
