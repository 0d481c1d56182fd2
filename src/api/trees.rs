//! `/v1/trees`: upload a scan, read and delete a tree.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::Router;
use axum::extract::rejection::{BytesRejection, FailedToBufferBody};
use axum::extract::{DefaultBodyLimit, FromRequest, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use bytes::Bytes;
use serde::Deserialize;
use sha2::{Digest, Sha256};
use tokio::sync::OwnedSemaphorePermit;
use tower_http::limit::RequestBodyLimitLayer;
use utoipa::IntoParams;
use uuid::Uuid;

use super::downloads::not_modified;
use super::error::Problem;
use super::extract::{ApiPath, ApiQuery, RawUpload};
use super::middleware::RequestClock;
use super::schema::{Binary, Job, Tree};
use super::{ApiError, AppState, BaseUrl, Config, ReadAccess, WriteAccess};
use crate::jobs::JobOptions;
use crate::reconstruct::Mode;
use crate::store::{Idempotency, Ingested, JobRow, NewIngest};

pub(super) fn routes(config: &Config) -> Router<Arc<AppState>> {
    Router::new()
        .route(
            "/v1/trees",
            post(create_tree)
                // Content-Length over the limit is refused before reading;
                // a chunked body is cut off while reading.
                .layer::<_, Infallible>(RequestBodyLimitLayer::new(config.max_body_bytes))
                .layer(DefaultBodyLimit::max(config.max_body_bytes))
                .get(super::features::list_trees),
        )
        .route("/v1/trees/{id}", get(get_tree).delete(delete_tree))
}

/// Metadata of an upload.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct IngestQuery {
    /// Species name, e.g. `Quercus robur`.
    #[param(max_length = 256, pattern = r"^[^\u0000]*$")]
    species: Option<String>,
    /// The inventory's own id; uploading again with the same id adds a scan
    /// to that tree (a rescan) and replaces its model.
    #[param(max_length = 256, pattern = r"^[^\u0000]*$")]
    external_id: Option<String>,
    /// Acquisition date, `YYYY-MM-DD`.
    #[param(format = Date)]
    acquired: Option<String>,
    /// Where the scan comes from, e.g. `TLS` or `AHN4`.
    #[param(max_length = 256, pattern = r"^[^\u0000]*$")]
    source: Option<String>,
    /// CRS of the coordinates, e.g. `EPSG:28992`.
    #[param(max_length = 256, pattern = r"^[^\u0000]*$")]
    crs: Option<String>,
    /// Reconstruction pipeline: `auto` (default: chosen from point density
    /// and trunk coverage), `dense` (terrestrial/mobile) or `airborne`.
    #[param(value_type = Option<super::schema::ModeName>, inline)]
    mode: Option<Mode>,
    /// Answer only when the tree is reconstructed (201 with the tree) or
    /// the time limit is near (202 with the job).
    #[serde(default)]
    wait: bool,
}

