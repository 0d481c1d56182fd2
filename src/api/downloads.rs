//! Downloads of a tree's current model: skeleton, LsJSON, chain code, meshes
//! and CityJSON, with strong ETags and `If-None-Match`.
//!
//! Every download is an [`Artifact`] of an immutable model, generated once
//! (off the runtime, for meshes) and then served from the [`ArtifactCache`];
//! its ETag hashes the bytes, so it is the same on every replica.

use std::sync::Arc;

use axum::Router;
use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde::Deserialize;
use utoipa::IntoParams;
use uuid::Uuid;

use super::cache::{Artifact, ArtifactKind};
use super::error::Problem;
use super::extract::{ApiPath, ApiQuery};
use super::schema::Binary;
use super::{ApiError, AppState, ReadAccess};
use crate::encode::chaincode::{self, ChainCode};
use crate::mesh::{Lod, MeshFormat, build_mesh};
use crate::skeleton::Skeleton;
use crate::store::ModelColumn;

pub(super) fn routes() -> Router<Arc<AppState>> {
    Router::new()
        .route("/v1/trees/{id}/skeleton", get(skeleton))
        .route("/v1/trees/{id}/lsystem", get(lsystem))
        .route("/v1/trees/{id}/chaincode", get(chaincode))
        .route("/v1/trees/{id}/mesh", get(mesh))
}

/// True when `If-None-Match` names `etag` (weak comparison, as RFC 9110
/// prescribes for this header) or is `*`.
pub(super) fn not_modified(headers: &HeaderMap, etag: &HeaderValue) -> bool {
    let ours = strip_weak(etag.to_str().unwrap_or_default());
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .any(|tag| tag == "*" || strip_weak(tag) == ours)
}

fn strip_weak(tag: &str) -> &str {
    tag.strip_prefix("W/").unwrap_or(tag)
}

/// 304 or 200 with the artifact, ETag and media type.
pub(super) fn respond(artifact: Artifact, headers: &HeaderMap) -> Response {
    let cache_control = HeaderValue::from_static("public, no-cache");
    if not_modified(headers, &artifact.etag) {
        return (
            StatusCode::NOT_MODIFIED,
            [
                (header::ETAG, artifact.etag),
                (header::CACHE_CONTROL, cache_control),
            ],
        )
            .into_response();
    }
    (
        [
            (header::ETAG, artifact.etag),
            (
                header::CONTENT_TYPE,
                HeaderValue::from_static(artifact.content_type),
            ),
            (header::CACHE_CONTROL, cache_control),
        ],
        artifact.bytes,
    )
        .into_response()
}

/// The current model of a tree; 404 without the tree, 409 before its first
/// reconstruction.
pub(super) async fn current_model(state: &AppState, tree_id: Uuid) -> Result<Uuid, ApiError> {
    let tree = state
        .store
        .tree(tree_id)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("no tree {tree_id}")))?;
    tree.model_id.ok_or_else(|| {
        ApiError::Conflict(format!(
            "tree {tree_id} has no model yet: its reconstruction job is queued, running or failed"
        ))
    })
}

/// The artifact `kind` of the tree's current model: from the cache, or made
/// by `make` from the model's id and cached. Every download goes through
/// here, so a model's artifact is made once per replica, whatever asks.
pub(super) async fn cached(
    state: &AppState,
    tree_id: Uuid,
    kind: ArtifactKind,
    make: impl AsyncFnOnce(Uuid) -> Result<Artifact, ApiError>,
) -> Result<Artifact, ApiError> {
    let model = current_model(state, tree_id).await?;
    if let Some(hit) = state.cache.get(model, kind) {
        return Ok(hit);
    }
    let artifact = make(model).await?;
    state.cache.insert(model, kind, artifact.clone());
    Ok(artifact)
}

/// A stored column of a model; 404 if the tree was deleted meanwhile.
async fn model_column(
    state: &AppState,
    tree_id: Uuid,
    model: Uuid,
    column: ModelColumn,
) -> Result<Vec<u8>, ApiError> {
    state
        .store
        .model_column(model, column)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("tree {tree_id} was just deleted")))
}

