//! `silva reconstruct CLOUD [--skeleton out.(json|ply)] [--mesh out.(obj|ply|glb) --lod N]
//! [--cityjson out.city.json] [--cylinders out.csv] [--metrics out.json]`:
//! one tree's skeleton with radii, and its metrics.
//!
//! The chosen pipeline and why, and any best-effort notes, go to stderr.
//! The skeleton PLY (binary, see `silva::Skeleton::to_ply`) has `element
//! vertex` (x y z as doubles in the cloud's real coordinates, radius as
//! float) and `element edge` (vertex1 vertex2), so that it lines up with the
//! input in any viewer: the georeference stays intact.

use std::path::PathBuf;

use anyhow::{Context, bail};
use silva::cloud::{ReadOptions, read_path};
use silva::reconstruct::{Mode, Options, Reconstruction, reconstruct};

use super::outputs::{Outputs, write};

/// Arguments of `silva reconstruct`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Point cloud of one tree (XYZ, PLY, LAS or LAZ; detected from content).
    cloud: PathBuf,
    /// Pipeline: auto picks from point density and trunk coverage.
    #[arg(long, value_enum, default_value_t = Mode::Auto)]
    mode: Mode,
    #[command(flatten)]
    outputs: Outputs,
    /// Where to write the tree metrics as JSON.
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// Species, recorded in CityJSON.
    #[arg(long)]
    species: Option<String>,
    /// Refuse clouds with more points than this.
    #[arg(long, default_value_t = ReadOptions::default().max_points)]
    max_points: usize,
}

/// Reads the cloud, reconstructs, and writes the requested files.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.outputs.is_empty() && args.metrics.is_none() {
        bail!("nothing to write: give --skeleton, --mesh, --cityjson, --cylinders or --metrics");
    }
    args.outputs.validate()?;
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
    let attributes = match serde_json::to_value(&tree.metrics)? {
        serde_json::Value::Object(map) => map,
        _ => serde_json::Map::new(),
    };
    args.outputs
        .write(&tree.skeleton, args.species.clone(), attributes)?;
    if let Some(path) = &args.metrics {
        let json = serde_json::to_string_pretty(&metrics_document(&tree))?;
        write(path, (json + "\n").as_bytes())?;
    }
    Ok(())
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
