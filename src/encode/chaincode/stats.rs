//! Figures for `silva eval`: chain code sizes at a resolution, in the forms
//! of the paper's Tables 3 and 5, with the measured node error and the sizes
//! of the reduced levels of detail.

use serde::Serialize;

use super::{
    ChainCode, ChainError, ChainOptions, Resolution, decode, encode, encode_order, lod_thresholds,
    reduce_lod,
};
use crate::encode::gzip_len;
use crate::skeleton::{NodeId, Skeleton};

/// Number of levels of detail reported, the full model included (as in the
/// paper's Experiment 1).
pub const LOD_LEVELS: usize = 4;

/// Sizes and error of one skeleton's chain code at one resolution.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChainStats {
    /// The resolution `r` (NaN when a voxel size was given).
    pub resolution: f32,
    /// The voxel size `d = l̄ / r`, metres.
    pub voxel_size_m: f64,
    /// Internodes of the skeleton.
    pub internodes: usize,
    /// Symbols in the DBF6 code.
    pub symbols: usize,
    /// Plain binary form ([`ChainCode::to_bytes`]), header included.
    pub bytes_binary: usize,
    /// The plain binary form through gzip at level 9.
    pub bytes_gzip: usize,
    /// Interpolative form ([`ChainCode::compress`]), header included.
    pub bytes_interpolative: usize,
    /// `bytes_interpolative / internodes`.
    pub bytes_per_internode: f64,
    /// Largest distance between a decoded node and its original, metres.
    pub max_error_m: f64,
    /// Mean distance between a decoded node and its original, metres.
    pub mean_error_m: f64,
    /// The guaranteed bound `√3·d/2`, metres.
    pub error_bound_m: f64,
    /// Reduced levels of detail at the thresholds of [`lod_thresholds`].
    pub lod: Vec<LodStats>,
}

/// Size of one reduced level of detail.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LodStats {
    /// Lateral branches with a thinner base were dropped, metres.
    pub radius_threshold_m: f32,
    /// Internodes left.
    pub internodes: usize,
    /// Symbols left.
    pub symbols: usize,
    /// Interpolative form of the reduced code, bytes.
    pub bytes_interpolative: usize,
}

/// Encodes `skeleton` at resolution `r` with the default options (predictive
/// voxels, 1 mm radius steps) and measures every form, the node error and
/// the LOD levels.
pub fn stats(skeleton: &Skeleton, resolution: f32) -> Result<ChainStats, ChainError> {
    stats_with(
        skeleton,
        &ChainOptions {
            resolution: Resolution::PerInternode(resolution),
            ..ChainOptions::default()
        },
    )
}

/// [`stats`] with any encoder options.
pub fn stats_with(skeleton: &Skeleton, opts: &ChainOptions) -> Result<ChainStats, ChainError> {
    let resolution = match opts.resolution {
        Resolution::PerInternode(r) => r,
        Resolution::VoxelSize(_) => f32::NAN,
    };
    let opts = *opts;
    let code = encode(skeleton, &opts)?;
    let binary = code.to_bytes();
    let compressed = code.compress();
    let decoded = decode(&code)?;
    let errors: Vec<f64> = encode_order(skeleton)
        .iter()
        .enumerate()
        .map(|(i, &orig)| {
            let back = decoded.position(NodeId::from_index(i)).as_dvec3();
            back.distance(skeleton.position(orig).as_dvec3())
        })
        .collect();
    let max_error_m = errors.iter().copied().fold(0.0, f64::max);
    let mean_error_m = errors.iter().sum::<f64>() / errors.len() as f64;
    let internodes = skeleton.internode_count();
    let lod = lod_thresholds(&code, LOD_LEVELS)
        .into_iter()
        .map(|t| lod_stats(&code, t))
        .collect();
    Ok(ChainStats {
        resolution,
        voxel_size_m: code.header().voxel_size_m,
        internodes,
        symbols: code.symbols().len(),
        bytes_binary: binary.len(),
        bytes_gzip: gzip_len(&binary),
        bytes_interpolative: compressed.len(),
        bytes_per_internode: compressed.len() as f64 / internodes.max(1) as f64,
        max_error_m,
        mean_error_m,
        error_bound_m: code.error_bound_m(),
        lod,
    })
}

fn lod_stats(code: &ChainCode, radius_threshold_m: f32) -> LodStats {
    let reduced = reduce_lod(code, radius_threshold_m);
    LodStats {
        radius_threshold_m,
        internodes: reduced.internode_count(),
        symbols: reduced.symbols().len(),
        bytes_interpolative: reduced.compress().len(),
    }
}
