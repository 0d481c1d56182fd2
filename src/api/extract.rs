//! Extractors whose rejections are [`ApiError`]s, so a malformed query or
//! path answers problem+json 400 like every other error.

use axum::extract::{FromRequestParts, Path, Query};
use axum::http::Uri;
use axum::http::request::Parts;
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
