//! `silva info FILE`: what a point cloud file holds, as JSON on stdout.

use std::path::PathBuf;

/// Arguments of `silva info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Point cloud file (XYZ, PLY, LAS or LAZ; detected from content).
    file: PathBuf,
}

/// Reads the file and prints its summary.
pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args.file;
    anyhow::bail!("not yet implemented")
}
