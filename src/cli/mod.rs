//! Subcommands of the `silva` binary: argument definitions and dispatch.
//!
//! Each subcommand lives in its own file with an `Args` struct and a `run`
//! function; this file only lists them.

use clap::{Parser, Subcommand};

mod codec;
mod eval;
mod info;
mod outputs;
mod reconstruct;
mod serve;
mod synth;

/// silva: tree skeletons from LiDAR point clouds.
#[derive(Debug, Parser)]
#[command(version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print format, point count, bounding box and offset of a point cloud as JSON.
    Info(info::Args),
    /// Generate a synthetic tree with its true skeleton and a simulated TLS or ALS scan.
    Synth(synth::Args),
    /// Reconstruct one tree's skeleton with radii and its metrics.
    Reconstruct(reconstruct::Args),
    /// Encode a skeleton as LsJSON and/or a compressed DBF6 chain code.
    Encode(codec::EncodeArgs),
    /// Decode LsJSON or a chain code (recognised by content) to a skeleton, mesh or CityJSON.
    Decode(codec::DecodeArgs),
    /// Export a skeleton, LsJSON or chain code to meshes, CityJSON or a cylinder table.
    Export(codec::ExportArgs),
    /// Measure speed and accuracy on a folder of clouds and on synthetic trees.
    Eval(eval::Args),
    /// Run the REST service (SQLite in the working directory unless DATABASE_URL says otherwise).
    Serve(Box<serve::Args>),
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Info(args) => info::run(args),
        Command::Synth(args) => synth::run(args),
        Command::Reconstruct(args) => reconstruct::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Encode(args) => codec::encode(args),
        Command::Decode(args) => codec::decode(args),
        Command::Export(args) => codec::export(args),
        Command::Serve(args) => serve::run(*args),
    }
}

/// True when the error is a write to a closed pipe.
pub fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|e| {
        e.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
