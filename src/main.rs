//! The `vizsim` binary: parses the command line (src/cli/, one file per command) and prints
//! errors with their context on stderr with a non-zero exit status.

mod cli;

use clap::Parser;

fn main() {
    let args = cli::Cli::parse();
    if let Err(err) = cli::run(args) {
        eprintln!("error: {err:#}");
        std::process::exit(1);
    }
}
