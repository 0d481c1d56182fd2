//! CityJSON downloads: one tree (`/v1/trees/{id}/cityjson`) and every tree
//! of an area as a streamed CityJSONSeq (`/v1/cityjson`).

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use futures::StreamExt;
use glam::DVec3;
use serde::Deserialize;
use serde_json::{Map, Value};
use tokio::time::Instant;
use utoipa::IntoParams;
use uuid::Uuid;

use super::cache::{Artifact, ArtifactKind};
use super::downloads::{cached, model_skeleton, parse_lod, respond};
use super::error::Problem;
use super::extract::{ApiPath, ApiQuery};
use super::features::parse_bbox;
use super::{ApiError, AppState, ReadAccess};
use crate::cityjson::{self, MEDIA_TYPE, MEDIA_TYPE_SEQ, TreeInfo};
use crate::cloud::MAX_ABS_COORDINATE_M;
use crate::mesh::Lod;
use crate::skeleton::Skeleton;
use crate::store::{TreeFilter, TreeRow};

pub(super) fn routes() -> Router<Arc<AppState>> {
    Router::new()
        .route("/v1/trees/{id}/cityjson", get(cityjson))
        .route("/v1/cityjson", get(cityjson_seq))
}

/// The CityJSON object of one stored tree: its id, species, and the metrics
/// of its model as attributes (CityGML `height`, `trunkDiameter` and
/// `crownDiameter` from the measured metrics).
fn tree_info<'a>(row: &TreeRow, skeleton: &'a Skeleton) -> TreeInfo<'a> {
    let mut info = TreeInfo::new(row.id.to_string(), skeleton);
    info.species.clone_from(&row.species);
    let metrics: Map<String, Value> = row
        .metrics
        .as_deref()
        .and_then(|m| serde_json::from_str(m).ok())
        .unwrap_or_default();
    for (city_name, metric) in [
        ("height", "height_m"),
        ("trunkDiameter", "dbh_m"),
        ("crownDiameter", "crown_diameter_m"),
    ] {
        if let Some(value) = metrics.get(metric).filter(|v| v.is_number()) {
            info.attributes.insert(city_name.into(), value.clone());
        }
    }
    // The remaining scalar metrics as they are; nested ones (per branch
    // order) stay in the tree JSON.
    for (name, value) in metrics {
        if value.is_number() || value.is_string() {
            info.attributes.entry(name).or_insert(value);
        }
    }
    if let Some(external_id) = &row.external_id {
        info.attributes
            .insert("externalId".into(), Value::String(external_id.clone()));
    }
    info
}

/// Level of a CityJSON download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct LodQuery {
    /// Level of detail 0–3 (default 2).
    #[param(minimum = 0, maximum = 3)]
    lod: Option<u8>,
}

/// The tree as a CityJSON 2.0 `SolitaryVegetationObject`: the branch mesh
/// at the requested LOD as a MultiSurface, the skeleton as a
/// MultiLineString, CityGML attributes, georeferenced.
#[utoipa::path(
    get,
    path = "/v1/trees/{id}/cityjson",
    tag = "downloads",
    params(("id" = Uuid, Path, description = "Tree id"), LodQuery),
    responses(
        (status = 200, description = "CityJSON 2.0", body = Object, content_type = "application/city+json",
            headers(("ETag" = String))),
        (status = 304, description = "Unchanged"),
        (status = 400, description = "Bad LOD, or the id is not a UUID", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Not reconstructed yet", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn cityjson(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiPath(id): ApiPath<Uuid>,
    ApiQuery(query): ApiQuery<LodQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let lod = parse_lod(query.lod.unwrap_or(2))?;
    let artifact = cached(&state, id, ArtifactKind::CityJson(lod), async |model| {
        let row = state
            .store
            .tree(id)
            .await?
            .ok_or_else(|| ApiError::NotFound(format!("no tree {id}")))?;
        let skeleton = model_skeleton(&state, id, model).await?;
        Ok(tokio::task::spawn_blocking(move || {
            let doc = cityjson::city_json(&tree_info(&row, &skeleton), &[lod]);
            Artifact::new(doc.to_string(), MEDIA_TYPE)
        })
        .await?)
    })
    .await?;
    Ok(respond(artifact, &headers))
}

/// Area, level and CRS of a CityJSONSeq export.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct SeqQuery {
    /// `min_x,min_y,max_x,max_y` in the trees' CRS.
    #[param(value_type = super::schema::BboxText, inline)]
    bbox: String,
    /// Level of detail 0–3 (default 2).
    #[param(minimum = 0, maximum = 3)]
    lod: Option<u8>,
    /// CRS of the export (default: that of the first tree found). Trees in
    /// another CRS are not part of the stream, since one stream has one
    /// transform and reference system.
    #[param(pattern = r"^[^\u0000]*$")]
    crs: Option<String>,
}

/// Trees per database page while streaming.
const SEQ_PAGE: u32 = 100;

