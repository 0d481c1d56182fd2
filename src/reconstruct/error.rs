//! Why a reconstruction could not produce a skeleton.

/// A reconstruction failure; every variant but [`ReconstructError::Interrupted`]
/// is a property of the input cloud (or of a pipeline this build does not
/// provide).
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
    /// The cloud stands on two or more stems apart from each other: trees
    /// whose crowns touch, so that no gap separates them.
    #[error(
        "the cloud stands on {stems} stems: two of them {apart_m:.1} m apart, at x {x1:.2}, y \
         {y1:.2} and at x {x2:.2}, y {y2:.2}, so it holds trees whose crowns touch, or one tree \
         forked at the ground (silva assumes the z axis points up and the cloud holds one \
         upright tree; split the cloud into one tree per file)",
        x1 = .first[0],
        y1 = .first[1],
        x2 = .second[0],
        y2 = .second[1]
    )]
    SeveralStems {
        /// Stems at least a metre apart.
        stems: usize,
        /// Distance between the centres of the two largest, in metres.
        apart_m: f32,
        /// Horizontal centre of the largest stem, in the cloud's coordinates.
        first: [f64; 2],
        /// Horizontal centre of the second largest.
        second: [f64; 2],
    },
    /// The tree points span more height than any tree has.
    #[error(
        "the tree points span {height_m:.0} m in height, more than any tree ({max_m:.0} m at \
         most): remove noise returns far above or below the tree (birds, multipath; LAS classes \
         7 and 18), or check that z is in metres"
    )]
    TooTall {
        /// Height spanned by the points, in metres.
        height_m: f32,
        /// The limit, [`super::MAX_TREE_HEIGHT_M`].
        max_m: f32,
    },
    /// The points span more ground than any tree's crown.
    #[error(
        "the points span {width_m:.0} m horizontally, more than any tree ({max_m:.0} m at most): \
         the cloud holds several trees or far-off returns (split it into one tree per file), or \
         x and y are not in metres"
    )]
    TooWide {
        /// Larger side of the points' horizontal bounding box, in metres.
        width_m: f32,
        /// The limit, [`super::MAX_TREE_WIDTH_M`].
        max_m: f32,
    },
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
    /// The caller's [`crate::interrupt::Interrupt`] stopped the
    /// reconstruction at a step boundary.
    #[error("reconstruction {0}")]
    Interrupted(#[from] crate::interrupt::Interrupted),
}
