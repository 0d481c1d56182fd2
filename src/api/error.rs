//! The one error type of the API and its RFC 9457 problem+json form.
//!
//! Handlers return `Result<_, ApiError>` and use `?`; the variant alone picks
//! the status, so the same failure always gets the same answer. Responses
//! that fail outside a handler (unknown route, body limit, timeout, panic)
//! are turned into the same form by [`super::middleware::problem_details`].

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::cloud::CloudError;
use crate::store::StoreError;

/// The media type of error responses.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// An RFC 9457 problem details document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Problem {
    /// URI naming the kind of problem, e.g. `urn:silva:problem:not-found`.
    #[serde(rename = "type")]
    pub problem_type: String,
    /// Short summary of the kind of problem.
    pub title: String,
    /// The HTTP status code.
    pub status: u16,
    /// What went wrong with this request, in one line.
    pub detail: String,
    /// The request path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instance: Option<String>,
}

impl Problem {
    /// A problem for `status`, titled with its reason phrase.
    pub fn new(status: StatusCode, slug: &str, detail: impl Into<String>) -> Self {
        Self {
            problem_type: format!("urn:silva:problem:{slug}"),
            title: status.canonical_reason().unwrap_or("Error").to_owned(),
            status: status.as_u16(),
            detail: detail.into(),
            instance: None,
        }
    }

    /// The problem as an HTTP response.
    pub fn into_response_with(self, status: StatusCode) -> Response {
        let body = serde_json::to_vec(&self).unwrap_or_default();
        let mut res = (status, body).into_response();
        res.headers_mut()
            .insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        res
    }
}

/// Why a request failed.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// The request is malformed (query, path, headers).
    #[error("{0}")]
    BadRequest(String),
    /// A key is required and was missing or wrong.
    #[error("{0}")]
    Unauthorized(&'static str),
    /// No such resource.
    #[error("{0}")]
    NotFound(String),
    /// The resource is not in a state that allows this (e.g. no model yet).
    #[error("{0}")]
    Conflict(String),
    /// The body exceeds the configured limit.
    #[error("request body exceeds the limit of {limit} bytes")]
    PayloadTooLarge {
        /// The limit in bytes.
        limit: usize,
    },
    /// The body comes in a form silva does not read (a content coding, a
    /// multipart form); the file itself would be accepted.
    #[error("{0}")]
    UnsupportedMediaType(String),
    /// The body is well-formed HTTP but not a usable point cloud.
    #[error("{0}")]
    Unprocessable(String),
    /// An `Idempotency-Key` sent again with another upload.
    #[error("{0}")]
    IdempotencyKeyReused(String),
    /// The database cannot be reached.
    #[error("{0}")]
    Unavailable(String),
    /// A fault of the service itself; details go to the log only.
    #[error("{0}")]
    Internal(String),
}

impl ApiError {
    /// The status and problem type slug of the variant.
    fn status(&self) -> (StatusCode, &'static str) {
        match self {
            ApiError::BadRequest(_) => (StatusCode::BAD_REQUEST, "bad-request"),
            ApiError::Unauthorized(_) => (StatusCode::UNAUTHORIZED, "unauthorized"),
            ApiError::NotFound(_) => (StatusCode::NOT_FOUND, "not-found"),
            ApiError::Conflict(_) => (StatusCode::CONFLICT, "conflict"),
            ApiError::PayloadTooLarge { .. } => {
                (StatusCode::PAYLOAD_TOO_LARGE, "payload-too-large")
            }
            ApiError::UnsupportedMediaType(_) => {
                (StatusCode::UNSUPPORTED_MEDIA_TYPE, "unsupported-media-type")
            }
            ApiError::Unprocessable(_) => (StatusCode::UNPROCESSABLE_ENTITY, "unprocessable-cloud"),
            ApiError::IdempotencyKeyReused(_) => {
                (StatusCode::UNPROCESSABLE_ENTITY, "idempotency-key-reused")
            }
            ApiError::Unavailable(_) => (StatusCode::SERVICE_UNAVAILABLE, "unavailable"),
            ApiError::Internal(_) => (StatusCode::INTERNAL_SERVER_ERROR, "internal"),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let (status, slug) = self.status();
        let detail = match &self {
            ApiError::Internal(message) => {
                tracing::error!(error = %message, "internal error");
                "the service failed; the error is logged".to_owned()
            }
            ApiError::Unavailable(message) => {
                tracing::warn!(error = %message, "database unavailable");
                "the database is unavailable; retry later".to_owned()
            }
            other => other.to_string(),
        };
        let mut res = Problem::new(status, slug, detail).into_response_with(status);
        if status == StatusCode::UNAUTHORIZED {
            res.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"silva\""),
            );
        }
        if status == StatusCode::UNSUPPORTED_MEDIA_TYPE {
            // RFC 9110 §12.5.3: the codings a request may use.
            res.headers_mut().insert(
                header::ACCEPT_ENCODING,
                HeaderValue::from_static("identity"),
            );
        }
        res
    }
}

impl From<StoreError> for ApiError {
    fn from(err: StoreError) -> Self {
        if err.is_unavailable() {
            ApiError::Unavailable(err.to_string())
        } else {
            ApiError::Internal(err.to_string())
        }
    }
}

impl From<CloudError> for ApiError {
    /// Every reader error is a property of the upload: 422 with the reader's
    /// one-line message.
    fn from(err: CloudError) -> Self {
        ApiError::Unprocessable(err.to_string())
    }
}

impl From<tokio::task::JoinError> for ApiError {
    fn from(err: tokio::task::JoinError) -> Self {
        ApiError::Internal(format!("background task: {err}"))
    }
}
