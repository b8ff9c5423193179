//! The `dynid` command line. Errors are rendered with miette; library errors stay typed
//! until here.

mod cli;

use clap::Parser;

/// mimalloc, not the system allocator: a structure search frees and allocates many
/// multi-megabyte buffers on several threads, which fragmented glibc's arenas (the peak
/// memory of `diagnose` with each allocator: docs/performance.md, `diagnose_chain`).
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    restore_sigpipe();
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(report) => {
            eprintln!("{report:?}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Rust ignores SIGPIPE, so printing into a closed pipe (`dynid compile m.dyn | head -1`)
/// would make `println!` panic. A command-line tool should end quietly instead, as `cat`
/// does: restore the default action (the process ends when the reader has gone).
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any thread exists; SIG_DFL is a valid
    // action for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
