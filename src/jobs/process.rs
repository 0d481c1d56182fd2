//! The processing step of the service: bytes in, stored forms out.
//!
//! [`prepare_scan`] runs at upload time (so a broken file is refused with a
//! 422 before anything is stored) and keeps the cloud LAZ-compressed;
//! [`process`] runs in a job and turns that LAZ into everything the store
//! keeps for a model. Both are synchronous and CPU-bound: callers run them
//! off the async runtime.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::record::{ChainCodeRecord, LsystemRecord, ModelRecord};
use super::{Progress, Stage};
use crate::cloud::{self, CloudError, ReadOptions};
use crate::encode::chaincode::{self, ChainError, ChainOptions};
use crate::encode::lsystem::{self, LsOptions};
use crate::reconstruct::{self, Mode, ReconstructError, Reconstruction};
use crate::skeleton::NodeId;
use crate::store::NewModel;

/// Options of a reconstruction job, stored with the job as JSON.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JobOptions {
    /// Pipeline to run.
    #[serde(default)]
    pub mode: Mode,
    /// CRS of the cloud, recorded on the skeleton's anchor.
    #[serde(default)]
    pub crs: Option<String>,
}

/// Why a job failed.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// The stored scan could not be read back.
    #[error(transparent)]
    Cloud(#[from] CloudError),
    /// No tree could be reconstructed from the cloud.
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
    /// The skeleton could not be chain-coded.
    #[error("chain code: {0}")]
    ChainCode(#[from] ChainError),
    /// The job's options could not be parsed.
    #[error("job options: {0}")]
    Options(String),
    /// The scan row is gone (its tree was deleted).
    #[error("the scan of this job no longer exists")]
    ScanMissing,
    /// The database failed.
    #[error("{0}")]
    Store(String),
    /// Another worker took the job over (this one was presumed dead).
    #[error("the job's lease was lost to another worker")]
    LeaseLost,
    /// The job ran past its time limit and was stopped.
    #[error(
        "stopped during {stage}{}: the job ran past its time limit of {limit_s} s (silva serve \
         --job-time-limit-secs); try a smaller or cleaner cloud, or ask for a longer limit",
        .step.map(|step| format!(" (before {step})")).unwrap_or_default()
    )]
    TimedOut {
        /// The limit, in seconds.
        limit_s: f64,
        /// What the job was doing at its deadline ([`Stage::name`]).
        stage: &'static str,
        /// The step within the stage that the deadline stopped, when the
        /// stage's own check caught it.
        step: Option<&'static str>,
    },
    /// The processing step panicked; a bug, reported rather than hidden.
    #[error("processing panicked: {0}")]
    Panicked(String),
}

/// An upload, validated and ready to store.
#[derive(Debug, Clone)]
pub struct PreparedScan {
    /// Detected format of the upload, lowercase (`laz`, `xyz`, …).
    pub format: String,
    /// Points read.
    pub point_count: i64,
    /// The cloud as LAZ.
    pub cloud_laz: Vec<u8>,
}

/// Reads an upload in any supported format (at most `max_points` points)
/// and compresses it to LAZ for storage.
pub fn prepare_scan(bytes: &[u8], max_points: usize) -> Result<PreparedScan, CloudError> {
    let (cloud, format) = cloud::read_bytes(bytes, &ReadOptions { max_points })?;
    if cloud.is_empty() {
        return Err(CloudError::Empty(format));
    }
    Ok(PreparedScan {
        format: format.to_string().to_ascii_lowercase(),
        point_count: i64::try_from(cloud.len()).unwrap_or(i64::MAX),
        cloud_laz: cloud::to_laz_bytes(&cloud)?,
    })
}

