//! `silva encode`, `silva decode` and `silva export`: move a skeleton between
//! its stored forms (LsJSON, DBF6 chain code) and its outputs.
//!
//! Inputs are recognised by content, never by name: a chain code starts with
//! the `SLVC` magic, a skeleton PLY (silva's or AdTree's) with `ply`, a silva
//! skeleton JSON has `"format":"silva-skeleton"`, anything else is parsed as
//! LsJSON (with the reader's expansion limits, so a hostile file cannot
//! expand without bound).

use std::path::{Path, PathBuf};

use anyhow::Context;
use silva::Skeleton;
use silva::encode::chaincode::{self, ChainOptions, Resolution};
use silva::encode::lsystem::{self, LsOptions};
use silva::reconstruct::radii::{self, estimate_radii};

use super::outputs::{Outputs, write};

/// Arguments of `silva encode`.
#[derive(Debug, clap::Args)]
pub struct EncodeArgs {
    /// Skeleton to encode (silva skeleton JSON or PLY, AdTree skeleton PLY,
    /// LsJSON or chain code).
    input: PathBuf,
    /// Write the L-system (LsJSON) here.
    #[arg(long)]
    lsystem: Option<PathBuf>,
    /// Write the interpolative-compressed DBF6 chain code here.
    #[arg(long)]
    chaincode: Option<PathBuf>,
    /// Chain code resolution r: voxels per mean internode length.
    #[arg(long, default_value_t = 5.0)]
    resolution: f32,
    /// LsJSON position tolerance in metres (guaranteed for every node).
    #[arg(long, default_value_t = 0.001)]
    tolerance: f32,
}

/// Arguments of `silva decode`.
#[derive(Debug, clap::Args)]
pub struct DecodeArgs {
    /// LsJSON, chain code or skeleton PLY (recognised by content).
    input: PathBuf,
    #[command(flatten)]
    outputs: Outputs,
}

/// Arguments of `silva export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// Skeleton JSON or PLY, LsJSON or chain code (recognised by content).
    input: PathBuf,
    /// Species, recorded in CityJSON.
    #[arg(long)]
    species: Option<String>,
    #[command(flatten)]
    outputs: Outputs,
}

/// Encodes a skeleton as LsJSON and/or chain code, printing sizes and errors.
pub fn encode(args: EncodeArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.lsystem.is_some() || args.chaincode.is_some(),
        "nothing to write: give --lsystem and/or --chaincode"
    );
    let skeleton = load_skeleton(&args.input)?;
    let mut summary = serde_json::Map::new();
    summary.insert("internodes".into(), skeleton.internode_count().into());
    if let Some(path) = &args.lsystem {
        let opts = LsOptions {
            tolerance_m: args.tolerance,
            ..LsOptions::default()
        };
        let ls = lsystem::encode(&skeleton, &opts);
        let text = ls.to_json();
        write(path, text.as_bytes())?;
        summary.insert("lsjson_bytes".into(), text.len().into());
        summary.insert("lsjson_max_error_m".into(), ls.error().max_m.into());
    }
    if let Some(path) = &args.chaincode {
        let opts = ChainOptions {
            resolution: Resolution::PerInternode(args.resolution),
            ..ChainOptions::default()
        };
        let code = chaincode::encode(&skeleton, &opts).context("encoding the chain code")?;
        let bytes = code.compress();
        write(path, &bytes)?;
        summary.insert("chaincode_bytes".into(), bytes.len().into());
        summary.insert(
            "chaincode_error_bound_m".into(),
            code.error_bound_m().into(),
        );
    }
    println!("{}", serde_json::Value::Object(summary));
    Ok(())
}

/// Decodes LsJSON or a chain code into the requested outputs.
pub fn decode(args: DecodeArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        !args.outputs.is_empty(),
        "nothing to write: give --skeleton, --mesh, --cityjson or --cylinders"
    );
    args.outputs.validate()?;
    let skeleton = load_skeleton(&args.input)?;
    args.outputs.write(&skeleton, None, serde_json::Map::new())
}

/// Writes meshes, CityJSON, skeleton or cylinder table from any stored form.
pub fn export(args: ExportArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        !args.outputs.is_empty(),
        "nothing to write: give --skeleton, --mesh, --cityjson or --cylinders"
    );
    args.outputs.validate()?;
    let skeleton = load_skeleton(&args.input)?;
    args.outputs
        .write(&skeleton, args.species, serde_json::Map::new())
}

/// Reads a skeleton from any of its file forms, recognised by content
/// ([`silva::encode::decode_stored`]). A skeleton without radii (AdTree's
/// PLY has none) gets the radii of an unseen trunk
/// ([`silva::reconstruct::radii::estimate_radii`]), with a note: zero radii
/// would give meshes and CityJSON solids no volume.
pub fn load_skeleton(path: &Path) -> anyhow::Result<Skeleton> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let mut skeleton =
        silva::encode::decode_stored(&bytes).with_context(|| format!("{}", path.display()))?;
    if skeleton.len() > 1 && skeleton.nodes().iter().all(|n| n.radius_m == 0.0) {
        let trunk = estimate_radii(&mut skeleton, &radii::Params::default());
        eprintln!(
            "silva: note: {}: every radius is 0 (a skeleton PLY without a radius property, \
             such as AdTree's), so the radii follow the pipe model through a DBH of {:.2} m \
             estimated from height and crown diameter (Jucker et al. 2017's angiosperm \
             allometry; {})",
            path.display(),
            trunk.dbh_m(),
            trunk.reason
        );
    }
    Ok(skeleton)
}
