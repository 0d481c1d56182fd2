//! The `silva` command line.
//!
//! `main` stays thin on purpose: it parses arguments, hands them to one
//! entry point in [`cli`], prints an error once, and picks the exit code.
//! Every subcommand's work lives in its own `cli/*.rs` file so that the
//! library stays free of process concerns (exit codes, stdout, progress bars).

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        // A closed pipe (`silva info x | head`) is a normal end, not an error.
        Err(err) if cli::is_broken_pipe(&err) => ExitCode::SUCCESS,
        Err(err) => {
            // One line, no backtrace: the chain of causes joined by ": ".
            eprintln!("silva: {err:#}");
            ExitCode::FAILURE
        }
    }
}
