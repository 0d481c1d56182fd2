//! The crate-wide error type.
//!
//! Each stage has its own typed error; [`Error`] gathers them so that the CLI
//! prints one clear line and the API maps each variant to one HTTP status.

use crate::cloud::CloudError;
use crate::reconstruct::ReconstructError;
use crate::skeleton::{SkeletonError, SkeletonJsonError};

/// Any error silva's library returns.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A point cloud could not be read.
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// Nodes do not form a valid skeleton.
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    /// A skeleton JSON document was rejected.
    #[error(transparent)]
    SkeletonJson(#[from] SkeletonJsonError),
    /// No skeleton could be reconstructed from a cloud.
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
    /// File or stream IO failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// `Result` with silva's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
