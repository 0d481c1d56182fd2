//! JSON documents of the API: trees, jobs, GeoJSON features, links.

use clap::ValueEnum;
use serde::{Deserialize, Serialize};
use time::OffsetDateTime;
use time::format_description::well_known::Rfc3339;
use utoipa::ToSchema;
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{Object, ObjectBuilder, Schema, Type};
use uuid::Uuid;

use crate::jobs::ModelRecord;
use crate::mesh::MeshFormat;
use crate::reconstruct::Mode;
use crate::store::{JobRow, JobState, TreeRow};

/// A hyperlink (RFC 8288 / OGC API style).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Link {
    /// Where it points.
    pub href: String,
    /// Relation: `self`, `next`, `skeleton`, …
    pub rel: String,
    /// Media type of the target.
    #[serde(rename = "type", default, skip_serializing_if = "Option::is_none")]
    pub media_type: Option<String>,
}

impl Link {
    /// A link with a media type.
    pub fn new(href: String, rel: &str, media_type: &str) -> Self {
        Self {
            href,
            rel: rel.to_owned(),
            media_type: Some(media_type.to_owned()),
        }
    }
}

/// A tree: metadata, location, metrics of its current model, links.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Tree {
    /// Tree id.
    pub id: Uuid,
    /// The inventory's own id.
    pub external_id: Option<String>,
    /// Species name.
    pub species: Option<String>,
    /// CRS of `location`.
    pub crs: Option<String>,
    /// Trunk base `[x, y, z]`, absolute; null until the first model.
    pub location: Option<[f64; 3]>,
    /// Height in metres; null until the first model.
    pub height_m: Option<f64>,
    /// Metrics of the current model (height, crown, DBH, …); null until then.
    #[schema(value_type = Option<Object>)]
    pub metrics: Option<serde_json::Value>,
    /// The current model; null until the first reconstruction succeeds.
    pub model_id: Option<Uuid>,
    /// How the current model was made: the pipeline, the best efforts it
    /// flagged and the encodings' error bounds; null until then.
    pub model: Option<TreeModel>,
    /// Incremented on every change.
    pub version: i64,
    /// RFC 3339.
    pub created_at: String,
    /// RFC 3339.
    pub updated_at: String,
    /// The tree and its downloads.
    pub links: Vec<Link>,
}

impl Tree {
    /// The document for a stored tree; links relative to `base`.
    pub fn from_row(row: &TreeRow, base: &str) -> Self {
        let own = format!("{base}/v1/trees/{}", row.id);
        let mut links = vec![Link::new(own.clone(), "self", "application/json")];
        if row.model_id.is_some() {
            for (path, rel, ty) in [
                ("skeleton", "skeleton", "application/json"),
                ("lsystem", "lsystem", "application/json"),
                ("chaincode", "chaincode", "application/octet-stream"),
                ("mesh?format=glb&lod=1", "mesh", "model/gltf-binary"),
                ("cityjson?lod=2", "cityjson", "application/city+json"),
            ] {
                links.push(Link::new(format!("{own}/{path}"), rel, ty));
            }
        }
        Self {
            id: row.id,
            external_id: row.external_id.clone(),
            species: row.species.clone(),
            crs: row.crs.clone(),
            location: row.location(),
            height_m: row.height_m,
            metrics: row
                .metrics
                .as_deref()
                .and_then(|m| serde_json::from_str(m).ok()),
            model_id: row.model_id,
            model: TreeModel::from_row(row),
            version: row.version,
            created_at: rfc3339(row.created_at_ms),
            updated_at: rfc3339(row.updated_at_ms),
            links,
        }
    }
}

/// The current model of a tree and its reconstruction record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TreeModel {
    /// Model id.
    pub id: Uuid,
    /// The record the job stored with the model.
    #[serde(flatten)]
    pub record: ModelRecord,
}

impl TreeModel {
    /// The current model of a stored tree, if it has one. A record an
    /// older version stored reads with what it holds.
    fn from_row(row: &TreeRow) -> Option<Self> {
        Some(Self {
            id: row.model_id?,
            record: row
                .model_parameters
                .as_deref()
                .map(ModelRecord::parse)
                .unwrap_or_default(),
        })
    }
}

/// A job: state and progress of a reconstruction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Job {
    /// Job id.
    pub id: Uuid,
    /// What it does: `reconstruct`.
    pub kind: String,
    /// Where it is in its lifecycle.
    pub state: JobState,
    /// 0 to 1.
    pub progress: f64,
    /// Executions started (more than 1 after a retry or a lost worker).
    pub attempts: i32,
    /// Why it failed.
    pub error: Option<String>,
    /// The tree being reconstructed.
    pub tree_id: Uuid,
    /// The scan it reconstructs from.
    pub scan_id: Uuid,
    /// The model it produced.
    pub model_id: Option<Uuid>,
    /// RFC 3339.
    pub created_at: String,
    /// RFC 3339.
    pub updated_at: String,
    /// RFC 3339, start of the last execution.
    pub started_at: Option<String>,
    /// RFC 3339, end of the last execution.
    pub finished_at: Option<String>,
    /// The job and its tree.
    pub links: Vec<Link>,
}

