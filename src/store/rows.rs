//! Rows read from and written to the store.

use serde::{Deserialize, Serialize};
use uuid::Uuid;

/// A row of `trees`.
#[derive(Debug, Clone, PartialEq, sqlx::FromRow)]
pub struct TreeRow {
    /// Tree id (UUIDv7).
    pub id: Uuid,
    /// The inventory's own id.
    pub external_id: Option<String>,
    /// Species name as given at ingest.
    pub species: Option<String>,
    /// Coordinate reference system of the location.
    pub crs: Option<String>,
    /// Trunk base x, absolute; `None` before the first model.
    pub x: Option<f64>,
    /// Trunk base y, absolute.
    pub y: Option<f64>,
    /// Trunk base z, absolute.
    pub z: Option<f64>,
    /// Tree height in metres from the current model.
    pub height_m: Option<f64>,
    /// Metrics JSON of the current model.
    pub metrics: Option<String>,
    /// The current model.
    pub model_id: Option<Uuid>,
    /// Parameters JSON (the reconstruction record) of the current model.
    pub model_parameters: Option<String>,
    /// Incremented on every change.
    pub version: i64,
    /// Creation time, Unix ms.
    pub created_at_ms: i64,
    /// Last change, Unix ms.
    pub updated_at_ms: i64,
}

impl TreeRow {
    /// The trunk base when the tree has a model.
    pub fn location(&self) -> Option<[f64; 3]> {
        Some([self.x?, self.y?, self.z?])
    }
}

/// Lifecycle of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    /// Waiting for a worker.
    Queued,
    /// A worker holds its lease.
    Running,
    /// Finished; the model is stored.
    Succeeded,
    /// Finished with an error; can be retried.
    Failed,
}

impl JobState {
    /// The state's name in the database.
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
        }
    }

    /// True for succeeded and failed.
    pub fn is_terminal(self) -> bool {
        matches!(self, JobState::Succeeded | JobState::Failed)
    }
}

impl std::str::FromStr for JobState {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s {
            "queued" => JobState::Queued,
            "running" => JobState::Running,
            "succeeded" => JobState::Succeeded,
            "failed" => JobState::Failed,
            other => return Err(format!("unknown job state {other:?}")),
        })
    }
}

/// A row of `jobs`.
#[derive(Debug, Clone, PartialEq, sqlx::FromRow)]
pub struct JobRow {
    /// Job id.
    pub id: Uuid,
    /// What the job does (`reconstruct`).
    pub kind: String,
    /// `queued`, `running`, `succeeded` or `failed`; see [`JobRow::state`].
    #[sqlx(rename = "state")]
    pub state_name: String,
    /// 0 to 1.
    pub progress: f64,
    /// Executions started so far.
    pub attempts: i32,
    /// Why the last execution failed.
    pub error: Option<String>,
    /// The worker holding the lease.
    pub lease_owner: Option<String>,
    /// When the lease ends, Unix ms.
    pub lease_expires_ms: Option<i64>,
    /// The tree the job reconstructs.
    pub tree_id: Uuid,
    /// The scan it reconstructs from.
    pub scan_id: Uuid,
    /// Reconstruction options, JSON.
    pub options: String,
    /// The model it produced.
    pub model_id: Option<Uuid>,
    /// Creation time, Unix ms.
    pub created_at_ms: i64,
    /// Last change, Unix ms.
    pub updated_at_ms: i64,
    /// Start of the current or last execution, Unix ms.
    pub started_at_ms: Option<i64>,
    /// End of the last execution, Unix ms.
    pub finished_at_ms: Option<i64>,
}

impl JobRow {
    /// The parsed state; an unknown name (a newer schema) reads as failed.
    pub fn state(&self) -> JobState {
        self.state_name.parse().unwrap_or(JobState::Failed)
    }
}

/// What one ingest stores.
#[derive(Debug, Clone, Default)]
pub struct NewIngest {
    /// The inventory's own id; an existing one attaches the scan to that tree.
    pub external_id: Option<String>,
    /// Species name.
    pub species: Option<String>,
    /// Coordinate reference system of the cloud.
    pub crs: Option<String>,
    /// Acquisition date (ISO 8601).
    pub acquired: Option<String>,
    /// Where the scan comes from.
    pub source: Option<String>,
    /// Format of the upload (`laz`, `xyz`, …).
    pub format: String,
    /// Points in the cloud.
    pub point_count: i64,
    /// The cloud, LAZ-compressed.
    pub cloud_laz: Vec<u8>,
    /// Reconstruction options, JSON.
    pub options: String,
    /// The upload's idempotency key, if it sent one.
    pub idempotency: Option<Idempotency>,
}

/// An upload's `Idempotency-Key` and the fingerprint of its request: sent
/// again with the same fingerprint, the key finds the first upload
/// ([`crate::store::Store::ingested_by_key`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Idempotency {
    /// The client's key.
    pub key: String,
    /// SHA-256 of the request's metadata and body, hex.
    pub fingerprint: String,
    /// When the key's lifetime began, in ms since the Unix epoch: an upload
    /// stored before it no longer holds the key (`i64::MIN`: keys never
    /// expire).
    pub not_before_ms: i64,
}

/// What a finished reconstruction stores.
#[derive(Debug, Clone)]
pub struct NewModel {
    /// Skeleton JSON.
    pub skeleton: String,
    /// LsJSON.
    pub lsystem: String,
    /// Compressed chain code.
    pub chaincode: Vec<u8>,
    /// The reconstruction record (`jobs::ModelRecord`), JSON.
    pub parameters: String,
    /// Tree metrics, JSON.
    pub metrics: String,
    /// Internodes in the skeleton.
    pub internodes: i64,
    /// Trunk base, absolute.
    pub location: [f64; 3],
    /// CRS of the skeleton's anchor.
    pub crs: Option<String>,
    /// Tree height in metres.
    pub height_m: f64,
}

/// A stored model column that is served as it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ModelColumn {
    /// silva skeleton JSON.
    Skeleton,
    /// LsJSON.
    LSystem,
    /// Compressed DBF6 chain code.
    ChainCode,
}

impl ModelColumn {
    /// The column's name.
    pub fn name(self) -> &'static str {
        match self {
            ModelColumn::Skeleton => "skeleton",
            ModelColumn::LSystem => "lsystem",
            ModelColumn::ChainCode => "chaincode",
        }
    }
}

/// Filters of a tree listing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TreeFilter {
    /// `[min_x, min_y, max_x, max_y]` in the trees' CRS.
    pub bbox: Option<[f64; 4]>,
    /// Exact species name.
    pub species: Option<String>,
    /// Minimum height in metres.
    pub min_height_m: Option<f64>,
    /// Maximum height in metres.
    pub max_height_m: Option<f64>,
    /// Exact CRS.
    pub crs: Option<String>,
    /// Cursor: only ids after this one.
    pub after: Option<Uuid>,
    /// Page size.
    pub limit: u32,
}