/// How many request time limits a CityJSONSeq export may run (ten minutes
/// at the default minute).
const EXPORT_TIME_LIMITS: u32 = 10;

/// Every reconstructed tree in a bbox as CityJSONSeq: a CityJSON header
/// line, then one CityJSONFeature line per tree. The stream is produced
/// page by page, so memory stays flat for any area.
///
/// The stream's headers leave before the request limits apply to the
/// rest, so the rest has its own:
/// each page is rendered in one of a few export slots (four per decode
/// slot; a client that stops reading holds none), and a stream that has
/// run ten request time limits ends at its next page (a cut-off body, and
/// a logged reason).
#[utoipa::path(
    get,
    path = "/v1/cityjson",
    tag = "downloads",
    params(SeqQuery),
    responses(
        (status = 200, description = "CityJSONSeq: newline-delimited CityJSON header and CityJSONFeature objects",
            body = String, content_type = "application/city+json-seq"),
        (status = 400, description = "Bad bbox or LOD", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn cityjson_seq(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    ApiQuery(query): ApiQuery<SeqQuery>,
) -> Result<Response, ApiError> {
    let lod = parse_lod(query.lod.unwrap_or(2))?;
    let bbox = parse_bbox(&query.bbox)?;
    let deadline = Deadline::after(state.config.request_timeout() * EXPORT_TIME_LIMITS);
    let mut filter = TreeFilter {
        bbox: Some(bbox),
        crs: query.crs,
        limit: SEQ_PAGE,
        ..TreeFilter::default()
    };
    // The first page fixes the CRS and the transform of the whole stream.
    let first = state.store.trees_with_skeletons(&filter).await?;
    let first = parse_page(first)?;
    // Whether more pages follow depends on the page the database gave,
    // before the CRS filter below drops any of its trees.
    let after = next_after(&first);
    if filter.crs.is_none() {
        filter.crs = first.first().and_then(|(row, _)| row.crs.clone());
    }
    // Later pages are filtered by the database.
    let first: Vec<_> = first
        .into_iter()
        .filter(|(row, _)| filter.crs.is_none() || row.crs == filter.crs)
        .collect();
    let translate = seq_translate(filter.bbox.unwrap_or_default());
    let header = cityjson::seq_header(translate, filter.crs.as_deref(), None).to_string() + "\n";
    let first_lines = render(&state, first, lod, translate).await;
    let rest = pages_within(after, deadline, move |after| {
        let (state, filter) = (state.clone(), filter.clone());
        async move {
            let filter = TreeFilter {
                after: Some(after),
                ..filter
            };
            next_page(&state, &filter, lod, translate).await
        }
    });
    // Fused: the compression layer polls the body again after its end, and
    // an unfused `unfold` panics then, cutting every compressed stream off.
    let body = futures::stream::iter([Ok(header), first_lines])
        .chain(rest)
        .fuse();
    Ok((
        [(header::CONTENT_TYPE, MEDIA_TYPE_SEQ)],
        Body::from_stream(body),
    )
        .into_response())
}

/// When an export must end, and how long it was given (for the message).
#[derive(Debug, Clone, Copy)]
struct Deadline {
    at: Instant,
    limit: Duration,
}

impl Deadline {
    fn after(limit: Duration) -> Self {
        Self {
            at: Instant::now() + limit,
            limit,
        }
    }
}

/// The pages of an export after the first, from `after` on: each fetched
/// by `fetch` (its lines, and where the page after it starts) when the
/// body wants more, until a page says none follow. A page wanted past the
/// deadline ends the stream with an error instead (a cut-off body).
fn pages_within<F, Fut>(
    after: Option<Uuid>,
    deadline: Deadline,
    fetch: F,
) -> impl futures::Stream<Item = Result<String, std::io::Error>>
where
    F: FnMut(Uuid) -> Fut,
    Fut: std::future::Future<Output = (Result<String, std::io::Error>, Option<Uuid>)>,
{
    futures::stream::unfold((after, fetch), move |(after, mut fetch)| async move {
        let after = after?;
        if Instant::now() > deadline.at {
            let err = format!(
                "the export ran past its time limit of {:?}; ask for a smaller bbox",
                deadline.limit
            );
            return Some((Err(stream_error(&err)), (None, fetch)));
        }
        let (lines, next) = fetch(after).await;
        Some((lines, (next, fetch)))
    })
}

/// The stream's `translate`: the bbox's lower corner, millimetre-snapped so
/// that integer vertices stay exact, and moved inside the coordinates a
/// stored tree can have ([`MAX_ABS_COORDINATE_M`]): a corner at −1e16 m
/// put every vertex past `i64` (each coordinate saturated to 2^63 − 1),
/// while within the clamp a vertex is at most about 2·10^12 mm, exact in
/// both `i64` and `f64`.
fn seq_translate(bbox: [f64; 4]) -> DVec3 {
    let corner = |v: f64| {
        let v = v.clamp(-MAX_ABS_COORDINATE_M, MAX_ABS_COORDINATE_M);
        (v * 1000.0).round() / 1000.0
    };
    DVec3::new(corner(bbox[0]), corner(bbox[1]), 0.0)
}

/// The id after which the next page starts, when `page` was a full one.
fn next_after<T>(page: &[(TreeRow, T)]) -> Option<Uuid> {
    (page.len() == SEQ_PAGE as usize)
        .then(|| page.last().map(|(row, _)| row.id))
        .flatten()
}

/// The feature lines of the page `filter` selects, and where the page after
/// it starts (none after the last page or an error).
async fn next_page(
    state: &AppState,
    filter: &TreeFilter,
    lod: Lod,
    translate: DVec3,
) -> (Result<String, std::io::Error>, Option<Uuid>) {
    let page = match state.store.trees_with_skeletons(filter).await {
        Ok(page) => page,
        Err(err) => return (Err(stream_error(&err)), None),
    };
    let after = next_after(&page);
    match parse_page(page) {
        Ok(trees) => (render(state, trees, lod, translate).await, after),
        Err(err) => (Err(stream_error(&err)), None),
    }
}

/// Skeletons of a page, parsed.
fn parse_page(page: Vec<(TreeRow, String)>) -> Result<Vec<(TreeRow, Skeleton)>, ApiError> {
    page.into_iter()
        .map(|(row, json)| {
            Skeleton::from_json(&json)
                .map(|s| (row, s))
                .map_err(|e| ApiError::Internal(format!("stored skeleton: {e}")))
        })
        .collect()
}

/// The feature lines of some trees, built off the runtime in an export
/// slot (which goes with the blocking task, so that a dropped stream frees
/// it only when the rendering ends).
async fn render(
    state: &AppState,
    trees: Vec<(TreeRow, Skeleton)>,
    lod: Lod,
    translate: DVec3,
) -> Result<String, std::io::Error> {
    let slot = state
        .export_slots
        .clone()
        .acquire_owned()
        .await
        .map_err(std::io::Error::other)?;
    tokio::task::spawn_blocking(move || {
        let _slot = slot;
        let mut out = String::new();
        for (row, skeleton) in &trees {
            let feature = cityjson::city_json_feature(&tree_info(row, skeleton), &[lod], translate);
            out.push_str(&feature.to_string());
            out.push('\n');
        }
        out
    })
    .await
    .map_err(std::io::Error::other)
}

/// Headers are sent already: the stream ends early, the client sees a
/// truncated sequence, and the log says why.
fn stream_error(err: &dyn std::fmt::Display) -> std::io::Error {
    tracing::error!(error = %err, "CityJSONSeq export stopped");
    std::io::Error::other(err.to_string())
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    /// Pages that each take 4 s under a 10 s limit: the pages wanted at
    /// 0, 4 and 8 s come; the one wanted at 12 s ends the stream with the
    /// error that names the limit, and is not fetched (without the limit
    /// six pages would come).
    #[tokio::test(start_paused = true)]
    async fn an_export_ends_at_the_first_page_wanted_past_its_time_limit() {
        let fetched = AtomicUsize::new(0);
        let deadline = Deadline::after(Duration::from_secs(10));
        let pages = pages_within(Some(Uuid::nil()), deadline, |_| async {
            let n = fetched.fetch_add(1, Ordering::SeqCst);
            tokio::time::sleep(Duration::from_secs(4)).await;
            (Ok(format!("page {n}\n")), (n < 5).then(Uuid::now_v7))
        });
        let items: Vec<_> = pages.collect().await;
        let lines: Vec<_> = items.iter().map(|i| i.as_ref().ok().cloned()).collect();
        let pages = ["page 0\n", "page 1\n", "page 2\n"].map(|p| Some(p.to_owned()));
        assert_eq!(lines[..3], pages);
        assert_eq!(items.len(), 4);
        let err = items[3].as_ref().unwrap_err().to_string();
        assert!(err.contains("time limit of 10s"), "{err}");
        assert_eq!(fetched.load(Ordering::SeqCst), 3);
    }

    /// An export whose pages end within its limit streams them all.
    #[tokio::test(start_paused = true)]
    async fn an_export_within_its_time_limit_ends_after_its_last_page() {
        let deadline = Deadline::after(Duration::from_secs(10));
        let pages = pages_within(Some(Uuid::nil()), deadline, |after| async move {
            tokio::time::sleep(Duration::from_secs(1)).await;
            let next = (after.as_u128() < 4).then(|| Uuid::from_u128(after.as_u128() + 1));
            (Ok(format!("after {}\n", after.as_u128())), next)
        });
        let lines: Vec<String> = pages.map(Result::unwrap).collect().await;
        assert_eq!(
            lines.concat(),
            "after 0\nafter 1\nafter 2\nafter 3\nafter 4\n"
        );
        let none = pages_within(None, deadline, |_| async { unreachable!() });
        let none: Vec<Result<String, std::io::Error>> = none.collect().await;
        assert!(none.is_empty());
    }
}
