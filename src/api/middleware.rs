//! Cross-cutting layers: problem+json for every error, the request time
//! limit, request metrics, ETags weakened under compression.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::extract::{FromRequestParts, MatchedPath, Request, State};
use axum::http::request::Parts;
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

/// A request's standing under its time limit ([`time_limit`]), which
/// handlers extract: when it arrived, and whether it has begun to store.
///
/// The arrival is taken before the request waited for a slot under the
/// concurrency limit: the time limit runs from then, so a handler that
/// spends what is left of it must count from then too.
///
/// Once a handler has begun to store something ([`RequestClock::begin_storing`]),
/// [`time_limit`] gives the request up to one more limit to report the
/// outcome instead of answering 503 at the first. Without it, a store that
/// committed while the limit passed (a slow commit, a database lock held
/// past the limit) answered 503 for an upload that was stored, and a client
/// that retried stored it twice.
#[derive(Debug, Clone)]
pub(crate) struct RequestClock {
    arrival: Instant,
    storing: Arc<AtomicBool>,
}

impl RequestClock {
    fn start() -> Self {
        Self {
            arrival: Instant::now(),
            storing: Arc::default(),
        }
    }

    /// When the request reached the service.
    pub(crate) fn arrival(&self) -> Instant {
        self.arrival
    }

    /// Marks the request as storing: call it just before the write.
    pub(crate) fn begin_storing(&self) {
        self.storing.store(true, Ordering::Release);
    }

    fn is_storing(&self) -> bool {
        self.storing.load(Ordering::Acquire)
    }
}

impl<S: Send + Sync> FromRequestParts<S> for RequestClock {
    type Rejection = std::convert::Infallible;

    /// The request's clock; one started now (that [`time_limit`] does not
    /// read) when the request did not pass [`time_limit`].
    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Self::Rejection> {
        Ok(parts.extensions.get::<Self>().cloned().unwrap_or_else(|| {
            tracing::warn!("a request without the time limit layer: its writes are not marked");
            Self::start()
        }))
    }
}

/// The request time limit, counted from arrival (before the wait for a
/// slot under the concurrency limit): past it a request is dropped and
/// answered 503, unless its handler has begun to store ([`RequestClock`]).
/// A committed request gets one more limit to answer, after which it is
/// dropped as well and the 503 says the write may have happened.
///
/// As with tower-http's `TimeoutLayer`, which this replaces, the limit
/// covers the handler up to its response head; a streamed body is bounded
/// by the stalled-connection limit (`api::stall`) and its own rules.
pub(crate) async fn time_limit(
    State(limit): State<Duration>,
    mut req: Request,
    next: Next,
) -> Response {
    let clock = RequestClock::start();
    req.extensions_mut().insert(clock.clone());
    let handler = next.run(req);
    tokio::pin!(handler);
    if let Ok(res) = tokio::time::timeout(limit, &mut handler).await {
        return res;
    }
    if !clock.is_storing() {
        return StatusCode::SERVICE_UNAVAILABLE.into_response();
    }
    tracing::warn!(
        limit_s = limit.as_secs_f64(),
        "a request was still storing at its time limit: waiting up to one more limit for the outcome"
    );
    match tokio::time::timeout(limit, handler).await {
        Ok(res) => res,
        Err(_) => (
            StatusCode::SERVICE_UNAVAILABLE,
            "the request was still writing when twice its time limit passed: the write may \
             have been made; check the resource's state before repeating the request",
        )
            .into_response(),
    }
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

#[cfg(test)]
mod tests {
    use axum::Router;
    use axum::routing::get;
    use tower::ServiceExt;

    use super::*;

    const LIMIT: Duration = Duration::from_secs(10);

    /// A route that waits `sleep`, having first begun a write when `commits`.
    fn app(sleep: Duration, commits: bool) -> Router {
        let handler = move |clock: RequestClock| async move {
            if commits {
                clock.begin_storing();
            }
            tokio::time::sleep(sleep).await;
            "stored"
        };
        Router::new()
            .route("/", get(handler))
            .layer(axum::middleware::from_fn_with_state(LIMIT, time_limit))
    }

    async fn answer(app: Router) -> (StatusCode, String) {
        let req = Request::builder().uri("/").body(Body::empty()).unwrap();
        let res = app.oneshot(req).await.unwrap();
        let status = res.status();
        let body = axum::body::to_bytes(res.into_body(), 1 << 16)
            .await
            .unwrap();
        (status, String::from_utf8_lossy(&body).into_owned())
    }

    #[tokio::test(start_paused = true)]
    async fn a_request_within_its_limit_is_answered() {
        assert_eq!(answer(app(LIMIT / 2, false)).await.0, StatusCode::OK);
    }

    #[tokio::test(start_paused = true)]
    async fn a_request_past_its_limit_is_a_503_when_it_stored_nothing() {
        let started = tokio::time::Instant::now();
        let (status, body) = answer(app(LIMIT * 3 / 2, false)).await;
        assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(body, "");
        assert_eq!(started.elapsed(), LIMIT);
    }

    #[tokio::test(start_paused = true)]
    async fn a_request_storing_at_its_limit_reports_the_outcome() {
        let (status, body) = answer(app(LIMIT * 3 / 2, true)).await;
        assert_eq!((status, body.as_str()), (StatusCode::OK, "stored"));
    }

    #[tokio::test(start_paused = true)]
    async fn a_request_storing_past_twice_its_limit_is_a_503_that_says_so() {
        let started = tokio::time::Instant::now();
        let (status, body) = answer(app(LIMIT * 3, true)).await;
        assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
        assert!(body.contains("may have been made"), "{body}");
        assert_eq!(started.elapsed(), LIMIT * 2);
    }
}
