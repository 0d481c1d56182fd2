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

/// A stored column of the current model, cached.
async fn stored(
    state: &AppState,
    tree_id: Uuid,
    column: ModelColumn,
    content_type: &'static str,
) -> Result<Artifact, ApiError> {
    let model = current_model(state, tree_id).await?;
    let kind = ArtifactKind::Stored(column);
    if let Some(hit) = state.cache.get(model, kind) {
        return Ok(hit);
    }
    let bytes = state
        .store
        .model_column(model, column)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("tree {tree_id} was just deleted")))?;
    let artifact = Artifact::new(bytes, content_type);
    state.cache.insert(model, kind, artifact.clone());
    Ok(artifact)
}

/// The skeleton with radii, as silva skeleton JSON.
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/skeleton",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id")),
    responses(
        (status = 200, description = "silva skeleton JSON: anchor and `[x, y, z, radius_m, parent]` nodes",
            body = Object, content_type = "application/json", headers(("ETag" = String))),
        (status = 304, description = "Unchanged"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn skeleton(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let artifact = stored(&state, id, ModelColumn::Skeleton, "application/json").await?;
    Ok(respond(artifact, &headers))
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

/// The tree as a compressed DBF6 chain code.
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/chaincode",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id")),
    responses(
        (status = 200, description = "Compressed DBF6 chain code", body = Binary,
            content_type = "application/octet-stream", headers(("ETag" = String))),
        (status = 304, description = "Unchanged"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn chaincode(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let artifact = stored(
        &state,
        id,
        ModelColumn::ChainCode,
        "application/octet-stream",
    )
    .await?;
    Ok(respond(artifact, &headers))
}

/// A level of detail from its number.
pub(super) fn parse_lod(level: u8) -> Result<Lod, ApiError> {
    Lod::from_level(level)
        .ok_or_else(|| ApiError::BadRequest(format!("lod: expected 0 to 3, found {level}")))
}

/// The current model's skeleton, parsed; with the model id.
pub(super) async fn current_skeleton(
    state: &AppState,
    tree_id: Uuid,
) -> Result<(Uuid, Skeleton), ApiError> {
    let model = current_model(state, tree_id).await?;
    let json = state
        .store
        .model_column(model, ModelColumn::Skeleton)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("tree {tree_id} was just deleted")))?;
    let skeleton = Skeleton::from_json(&String::from_utf8_lossy(&json))
        .map_err(|e| ApiError::Internal(format!("stored skeleton of model {model}: {e}")))?;
    Ok((model, skeleton))
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
    let kind = ArtifactKind::Mesh(format, lod);
    let model = current_model(&state, id).await?;
    if let Some(hit) = state.cache.get(model, kind) {
        return Ok(respond(hit, &headers));
    }
    let (model, skeleton) = current_skeleton(&state, id).await?;
    let artifact = tokio::task::spawn_blocking(move || {
        let mesh = build_mesh(&skeleton, lod);
        let anchor = skeleton.anchor();
        Artifact::new(
            format.encode(&mesh, anchor, anchor.origin),
            format.media_type(),
        )
    })
    .await?;
    state.cache.insert(model, kind, artifact.clone());
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