/// Upload a point cloud of one tree.
///
/// The body is the cloud in any supported format (XYZ text, PLY, LAS, LAZ;
/// detected from content), sent as it is: not under a `Content-Encoding`,
/// not in a multipart form. It is validated, stored LAZ-compressed together
/// with a reconstruction job in one transaction, and only then answered.
#[utoipa::path(
    post,
    path = "/v1/trees",
    tag = "trees",
    params(
        IngestQuery,
        ("Idempotency-Key" = Option<String>, Header, nullable = false, min_length = 1, max_length = 258,
            pattern = r#"^([!#-\[\]-~]{1,256}|"[!#-\[\]-~]{1,256}")$"#,
            description = "Makes a retry safe: an upload sent again with the same key and the same \
                           metadata and body is answered with the first upload's job (or tree) and \
                           stores nothing new; the same key with another upload is a 422. A key \
                           holds for `--idempotency-key-ttl-secs` (default a day) while its scan \
                           exists, then is free for a new upload \
                           (draft-ietf-httpapi-idempotency-key-header)"),
    ),
    request_body(
        content = Binary,
        description = "Point cloud bytes: XYZ, PLY, LAS or LAZ",
        content_type = "application/octet-stream"
    ),
    responses(
        (status = 202, description = "Stored and queued; `Location` names the job", body = Job,
            headers(("Location" = String, description = "The job"))),
        (status = 201, description = "With `wait=true`: reconstructed", body = Tree,
            headers(("Location" = String, description = "The tree"))),
        (status = 400, description = "Bad query or `Idempotency-Key` header", body = Problem, content_type = "application/problem+json"),
        (status = 401, description = "Missing or wrong API key", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The tree, or the upload that first held the `Idempotency-Key`, was deleted while this request ran: send it again",
            body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body over the size limit", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "The body is compressed (`Content-Encoding`) or a multipart form: send the file itself",
            body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Not a readable point cloud, (with `wait=true`) no tree could be reconstructed from it, or the `Idempotency-Key` was used for another upload",
            body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Past the request time limit before anything was written (nothing stored: safe to repeat), or still writing at twice the limit (the detail says the write may have been made)",
            body = Problem, content_type = "application/problem+json"),
    ),
    security(("api_key" = []))
)]
pub(super) async fn create_tree(
    State(state): State<Arc<AppState>>,
    _: WriteAccess,
    BaseUrl(base): BaseUrl,
    ApiQuery(query): ApiQuery<IngestQuery>,
    _: RawUpload,
    clock: RequestClock,
    request: Request,
) -> Result<Response, ApiError> {
    let key = idempotency_key(request.headers())?;
    let memory = reserve_upload_memory(&state, request.headers()).await?;
    let body = Bytes::from_request(request, &()).await;
    let body = body.map_err(|rejection| match rejection {
        BytesRejection::FailedToBufferBody(FailedToBufferBody::LengthLimitError(_)) => {
            ApiError::PayloadTooLarge {
                limit: state.config.max_body_bytes,
            }
        }
        other => ApiError::BadRequest(other.body_text()),
    })?;
    check_acquired(query.acquired.as_deref())?;
    check_metadata_lengths(&query)?;
    let idempotency = match key {
        Some(key) => Some(Idempotency {
            fingerprint: request_fingerprint(&query, body.clone()).await?,
            key,
            not_before_ms: key_lifetime_start(state.config.idempotency_key_ttl()),
        }),
        None => None,
    };
    let wait = query.wait;
    let ingested = match first_upload(&state, idempotency.as_ref()).await? {
        Some(first) => {
            // A repeat stores nothing: its body's memory is free at once.
            drop((body, memory));
            first
        }
        None => {
            let (decoded, memory) = decode_upload(&state, body, memory).await?;
            clock.begin_storing();
            let stored = store_upload(&state, query, decoded, idempotency).await;
            drop(memory);
            stored?
        }
    };
    answer_upload(&state, &base, &clock, wait, &ingested).await
}

/// Stores a decoded upload with its job, and wakes the workers; when
/// another upload with the same idempotency key committed first, that
/// upload instead.
async fn store_upload(
    state: &AppState,
    query: IngestQuery,
    decoded: crate::jobs::PreparedScan,
    idempotency: Option<Idempotency>,
) -> Result<Ingested, ApiError> {
    let options = JobOptions {
        mode: query.mode.unwrap_or_default(),
        crs: query.crs.clone(),
    };
    let new = NewIngest {
        external_id: query.external_id,
        species: query.species,
        crs: query.crs,
        acquired: query.acquired,
        source: query.source,
        format: decoded.format,
        point_count: decoded.point_count,
        cloud_laz: decoded.cloud_laz,
        options: serde_json::to_string(&options).map_err(|e| ApiError::Internal(e.to_string()))?,
        idempotency,
    };
    let ingested = match state.store.ingest(&new).await {
        Ok(ingested) => ingested,
        Err(e) if e.is_idempotency_key_taken() && new.idempotency.is_some() => {
            // Another upload with the key committed while this one stored:
            // that one came first, however old its scan's time (taken when
            // its write began, which a held-up write can put past the key's
            // lifetime by now).
            let winner = new.idempotency.map(|i| Idempotency {
                not_before_ms: i64::MIN,
                ..i
            });
            // The winner may be gone again (its tree deleted in between):
            // the key is free, and a retry stores this upload.
            return first_upload(state, winner.as_ref()).await?.ok_or_else(|| {
                ApiError::Conflict(
                    "another upload with this Idempotency-Key was stored and deleted \
                     while this one was being stored; send it again"
                        .into(),
                )
            });
        }
        Err(e) => return Err(e.into()),
    };
    state.events.notify_enqueued();
    tracing::info!(tree = %ingested.tree_id, job = %ingested.job_id, points = decoded.point_count, "scan stored");
    Ok(ingested)
}

