//! The `vizsim` binary: parses the command line (src/cli/, one file per command) and prints
//! errors with their context on stderr with a non-zero exit status.

mod cli;

use clap::Parser;

fn main() {
    end_quietly_when_the_reader_is_gone();
    let args = cli::Cli::parse();
    if let Err(err) = cli::run(args) {
        vizsim::note!("error: {err:#}");
        std::process::exit(1);
    }
}

/// `vizsim table runs/x | head`: once the reader of standard output has gone, printing fails
/// (Rust ignores SIGPIPE, so the write returns EPIPE) and `println!` panics. A command-line
/// tool ends quietly there instead, with the status of one killed by SIGPIPE (128 + 13), as a C
/// tool would be. Any other failure to print (a full disk) is an error with status 1, not a
/// panic; so is a standard error that cannot be written. Any other panic still reports as usual.
fn end_quietly_when_the_reader_is_gone() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or_default();
        if let Some(cause) = message.strip_prefix("failed printing to stdout") {
            if cause.contains("Broken pipe") {
                std::process::exit(128 + 13);
            }
            // Any other write error (a full disk, `> /dev/full`): an error like any other, not
            // a panic. Files the command writes are written atomically, so none is half-written.
            // Not `eprintln!`: a standard error that cannot be written either (both to one full
            // log) would panic inside the hook and abort.
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "error: writing to standard output{cause}",
                cause = cause.trim_end()
            );
            std::process::exit(1);
        }
        // Standard error itself cannot be written (`2>/dev/full`; vizsim's own notes use
        // `note!`, which ignores that): a failure, but not a panic's status 101.
        if message.starts_with("failed printing to stderr") {
            std::process::exit(1);
        }
        report(info);
    }));
}
