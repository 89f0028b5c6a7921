//! The `matedit` command line: parses the arguments, calls the library, reports.
//!
//! Exit codes: 0 success, 2 bad usage or bad input (clap's usage errors, and every
//! [`matedit::Error::is_input_error`]), 1 runtime failures (no GPU for `--device gpu`, a
//! device error, a failed write). Errors are printed as one line on stderr; no output file
//! is left behind by a failed run.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // Without it the Vulkan loader prints "error: XDG_RUNTIME_DIR is invalid" lines
        // that look like matedit's own errors; a headless run has no use for the variable.
        // SAFETY: no other thread exists yet.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    if std::env::var_os("RUST_BACKTRACE").is_none() {
        // A bug is still a bug, but the user gets one line, not a backtrace dump.
        std::panic::set_hook(Box::new(|info| {
            let msg = info.to_string().replace('\n', " ");
            eprintln!("error: internal error (please report it): {msg}");
        }));
    }
    let cli = cli::Cli::parse();
    match cli.run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.error);
            ExitCode::from(f.code)
        }
    }
}