/// The answer to a stored upload (or to a repeat of one): with `wait`, the
/// tree once its job has ended within the wait budget; otherwise, or past
/// the budget, 202 with the job.
async fn answer_upload(
    state: &AppState,
    base: &str,
    clock: &RequestClock,
    wait: bool,
    ingested: &Ingested,
) -> Result<Response, ApiError> {
    if wait {
        let budget = wait_budget(state.config.request_timeout(), clock.arrival().elapsed());
        let job = wait_for_job(state, ingested.job_id, budget).await?;
        if job.state().is_terminal() {
            return finished_upload(state, base, &job).await;
        }
    }
    let job = state
        .store
        .job(ingested.job_id)
        .await?
        .ok_or_else(|| ApiError::Conflict("the job was deleted with its tree".into()))?;
    Ok(with_location(
        StatusCode::ACCEPTED,
        format!("{base}/v1/jobs/{}", job.id),
        axum::Json(Job::from_row(&job, base)),
    ))
}

/// Longest `Idempotency-Key` accepted, in bytes.
const MAX_IDEMPOTENCY_KEY_BYTES: usize = 256;

/// The upload's `Idempotency-Key` header (draft-ietf-httpapi-idempotency-key-header):
/// one header, a token or a quoted string as the draft writes it, of 1 to
/// [`MAX_IDEMPOTENCY_KEY_BYTES`] visible ASCII bytes (no spaces, no
/// escapes).
fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    let mut values = headers.get_all(IDEMPOTENCY_KEY).iter();
    let Some(value) = values.next() else {
        return Ok(None);
    };
    let bad = |why: String| ApiError::BadRequest(format!("Idempotency-Key: {why}"));
    if values.next().is_some() {
        return Err(bad("sent more than once".into()));
    }
    let text = value.as_bytes().trim_ascii();
    let key = match text.strip_prefix(b"\"") {
        Some(quoted) => quoted
            .strip_suffix(b"\"")
            .ok_or_else(|| bad("a quoted key must end with a quote".into()))?,
        None => text,
    };
    if key.is_empty() || key.len() > MAX_IDEMPOTENCY_KEY_BYTES {
        return Err(bad(format!(
            "expected 1 to {MAX_IDEMPOTENCY_KEY_BYTES} bytes, found {}",
            key.len()
        )));
    }
    if let Some(&byte) = key
        .iter()
        .find(|b| !b.is_ascii_graphic() || **b == b'"' || **b == b'\\')
    {
        return Err(bad(format!(
            "expected visible ASCII without quotes or backslashes, found byte {byte:#04x}"
        )));
    }
    Ok(Some(String::from_utf8_lossy(key).into_owned()))
}

/// The start of the lifetime of a key sent now: uploads stored before it
/// no longer hold their keys (`i64::MIN` without a lifetime).
fn key_lifetime_start(ttl: Option<Duration>) -> i64 {
    ttl.map_or(i64::MIN, |ttl| {
        // Rounded up: a lifetime under a millisecond is not none.
        let ttl_ms = i64::try_from(ttl.as_nanos().div_ceil(1_000_000)).unwrap_or(i64::MAX);
        crate::store::now_ms().saturating_sub(ttl_ms)
    })
}

/// The `Idempotency-Key` request header.
const IDEMPOTENCY_KEY: &str = "idempotency-key";

