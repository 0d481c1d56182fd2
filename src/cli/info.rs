//! `silva info FILE`: what a point cloud file holds, as JSON on stdout.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use silva::cloud::{ReadOptions, read_path_with_details};

/// Arguments of `silva info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Point cloud file (XYZ, PLY, LAS or LAZ; detected from content).
    file: PathBuf,
    /// Refuse files with more points than this.
    #[arg(long, default_value_t = ReadOptions::default().max_points)]
    max_points: usize,
}

/// Reads the file and prints format, point count, offset and absolute
/// bounds (plus LAS version and point format for LAS/LAZ) as one JSON object.
pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = ReadOptions {
        max_points: args.max_points,
    };
    let (cloud, details) = read_path_with_details(&args.file, &opts)
        .with_context(|| format!("{}", args.file.display()))?;
    // Readers reject empty clouds, so bounds exist.
    let (min, max) = cloud
        .absolute_bounds()
        .context("the cloud holds no points")?;
    let mut summary = serde_json::json!({
        "format": details.format,
        "points": cloud.len(),
        "offset": cloud.offset.to_array(),
        "bounds": { "min": min.to_array(), "max": max.to_array() },
    });
    if let Some(las) = details.las {
        summary["las"] = serde_json::to_value(las)?;
    }
    let mut out = std::io::stdout().lock();
    serde_json::to_writer_pretty(&mut out, &summary)?;
    writeln!(out)?;
    Ok(())
}
