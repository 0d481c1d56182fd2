//! Why a reconstruction could not produce a skeleton.

/// A reconstruction failure; every variant is a property of the input cloud
/// (or of a pipeline this build does not provide).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReconstructError {
    /// Too few points to say anything about a tree.
    #[error("too few points for a tree: {found} (at least {needed} needed)")]
    TooFewPoints {
        /// Points after clean-up.
        found: usize,
        /// The minimum the pipeline accepts.
        needed: usize,
    },
    /// The cloud is degenerate (collinear, planar, tilted or upside down).
    #[error("{0} (silva assumes the z axis points up and the cloud holds one upright tree)")]
    Degenerate(String),
    /// The cloud holds two or more clusters too far apart to be one tree.
    #[error(
        "the cloud holds separate clusters: {share_pct:.0} % of the points lie {gap_m:.2} m from \
         the rest (silva assumes the z axis points up and the cloud holds one upright tree; split \
         the cloud into one tree per file)"
    )]
    Disconnected {
        /// Share of the points in the detached part, in percent.
        share_pct: f32,
        /// Smallest gap between the detached part and the tree, in metres.
        gap_m: f32,
    },
    /// The requested pipeline is not part of this build.
    #[error("the {0} reconstruction pipeline is not available in this build")]
    PipelineUnavailable(&'static str),
    /// Ground removal left too few points for a tree.
    #[error(
        "only {tree} points above the ground ({ground} ground points); at least {needed} needed \
         for a tree"
    )]
    NoTreeAboveGround {
        /// Points left after ground removal.
        tree: usize,
        /// Points identified as ground.
        ground: usize,
        /// The minimum the pipeline accepts.
        needed: usize,
    },
    /// A reconstruction parameter is out of its valid range.
    #[error("invalid reconstruction parameters: {0}")]
    InvalidParameter(String),
}