/// SHA-256 (hex) of what an upload stores: its metadata, its pipeline and
/// its body. `wait` is left out: it changes the answer, not the upload. The
/// body (up to `--max-body-bytes`) is hashed off the async workers.
async fn request_fingerprint(query: &IngestQuery, body: Bytes) -> Result<String, ApiError> {
    let metadata = serde_json::json!([
        query.species,
        query.external_id,
        query.acquired,
        query.source,
        query.crs,
        query.mode.unwrap_or_default().name(),
    ])
    .to_string();
    let digest = tokio::task::spawn_blocking(move || {
        let mut hash = Sha256::new();
        hash.update(metadata.as_bytes());
        hash.update([0]);
        hash.update(&body);
        hash.finalize()
    })
    .await?;
    Ok(digest.iter().map(|b| format!("{b:02x}")).collect())
}

/// The upload first stored under `idempotency`'s key, if any; a 422 when
/// that upload was another request (draft-ietf-httpapi-idempotency-key-header
/// §2.7: a key reused with a different payload).
async fn first_upload(
    state: &AppState,
    idempotency: Option<&Idempotency>,
) -> Result<Option<Ingested>, ApiError> {
    let Some(idempotency) = idempotency else {
        return Ok(None);
    };
    match state.store.ingested_by_key(idempotency).await? {
        Some((first, fingerprint)) if fingerprint == idempotency.fingerprint => {
            tracing::info!(tree = %first.tree_id, job = %first.job_id, "repeated upload answered from its key");
            Ok(Some(first))
        }
        Some(_) => Err(ApiError::IdempotencyKeyReused(format!(
            "Idempotency-Key {:?} was used for another upload (other metadata or body): send \
             a new key for a new upload",
            idempotency.key
        ))),
        None => Ok(None),
    }
}

/// How long a `wait=true` upload may wait for its job: 80 % of the request
/// time limit, less what the request has already spent (in line for a
/// slot, receiving and decoding the body). Counted from the job's queueing
/// instead, a slow decode pushed the wait past the time limit: the client
/// got a 503 for a scan that was stored and queued, and a retry stored it
/// twice.
fn wait_budget(time_limit: Duration, spent: Duration) -> Duration {
    time_limit.mul_f32(0.8).saturating_sub(spent)
}

/// Refuses an acquisition date that is not `YYYY-MM-DD`.
fn check_acquired(date: Option<&str>) -> Result<(), ApiError> {
    let Some(date) = date else { return Ok(()) };
    let format = time::macros::format_description!("[year]-[month]-[day]");
    time::Date::parse(date, &format)
        .map(|_| ())
        .map_err(|_| ApiError::BadRequest(format!("acquired: expected YYYY-MM-DD, found {date:?}")))
}

/// Longest metadata string an upload may carry, in bytes.
const MAX_METADATA_BYTES: usize = 256;

/// Refuses metadata longer than [`MAX_METADATA_BYTES`] before the cloud is
/// decoded: PostgreSQL cannot index a few kilobytes of `external_id` or
/// `species` (its btree rows stop at about 2.7 kB), so a long random one
/// failed the insert after the upload was decoded and stored nothing.
fn check_metadata_lengths(query: &IngestQuery) -> Result<(), ApiError> {
    let fields = [
        ("species", &query.species),
        ("external_id", &query.external_id),
        ("source", &query.source),
        ("crs", &query.crs),
    ];
    for (name, value) in fields {
        if let Some(len) = value
            .as_ref()
            .map(String::len)
            .filter(|&n| n > MAX_METADATA_BYTES)
        {
            return Err(ApiError::BadRequest(format!(
                "{name}: at most {MAX_METADATA_BYTES} bytes, found {len}"
            )));
        }
    }
    Ok(())
}

/// Waits until the upload's body fits in the service's upload memory
/// budget ([`Config::upload_budget_kib`]) and reserves it: its
/// `Content-Length`, or the largest body allowed when it is sent in chunks.
/// The reservation lasts until the scan is stored, or until its decode ends
/// when the request is dropped (past its time limit) while it decodes.
/// Before, every request
/// buffered its body on arrival, so a burst of large uploads (up to the
/// concurrency limit) could hold hundreds of gigabytes.
async fn reserve_upload_memory(
    state: &AppState,
    headers: &HeaderMap,
) -> Result<OwnedSemaphorePermit, ApiError> {
    let limit = state.config.max_body_bytes;
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok());
    let bytes = declared.unwrap_or(limit).min(limit);
    let kib = u32::try_from(bytes.div_ceil(1024))
        .unwrap_or(u32::MAX)
        .clamp(1, state.upload_budget_kib.max(1));
    state
        .upload_memory
        .clone()
        .acquire_many_owned(kib)
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))
}