impl Job {
    /// The document for a stored job; links relative to `base`.
    pub fn from_row(row: &JobRow, base: &str) -> Self {
        Self {
            id: row.id,
            kind: row.kind.clone(),
            state: row.state(),
            progress: row.progress,
            attempts: row.attempts,
            error: row.error.clone(),
            tree_id: row.tree_id,
            scan_id: row.scan_id,
            model_id: row.model_id,
            created_at: rfc3339(row.created_at_ms),
            updated_at: rfc3339(row.updated_at_ms),
            started_at: row.started_at_ms.map(rfc3339),
            finished_at: row.finished_at_ms.map(rfc3339),
            links: vec![
                Link::new(
                    format!("{base}/v1/jobs/{}", row.id),
                    "self",
                    "application/json",
                ),
                Link::new(
                    format!("{base}/v1/trees/{}", row.tree_id),
                    "tree",
                    "application/json",
                ),
            ],
        }
    }
}

/// A GeoJSON point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PointGeometry {
    /// Always `Point`.
    #[serde(rename = "type")]
    pub geometry_type: String,
    /// `[x, y, z]` in the tree's CRS.
    pub coordinates: [f64; 3],
}

/// Properties of a tree feature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TreeProperties {
    /// The inventory's own id.
    pub external_id: Option<String>,
    /// Species name.
    pub species: Option<String>,
    /// CRS of the geometry.
    pub crs: Option<String>,
    /// Height in metres.
    pub height_m: Option<f64>,
    /// The current model.
    pub model_id: Option<Uuid>,
    /// How the current model was made (as in the tree document).
    pub model: Option<TreeModel>,
    /// RFC 3339.
    pub updated_at: String,
}

/// A tree as a GeoJSON feature at its trunk base.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TreeFeature {
    /// Always `Feature`.
    #[serde(rename = "type")]
    pub feature_type: String,
    /// Tree id.
    pub id: Uuid,
    /// Trunk base; null until the first model.
    pub geometry: Option<PointGeometry>,
    /// Tree metadata.
    pub properties: TreeProperties,
    /// The tree document.
    pub links: Vec<Link>,
}

impl TreeFeature {
    /// The feature of a stored tree.
    pub fn from_row(row: &TreeRow, base: &str) -> Self {
        Self {
            feature_type: "Feature".into(),
            id: row.id,
            geometry: row.location().map(|coordinates| PointGeometry {
                geometry_type: "Point".into(),
                coordinates,
            }),
            properties: TreeProperties {
                external_id: row.external_id.clone(),
                species: row.species.clone(),
                crs: row.crs.clone(),
                height_m: row.height_m,
                model_id: row.model_id,
                model: TreeModel::from_row(row),
                updated_at: rfc3339(row.updated_at_ms),
            },
            links: vec![Link::new(
                format!("{base}/v1/trees/{}", row.id),
                "self",
                "application/json",
            )],
        }
    }
}

/// A page of trees as a GeoJSON FeatureCollection (OGC API Features items).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "camelCase")]
pub struct TreeCollection {
    /// Always `FeatureCollection`.
    #[serde(rename = "type")]
    pub collection_type: String,
    /// The trees of this page.
    pub features: Vec<TreeFeature>,
    /// Features in this page.
    pub number_returned: usize,
    /// RFC 3339 time of the answer.
    pub time_stamp: String,
    /// `self`, and `next` when more trees match.
    pub links: Vec<Link>,
}

/// Unix milliseconds as RFC 3339.
pub(super) fn rfc3339(ms: i64) -> String {
    OffsetDateTime::from_unix_timestamp_nanos(i128::from(ms) * 1_000_000)
        .ok()
        .and_then(|t| t.format(&Rfc3339).ok())
        .unwrap_or_default()
}

/// Raw bytes in a request or response body (OpenAPI `string`, format `binary`).
#[derive(Debug, Clone, ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct Binary(pub Vec<u8>);

/// A string parameter that takes one of `values`.
fn one_of(values: impl IntoIterator<Item = &'static str>) -> Object {
    ObjectBuilder::new()
        .schema_type(Type::String)
        .enum_values(Some(values))
        .build()
}

/// Declares a marker type whose schema is `$schema`: for query parameters
/// that are plain strings in Rust but take a narrower form on the wire, as
/// `#[param(value_type = Option<Marker>, inline)]`.
macro_rules! param_schema {
    ($(#[$doc:meta])* $name:ident => $schema:expr) => {
        $(#[$doc])*
        pub(super) struct $name;

        impl utoipa::PartialSchema for $name {
            fn schema() -> RefOr<Schema> {
                $schema.into()
            }
        }

        impl ToSchema for $name {}
    };
}

param_schema!(
    /// The `mode` of an upload: a [`Mode`]'s name.
    ModeName => one_of(Mode::value_variants().iter().map(|mode| mode.name()))
);

param_schema!(
    /// The `format` of a mesh download: a [`MeshFormat`]'s extension.
    MeshFormatName => one_of(MeshFormat::ALL.map(MeshFormat::extension))
);

param_schema!(
    /// The `format` of a skeleton download.
    SkeletonFormatName => one_of(["json", "ply"])
);

param_schema!(
    /// A `bbox`: four comma-separated decimal numbers, as `parse_bbox`
    /// reads them. The pattern cannot say that min is at most max; exponents
    /// of at most two digits keep the numbers finite.
    BboxText => {
        const NUMBER: &str = "-?([0-9]+(\\.[0-9]*)?|\\.[0-9]+)([eE][-+]?[0-9]{1,2})?";
        ObjectBuilder::new()
            .schema_type(Type::String)
            .pattern(Some(format!("^{NUMBER},{NUMBER},{NUMBER},{NUMBER}$")))
            .build()
    }
);
