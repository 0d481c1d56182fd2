//! `silva reconstruct CLOUD --skeleton out.(json|ply) [--metrics out.json]`:
//! one tree's skeleton with radii, and its metrics.
//!
//! The chosen pipeline and why, and any best-effort notes, go to stderr.
//! The skeleton PLY has `element vertex` (x y z as doubles in the cloud's
//! real coordinates, radius as float) and `element edge` (vertex1 vertex2),
//! so that it lines up with the input in any viewer: the georeference stays
//! intact.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use silva::Skeleton;
use silva::cloud::{ReadOptions, read_path};
use silva::reconstruct::{Mode, Options, Reconstruction, reconstruct};

/// Arguments of `silva reconstruct`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Point cloud of one tree (XYZ, PLY, LAS or LAZ; detected from content).
    cloud: PathBuf,
    /// Pipeline: auto picks from point density and trunk coverage.
    #[arg(long, value_enum, default_value_t = Mode::Auto)]
    mode: Mode,
    /// Where to write the skeleton: `.json` (silva skeleton) or `.ply`.
    #[arg(long)]
    skeleton: PathBuf,
    /// Where to write the tree metrics as JSON.
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// Refuse clouds with more points than this.
    #[arg(long, default_value_t = ReadOptions::default().max_points)]
    max_points: usize,
}

/// Skeleton file formats, chosen by extension.
enum SkeletonFormat {
    Json,
    Ply,
}

/// Reads the cloud, reconstructs, and writes the requested files.
pub fn run(args: Args) -> anyhow::Result<()> {
    let format = skeleton_format(&args.skeleton)?;
    let opts = ReadOptions {
        max_points: args.max_points,
    };
    let (cloud, _) =
        read_path(&args.cloud, &opts).with_context(|| format!("{}", args.cloud.display()))?;
    let options = Options {
        mode: args.mode,
        ..Options::default()
    };
    let tree = reconstruct(&cloud, &options)
        .with_context(|| format!("reconstructing {}", args.cloud.display()))?;
    eprintln!("silva: mode {} ({})", tree.mode.name(), tree.mode_reason);
    for note in &tree.notes {
        eprintln!("silva: note: {note}");
    }
    let text = match format {
        SkeletonFormat::Json => tree.skeleton.to_json(),
        SkeletonFormat::Ply => skeleton_ply(&tree.skeleton),
    };
    std::fs::write(&args.skeleton, text)
        .with_context(|| format!("writing {}", args.skeleton.display()))?;
    if let Some(path) = &args.metrics {
        let json = serde_json::to_string_pretty(&metrics_document(&tree))?;
        std::fs::write(path, json + "\n").with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn skeleton_format(path: &Path) -> anyhow::Result<SkeletonFormat> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("json") => Ok(SkeletonFormat::Json),
        Some("ply") => Ok(SkeletonFormat::Ply),
        _ => bail!(
            "{}: the skeleton file must end in .json or .ply",
            path.display()
        ),
    }
}

/// The metrics file: metrics plus how they were obtained.
fn metrics_document(tree: &Reconstruction) -> serde_json::Value {
    let base = tree.skeleton.anchor().origin;
    serde_json::json!({
        "mode": tree.mode,
        "mode_reason": tree.mode_reason,
        "notes": tree.notes,
        "trunk_base": [base.x, base.y, base.z],
        "metrics": tree.metrics,
    })
}

/// ASCII PLY with absolute vertex coordinates (doubles) and radii.
fn skeleton_ply(skeleton: &Skeleton) -> String {
    let mut out = String::new();
    // Writing to a String cannot fail.
    let _ = write!(
        out,
        "ply\nformat ascii 1.0\ncomment silva skeleton; coordinates in the cloud's CRS\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property float radius\nelement edge {}\nproperty int vertex1\nproperty int vertex2\n\
         end_header\n",
        skeleton.len(),
        skeleton.internode_count()
    );
    for id in skeleton.ids() {
        let p = skeleton.absolute_position(id);
        let _ = writeln!(out, "{} {} {} {}", p.x, p.y, p.z, skeleton.radius(id));
    }
    for (parent, child) in skeleton.internodes() {
        let _ = writeln!(out, "{} {}", parent.index(), child.index());
    }
    out
}