/// The upload read and LAZ-compressed off the async workers, at most
/// `decode_slots` at a time (each holds a whole cloud in memory). The
/// decode slot and the upload's `memory` go with the blocking task: when
/// the request is dropped past its time limit, the task still runs to its
/// end, and both stay taken until then. `memory` comes back with the scan.
async fn decode_upload(
    state: &AppState,
    body: Bytes,
    memory: OwnedSemaphorePermit,
) -> Result<(crate::jobs::PreparedScan, OwnedSemaphorePermit), ApiError> {
    let slot = state
        .decode_slots
        .clone()
        .acquire_owned()
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))?;
    let max_points = state.config.max_points;
    let (scan, memory) = tokio::task::spawn_blocking(move || {
        let scan = crate::jobs::prepare_scan(&body, max_points);
        drop((body, slot));
        (scan, memory)
    })
    .await?;
    Ok((scan?, memory))
}

/// Answer for a `wait=true` upload whose job ended.
async fn finished_upload(state: &AppState, base: &str, job: &JobRow) -> Result<Response, ApiError> {
    if job.state() != crate::store::JobState::Succeeded {
        return Err(ApiError::Unprocessable(format!(
            "no tree could be reconstructed (job {}): {}",
            job.id,
            job.error.as_deref().unwrap_or("unknown error")
        )));
    }
    let tree = state
        .store
        .tree(job.tree_id)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("tree {} was deleted", job.tree_id)))?;
    Ok(with_location(
        StatusCode::CREATED,
        format!("{base}/v1/trees/{}", tree.id),
        axum::Json(Tree::from_row(&tree, base)),
    ))
}

/// Polls a job until it ends or `budget` runs out, woken early whenever a
/// job of this process finishes (other processes' jobs are seen by polling).
async fn wait_for_job(
    state: &AppState,
    job_id: Uuid,
    budget: Duration,
) -> Result<JobRow, ApiError> {
    let deadline = Instant::now() + budget;
    let mut finished = state.events.finished();
    loop {
        finished.borrow_and_update();
        let job = state
            .store
            .job(job_id)
            .await?
            .ok_or_else(|| ApiError::NotFound(format!("no job {job_id}")))?;
        let left = deadline.saturating_duration_since(Instant::now());
        if job.state().is_terminal() || left.is_zero() {
            return Ok(job);
        }
        tokio::select! {
            _ = finished.changed() => {}
            () = tokio::time::sleep(left.min(Duration::from_millis(250))) => {}
        }
    }
}

fn with_location(status: StatusCode, location: String, body: impl IntoResponse) -> Response {
    let mut res = (status, body).into_response();
    if let Ok(value) = HeaderValue::from_str(&location) {
        res.headers_mut().insert(header::LOCATION, value);
    }
    res
}

/// One tree: metadata, location, metrics and links to its downloads.
#[utoipa::path(
    get,
    path = "/v1/trees/{id}",
    tag = "trees",
    params(("id" = Uuid, Path, description = "Tree id")),
    responses(
        (status = 200, description = "The tree", body = Tree,
            headers(("ETag" = String, description = "Changes whenever the tree does"))),
        (status = 304, description = "Unchanged since the `If-None-Match` tag"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn get_tree(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    BaseUrl(base): BaseUrl,
    ApiPath(id): ApiPath<Uuid>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let row = state
        .store
        .tree(id)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("no tree {id}")))?;
    let etag = HeaderValue::from_str(&format!("\"{}-{}\"", row.id.simple(), row.version))
        .map_err(|e| ApiError::Internal(e.to_string()))?;
    if not_modified(&headers, &etag) {
        return Ok((StatusCode::NOT_MODIFIED, [(header::ETAG, etag)]).into_response());
    }
    Ok((
        [(header::ETAG, etag)],
        axum::Json(Tree::from_row(&row, &base)),
    )
        .into_response())
}

