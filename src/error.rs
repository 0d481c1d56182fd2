//! The crate-wide error type.
//!
//! Each stage has its own typed error; [`Error`] gathers them so that the CLI
//! prints one clear line and the API maps each variant to one HTTP status.

use crate::cityjson::CityJsonError;
use crate::cloud::CloudError;
use crate::encode::chaincode::ChainError;
use crate::encode::lsystem::LsError;
use crate::reconstruct::ReconstructError;
use crate::skeleton::{SkeletonError, SkeletonJsonError, SkeletonPlyError};

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
    /// A skeleton PLY file was rejected.
    #[error(transparent)]
    SkeletonPly(#[from] SkeletonPlyError),
    /// No skeleton could be reconstructed from a cloud.
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
    /// A chain code could not be encoded or decoded.
    #[error(transparent)]
    ChainCode(#[from] ChainError),
    /// An LsJSON document was rejected.
    #[error(transparent)]
    LsJson(#[from] LsError),
    /// A CityJSON or CityJSONSeq output could not be written.
    #[error(transparent)]
    CityJson(#[from] CityJsonError),
    /// File or stream IO failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// `Result` with silva's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
