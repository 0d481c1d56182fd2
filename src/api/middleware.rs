//! Cross-cutting layers: problem+json for every error, request metrics,
//! ETags weakened under compression.

use std::sync::Arc;
use std::time::Instant;

use axum::body::Body;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::error::{PROBLEM_JSON, Problem};

/// Largest error body read back when normalising it (they are tiny).
const MAX_ERROR_BODY: usize = 64 * 1024;

/// Makes every 4xx/5xx an RFC 9457 document with `instance` set to the
/// request path. [`super::ApiError`] responses only gain the `instance`;
/// responses made outside handlers (unknown route, wrong method, body limit,
/// timeout, panic) are rewritten, their plain-text body kept as the detail.
pub(crate) async fn problem_details(req: Request, next: Next) -> Response {
    let instance = req.uri().path().to_owned();
    let res = next.run(req).await;
    let status = res.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return res;
    }
    let (mut parts, body) = res.into_parts();
    let is_problem = parts
        .headers
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v == PROBLEM_JSON);
    let bytes = axum::body::to_bytes(body, MAX_ERROR_BODY)
        .await
        .unwrap_or_default();
    let parsed = is_problem
        .then(|| serde_json::from_slice::<Problem>(&bytes).ok())
        .flatten();
    let mut problem = parsed.unwrap_or_else(|| {
        let text = String::from_utf8_lossy(&bytes);
        let detail = match text.trim() {
            "" => default_detail(status).to_owned(),
            text => text.chars().take(500).collect(),
        };
        Problem::new(status, slug(status), detail)
    });
    problem.instance.get_or_insert(instance);
    if status == StatusCode::PAYLOAD_TOO_LARGE {
        // The body was refused unread (or cut off), so this connection
        // cannot carry another request. Saying so keeps clients from reusing
        // it: a pooled client that raced the close got `IncompleteMessage`
        // on its next request (seen once in CI, `tests/api.rs`).
        parts
            .headers
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
    }
    parts.headers.remove(header::CONTENT_LENGTH);
    parts
        .headers
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
    let body = serde_json::to_vec(&problem).unwrap_or_default();
    Response::from_parts(parts, Body::from(body))
}

fn slug(status: StatusCode) -> &'static str {
    match status {
        StatusCode::NOT_FOUND => "not-found",
        StatusCode::METHOD_NOT_ALLOWED => "method-not-allowed",
        StatusCode::PAYLOAD_TOO_LARGE => "payload-too-large",
        StatusCode::SERVICE_UNAVAILABLE => "unavailable",
        StatusCode::INTERNAL_SERVER_ERROR => "internal",
        s if s.is_client_error() => "bad-request",
        _ => "internal",
    }
}

fn default_detail(status: StatusCode) -> &'static str {
    match status {
        StatusCode::NOT_FOUND => "no such route",
        StatusCode::METHOD_NOT_ALLOWED => "this route does not accept this method",
        StatusCode::PAYLOAD_TOO_LARGE => "the request body exceeds the configured limit",
        StatusCode::SERVICE_UNAVAILABLE => {
            "the request did not complete within the time limit, or the service is overloaded"
        }
        StatusCode::INTERNAL_SERVER_ERROR => "the service failed; the error is logged",
        _ => "the request failed",
    }
}

/// Turns a strong ETag weak when the body was compressed: the bytes on the
/// wire differ from the identity representation the tag names. Matching on
/// `If-None-Match` is weak anyway, so revalidation keeps working.
pub(crate) async fn weaken_etag_when_encoded(req: Request, next: Next) -> Response {
    let mut res = next.run(req).await;
    if res.headers().contains_key(header::CONTENT_ENCODING) {
        let weak = res
            .headers()
            .get(header::ETAG)
            .and_then(|v| v.to_str().ok())
            .filter(|v| v.starts_with('"'))
            .and_then(|v| HeaderValue::from_str(&format!("W/{v}")).ok());
        if let Some(weak) = weak {
            res.headers_mut().insert(header::ETAG, weak);
        }
    }
    res
}

/// When a request reached the service, before it waited for a slot under
/// the concurrency limit: the request time limit runs from then, so a
/// handler that spends what is left of it must count from then too.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Arrival(pub(crate) Instant);

/// Stamps each request with its [`Arrival`].
pub(crate) async fn stamp_arrival(mut req: Request, next: Next) -> Response {
    req.extensions_mut().insert(Arrival(Instant::now()));
    next.run(req).await
}

/// Records the latency of each request under its route template.
pub(crate) async fn record_metrics(
    State(state): State<Arc<AppState>>,
    req: Request,
    next: Next,
) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_owned(), |p| p.as_str().to_owned());
    let method = req.method().clone();
    let started = Instant::now();
    let res = next.run(req).await;
    state
        .metrics
        .observe_request(method.as_str(), &route, res.status(), started.elapsed());
    res
}

/// The answer for routes that do not exist.
pub(crate) async fn not_found() -> Response {
    StatusCode::NOT_FOUND.into_response()
}
