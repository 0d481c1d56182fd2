//! Skeleton reconstruction from point clouds (issue 3).
//!
//! Will hold the dense pipeline after AdTree (lsystem-from-adtree-skeletons
//! §2.1.1; multi-temporal-tree-growth §3.2.1), the airborne pipeline after
//! Hu et al. (airborne-lidar-tree-modeling §3), radius fitting, and tree
//! metrics. Plain synchronous code: no IO.

pub mod airborne;
mod error;
pub mod ground;
pub use error::ReconstructError;