/// Delete a tree with all its scans, models and jobs.
#[utoipa::path(
    delete,
    path = "/v1/trees/{id}",
    tag = "trees",
    params(("id" = Uuid, Path, description = "Tree id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Missing or wrong API key", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such tree", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Past the request time limit before anything was written (nothing stored: safe to repeat), or still writing at twice the limit (the detail says the write may have been made)",
            body = Problem, content_type = "application/problem+json"),
    ),
    security(("api_key" = []))
)]
pub(super) async fn delete_tree(
    State(state): State<Arc<AppState>>,
    _: WriteAccess,
    clock: RequestClock,
    ApiPath(id): ApiPath<Uuid>,
) -> Result<StatusCode, ApiError> {
    clock.begin_storing();
    if state.store.delete_tree(id).await? {
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(ApiError::NotFound(format!("no tree {id}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(key: &str) -> HeaderMap {
        let mut headers = HeaderMap::new();
        headers.insert(IDEMPOTENCY_KEY, HeaderValue::from_str(key).unwrap());
        headers
    }

    #[test]
    fn an_idempotency_key_is_a_token_or_a_quoted_string_of_at_most_256_bytes() {
        let key = |text: &str| idempotency_key(&headers(text)).map_err(|e| e.to_string());
        assert_eq!(idempotency_key(&HeaderMap::new()).unwrap(), None);
        assert_eq!(key("abc-1").unwrap().as_deref(), Some("abc-1"));
        assert_eq!(key("\"abc-1\"").unwrap().as_deref(), Some("abc-1"));
        assert_eq!(key(&"k".repeat(256)).unwrap().map(|k| k.len()), Some(256));
        assert!(key(&"k".repeat(257)).unwrap_err().contains("found 257"));
        assert!(key("").is_err());
        assert!(key("\"\"").is_err());
        assert!(key("\"abc").unwrap_err().contains("must end with a quote"));
        assert!(key("a b").unwrap_err().contains("0x20"));
        assert!(key("a\\\"b").is_err());
        let mut twice = headers("a");
        twice.append(IDEMPOTENCY_KEY, HeaderValue::from_static("b"));
        assert!(
            idempotency_key(&twice)
                .unwrap_err()
                .to_string()
                .contains("more than once")
        );
    }

    #[tokio::test]
    async fn the_fingerprint_covers_metadata_mode_and_body_but_not_wait() {
        let query = |species: &str, mode, wait| IngestQuery {
            species: Some(species.into()),
            external_id: Some("t1".into()),
            acquired: None,
            source: None,
            crs: None,
            mode,
            wait,
        };
        let hash = |query: IngestQuery, body: &'static [u8]| async move {
            request_fingerprint(&query, Bytes::from_static(body))
                .await
                .unwrap()
        };
        let base = hash(query("Quercus", None, false), b"1 2 3").await;
        assert_eq!(base.len(), 64);
        assert_eq!(base, hash(query("Quercus", None, true), b"1 2 3").await);
        let auto = hash(query("Quercus", Some(Mode::Auto), false), b"1 2 3").await;
        assert_eq!(base, auto);
        for other in [
            hash(query("Quercus", None, false), b"1 2 4").await,
            hash(query("Betula", None, false), b"1 2 3").await,
            hash(query("Quercus", Some(Mode::Dense), false), b"1 2 3").await,
        ] {
            assert_ne!(base, other);
        }
    }

    #[test]
    fn the_wait_budget_counts_from_the_requests_arrival() {
        let limit = Duration::from_secs(10);
        assert_eq!(wait_budget(limit, Duration::ZERO), Duration::from_secs(8));
        assert_eq!(
            wait_budget(limit, Duration::from_secs(3)),
            Duration::from_secs(5)
        );
        assert_eq!(wait_budget(limit, Duration::from_secs(9)), Duration::ZERO);
        assert_eq!(wait_budget(limit, Duration::MAX), Duration::ZERO);
    }
}