/// Reconstructs the tree in a stored scan and encodes it: the skeleton JSON,
/// LsJSON and compressed chain code, with their parameters and error bounds,
/// the tree metrics and the trunk base location. Stops with
/// [`JobError::TimedOut`] at the first stage boundary past the deadline of
/// `progress`, or at the first step boundary within reconstruction and
/// L-system encoding (see [`crate::interrupt`]).
pub fn process(
    cloud_laz: &[u8],
    options: &JobOptions,
    max_points: usize,
    progress: &Progress,
) -> Result<NewModel, JobError> {
    progress.enter(Stage::Reading)?;
    let (cloud, _) = cloud::read_bytes(cloud_laz, &ReadOptions { max_points })?;
    progress.enter(Stage::Reconstructing)?;
    let tree = reconstruct_tree(&cloud, options, progress)?;
    progress.enter(Stage::EncodingLsystem)?;
    let mut skeleton = tree.skeleton;
    if options.crs.is_some() {
        let mut anchor = skeleton.anchor().clone();
        anchor.crs.clone_from(&options.crs);
        skeleton.set_anchor(anchor);
    }
    let ls_options = LsOptions::default();
    let lsjson = lsystem::encode_within(&skeleton, &ls_options, &progress.interrupt())
        .map_err(|interrupted| progress.timed_out_at(interrupted))?;
    progress.enter(Stage::EncodingChainCode)?;
    let chain_options = ChainOptions::default();
    let chain = chaincode::encode(&skeleton, &chain_options)?;
    progress.enter(Stage::Finishing)?;
    let record = ModelRecord {
        mode: Some(tree.mode),
        mode_reason: Some(tree.mode_reason),
        notes: tree.notes,
        lsystem: Some(LsystemRecord {
            tolerance_m: ls_options.tolerance_m,
            radius_tolerance_m: ls_options.radius_tolerance_m,
            error: *lsjson.error(),
        }),
        chaincode: Some(ChainCodeRecord {
            voxel_size_m: chain.header().voxel_size_m,
            resolution: chain.header().resolution,
            radius_step_m: chain.header().radius_step_m,
            error_bound_m: chain.error_bound_m(),
        }),
    };
    let location: DVec3 = skeleton.absolute_position(NodeId::ROOT);
    Ok(NewModel {
        lsystem: lsjson.to_json(),
        chaincode: chain.compress(),
        skeleton: skeleton.to_json(),
        parameters: to_json(&record)?,
        metrics: to_json(&tree.metrics)?,
        internodes: i64::try_from(skeleton.internode_count()).unwrap_or(i64::MAX),
        location: location.to_array(),
        crs: skeleton.anchor().crs.clone(),
        height_m: f64::from(tree.metrics.height_m),
    })
}

/// The reconstruction stage: stops at the first step boundary of the
/// pipeline past the deadline of `progress`.
fn reconstruct_tree(
    cloud: &cloud::PointCloud,
    options: &JobOptions,
    progress: &Progress,
) -> Result<Reconstruction, JobError> {
    let reconstruct_options = reconstruct::Options {
        mode: options.mode,
        interrupt: progress.interrupt(),
        ..reconstruct::Options::default()
    };
    reconstruct::reconstruct(cloud, &reconstruct_options).map_err(|e| match e {
        ReconstructError::Interrupted(interrupted) => progress.timed_out_at(interrupted),
        other => JobError::Reconstruct(other),
    })
}

/// `value` as JSON text for the store.
fn to_json(value: &impl Serialize) -> Result<String, JobError> {
    serde_json::to_string(value).map_err(|e| JobError::Store(e.to_string()))
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use glam::Vec3;

    use super::*;

    /// A stem 3 m tall: a few hundred milliseconds of work.
    fn stem() -> cloud::PointCloud {
        let points = (0..3000)
            .map(|i| {
                let a = i as f32 * 2.399_963;
                Vec3::new(0.1 * a.cos(), 0.1 * a.sin(), 3.0 * i as f32 / 3000.0)
            })
            .collect();
        cloud::PointCloud::from_points(DVec3::ZERO, points)
    }

    /// A deadline that passes once reconstruction has started stops it at
    /// its next step boundary, not at the end of the stage, and the error
    /// names the step.
    #[test]
    fn a_deadline_inside_reconstruction_stops_it_at_a_step() {
        let mut progress = Progress::with_limit(Some(Duration::from_secs(3600)));
        progress.enter(Stage::Reconstructing).unwrap();
        progress.expire_now();
        let err = reconstruct_tree(&stem(), &JobOptions::default(), &progress).unwrap_err();
        assert!(
            matches!(
                err,
                JobError::TimedOut {
                    stage: "reconstruction",
                    step: Some("stray-return removal"),
                    ..
                }
            ),
            "{err}"
        );
        assert!(
            err.to_string()
                .starts_with("stopped during reconstruction (before stray-return removal): "),
            "{err}"
        );
    }

    #[test]
    fn a_job_past_its_deadline_stops_at_the_next_stage() {
        let laz = cloud::to_laz_bytes(&stem()).unwrap();
        let options = JobOptions::default();
        let late = Progress::with_limit(Some(Duration::ZERO));
        let err = process(&laz, &options, 10_000, &late).unwrap_err();
        assert!(
            matches!(
                err,
                JobError::TimedOut {
                    stage: "reading the scan",
                    ..
                }
            ),
            "{err}"
        );
        let model = process(&laz, &options, 10_000, &Progress::default()).unwrap();
        assert!(model.internodes > 0);
    }
}
