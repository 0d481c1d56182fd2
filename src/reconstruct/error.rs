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
}