/// A stored column of the current model, cached.
async fn stored(
    state: &AppState,
    tree_id: Uuid,
    column: ModelColumn,
    content_type: &'static str,
) -> Result<Artifact, ApiError> {
    cached(
        state,
        tree_id,
        ArtifactKind::Stored(column),
        async |model| {
            let bytes = model_column(state, tree_id, model, column).await?;
            Ok(Artifact::new(bytes, content_type))
        },
    )
    .await
}

/// Format of a skeleton download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct SkeletonQuery {
    /// `json` (default): silva skeleton JSON; `ply`: binary PLY with one
    /// vertex per node (absolute `double x y z`, `float radius`) and one
    /// edge per internode, parent to child, as `silva reconstruct
    /// --skeleton s.ply` writes it.
    #[param(value_type = Option<super::schema::SkeletonFormatName>, inline)]
    format: Option<String>,
}

/// The skeleton with radii, as silva skeleton JSON or PLY.
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/skeleton",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id"), SkeletonQuery),
    responses(
        (status = 200, description = "The skeleton", headers(("ETag" = String)),
            content(
                (Object = "application/json"),
                (Binary = "application/ply"),
            )),
        (status = 304, description = "Unchanged"),
        (status = 400, description = "Unknown format, or the id is not a UUID", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn skeleton(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    ApiQuery(query): ApiQuery<SkeletonQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    match query.format.as_deref().unwrap_or("json") {
        "json" => {
            let artifact = stored(&state, id, ModelColumn::Skeleton, "application/json").await?;
            Ok(respond(artifact, &headers))
        }
        "ply" => {
            let artifact = cached(&state, id, ArtifactKind::SkeletonPly, async |model| {
                let skeleton = model_skeleton(&state, id, model).await?;
                Ok(Artifact::new(skeleton.to_ply(), "application/ply"))
            })
            .await?;
            Ok(respond(artifact, &headers))
        }
        other => Err(ApiError::BadRequest(format!(
            "format: expected json or ply, found {other:?}"
        ))),
    }
}

/// The tree as an L-system (LsJSON).
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/lsystem",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id")),
    responses(
        (status = 200, description = "LsJSON", body = Object, content_type = "application/json",
            headers(("ETag" = String))),
        (status = 304, description = "Unchanged"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn lsystem(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let artifact = stored(&state, id, ModelColumn::LSystem, "application/json").await?;
    Ok(respond(artifact, &headers))
}

/// Level of a chain code download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct ChainCodeQuery {
    /// Level of detail 1 (scaffold limbs) to 3 (every branch, the stored
    /// code); default 3. Levels 1 and 2 are cut from the code itself
    /// (Pseudocode 2 of the chain-code paper) and decode to the branches of
    /// the mesh at the same level; level 0 selects branches by order and has
    /// no chain code.
    #[param(minimum = 1, maximum = 3)]
    lod: Option<u8>,
}

/// The tree as a compressed DBF6 chain code, whole or at a level of detail.
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/chaincode",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id"), ChainCodeQuery),
    responses(
        (status = 200, description = "Compressed DBF6 chain code", body = Binary,
            content_type = "application/octet-stream", headers(("ETag" = String))),
        (status = 304, description = "Unchanged"),
        (status = 400, description = "A LOD other than 1 to 3, or the id is not a UUID", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn chaincode(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    ApiQuery(query): ApiQuery<ChainCodeQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let lod = match query.lod.map(parse_lod).transpose()? {
        Some(Lod::L0) => {
            return Err(ApiError::BadRequest(
                "lod: 0 selects branches by order and has no chain code; expected 1 to 3".into(),
            ));
        }
        Some(lod) => lod,
        None => Lod::L3,
    };
    const MEDIA_TYPE: &str = "application/octet-stream";
    if lod == Lod::L3 {
        let full = stored(&state, id, ModelColumn::ChainCode, MEDIA_TYPE).await?;
        return Ok(respond(full, &headers));
    }
    let artifact = cached(&state, id, ArtifactKind::ChainCode(lod), async |model| {
        let full = model_column(&state, id, model, ModelColumn::ChainCode).await?;
        tokio::task::spawn_blocking(move || {
            let corrupt =
                |e| ApiError::Internal(format!("stored chain code of model {model}: {e}"));
            let code =
                ChainCode::decompress(&full, &chaincode::Limits::default()).map_err(corrupt)?;
            let cut = lod.reduce_chain_code(&code).map_err(corrupt)?;
            let cut = cut.expect("levels 1 to 3 have a threshold");
            Ok(Artifact::new(cut.compress(), MEDIA_TYPE))
        })
        .await?
    })
    .await?;
    Ok(respond(artifact, &headers))
}

/// A level of detail from its number.
pub(super) fn parse_lod(level: u8) -> Result<Lod, ApiError> {
    Lod::from_level(level)
        .ok_or_else(|| ApiError::BadRequest(format!("lod: expected 0 to 3, found {level}")))
}

/// The skeleton of a model, parsed.
pub(super) async fn model_skeleton(
    state: &AppState,
    tree_id: Uuid,
    model: Uuid,
) -> Result<Skeleton, ApiError> {
    let json = model_column(state, tree_id, model, ModelColumn::Skeleton).await?;
    Skeleton::from_json(&String::from_utf8_lossy(&json))
        .map_err(|e| ApiError::Internal(format!("stored skeleton of model {model}: {e}")))
}

/// Format and level of a mesh download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct MeshQuery {
    /// `glb` (default), `obj` or `ply`.
    #[param(value_type = Option<super::schema::MeshFormatName>, inline)]
    format: Option<String>,
    /// Level of detail 0 (trunk and first-order branches) to 3 (every
    /// branch); default 1.
    #[param(minimum = 0, maximum = 3)]
    lod: Option<u8>,
}

/// The branch mesh of the tree at a level of detail, in its own local frame
/// (metres from the trunk base; GLB carries the georeference in its root
/// node translation).
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/mesh",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id"), MeshQuery),
    responses(
        (status = 200, description = "The mesh", body = Binary, headers(("ETag" = String)),
            content(
                (Binary = "model/gltf-binary"),
                (String = "model/obj"),
                (Binary = "application/ply"),
            )),
        (status = 304, description = "Unchanged"),
        (status = 400, description = "Unknown format or LOD, or the id is not a UUID", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn mesh(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    ApiQuery(query): ApiQuery<MeshQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let name = query.format.as_deref().unwrap_or("glb");
    let format = MeshFormat::from_extension(name).ok_or_else(|| {
        ApiError::BadRequest(format!("format: expected glb, obj or ply, found {name:?}"))
    })?;
    let lod = parse_lod(query.lod.unwrap_or(1))?;
    let artifact = cached(&state, id, ArtifactKind::Mesh(format, lod), async |model| {
        let skeleton = model_skeleton(&state, id, model).await?;
        Ok(tokio::task::spawn_blocking(move || {
            let mesh = build_mesh(&skeleton, lod);
            let anchor = skeleton.anchor();
            Artifact::new(
                format.encode(&mesh, anchor, anchor.origin),
                format.media_type(),
            )
        })
        .await?)
    })
    .await?;
    Ok(respond(artifact, &headers))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_none_match_compares_weakly() {
        let etag = HeaderValue::from_static("\"abc\"");
        let mut headers = HeaderMap::new();
        assert!(!not_modified(&headers, &etag));
        headers.insert(
            header::IF_NONE_MATCH,
            HeaderValue::from_static("\"x\", W/\"abc\""),
        );
        assert!(not_modified(&headers, &etag));
        headers.insert(header::IF_NONE_MATCH, HeaderValue::from_static("\"abd\""));
        assert!(!not_modified(&headers, &etag));
        headers.insert(header::IF_NONE_MATCH, HeaderValue::from_static("*"));
        assert!(not_modified(&headers, &etag));
    }
}
