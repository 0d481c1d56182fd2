//! Extractors whose rejections are [`ApiError`]s: a malformed query or
//! path answers problem+json 400 like every other error, and an upload body
//! silva would misread ([`RawUpload`]) a 415.

use axum::extract::{FromRequestParts, Path, Query};
use axum::http::request::Parts;
use axum::http::{HeaderMap, Uri, header};
use serde::de::DeserializeOwned;

use super::ApiError;

/// Query parameters; a parse failure, or a NUL character anywhere, is a
/// 400 naming the parameter.
#[derive(Debug, Clone)]
pub struct ApiQuery<T>(pub T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for ApiQuery<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        reject_nul(&parts.uri)?;
        Query::<T>::try_from_uri(&parts.uri)
            .map(|Query(q)| ApiQuery(q))
            .map_err(|e| ApiError::BadRequest(e.body_text()))
    }
}

/// Refuses a query whose decoded names or values hold U+0000. PostgreSQL
/// `text` cannot store it, so `species=%00` on an upload or a listing came
/// back from the database as an error and a 500, while SQLite took it
/// (found by `tools/hostile_uploads.py`); no name, id or CRS needs it.
fn reject_nul(uri: &Uri) -> Result<(), ApiError> {
    // A query that does not even split into pairs is left to the typed parse.
    let Ok(Query(pairs)) = Query::<Vec<(String, String)>>::try_from_uri(uri) else {
        return Ok(());
    };
    match pairs
        .iter()
        .find(|(name, value)| name.contains('\0') || value.contains('\0'))
    {
        Some((name, _)) => Err(ApiError::BadRequest(format!(
            "query parameter {name:?} contains a NUL character"
        ))),
        None => Ok(()),
    }
}

/// Path parameters; a parse failure (e.g. an id that is not a UUID) is a 400.
#[derive(Debug, Clone)]
pub struct ApiPath<T>(pub T);

impl<T: DeserializeOwned + Send, S: Send + Sync> FromRequestParts<S> for ApiPath<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        Path::<T>::from_request_parts(parts, state)
            .await
            .map(|Path(p)| ApiPath(p))
            .map_err(|e| ApiError::BadRequest(e.body_text()))
    }
}

/// An upload body silva can read as sent, checked before the body is read:
/// a body under a content coding (`Content-Encoding: gzip`) would reach
/// format detection still compressed (and a `br` claim on plain text was
/// read as if unencoded), and a form (`multipart/form-data`, as `curl -F`
/// sends) wraps the file in boundaries. Both are a 415 that says what to
/// send, where they were a 422 about the bytes (found by
/// `tools/hostile_uploads.py`). Other content types are not checked: the
/// format is told from the content, and `curl --data-binary` labels every
/// file `application/x-www-form-urlencoded`.
#[derive(Debug, Clone, Copy)]
pub(super) struct RawUpload;

impl<S: Send + Sync> FromRequestParts<S> for RawUpload {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        if let Some(coding) = content_coding(&parts.headers) {
            return Err(ApiError::UnsupportedMediaType(format!(
                "the body is {coding}-encoded (Content-Encoding) and uploads are read as sent: \
                 send the point cloud file itself (LAZ is the compressed format)"
            )));
        }
        let content_type = parts.headers.get(header::CONTENT_TYPE).map(|v| {
            String::from_utf8_lossy(v.as_bytes())
                .trim()
                .to_ascii_lowercase()
        });
        if content_type.is_some_and(|t| t.starts_with("multipart/")) {
            return Err(ApiError::UnsupportedMediaType(
                "the body is a multipart form: send the point cloud file itself as the body \
                 (curl --data-binary @tree.laz)"
                    .into(),
            ));
        }
        Ok(RawUpload)
    }
}

/// The first content coding other than `identity` the request declares.
fn content_coding(headers: &HeaderMap) -> Option<String> {
    headers
        .get_all(header::CONTENT_ENCODING)
        .iter()
        .flat_map(|v| {
            String::from_utf8_lossy(v.as_bytes())
                .split(',')
                .map(|c| c.trim().to_owned())
                .collect::<Vec<_>>()
        })
        .find(|c| !c.is_empty() && !c.eq_ignore_ascii_case("identity"))
}
