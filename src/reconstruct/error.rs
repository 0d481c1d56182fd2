//! Why a reconstruction could not produce a skeleton.

/// A reconstruction failure; every variant is a property of the input cloud.
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
    /// The cloud is degenerate (collinear, planar, or upside down).
    #[error("{0} (silva assumes the z axis points up and the cloud holds one upright tree)")]
    Degenerate(String),
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
