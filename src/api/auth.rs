//! API keys: bearer tokens compared by SHA-256 hash in constant time.
//!
//! Keys are hashed once at start-up and the plain keys dropped, so a memory
//! dump or log line never shows one. Each request's token is hashed and
//! compared with every configured hash without an early exit, so timing
//! reveals neither which key nor how much of it matched.

use std::sync::Arc;

use axum::extract::FromRequestParts;
use axum::http::header;
use axum::http::request::Parts;
use sha2::{Digest, Sha256};

use super::{ApiError, AppState};

/// The hashes of the accepted keys.
#[derive(Debug, Clone, Default)]
pub struct ApiKeys {
    hashes: Vec<[u8; 32]>,
}

impl ApiKeys {
    /// Hashes `keys`, ignoring empty ones (a trailing comma).
    pub fn new(keys: &[String]) -> Self {
        let hashes = keys
            .iter()
            .map(|k| k.trim())
            .filter(|k| !k.is_empty())
            .map(hash)
            .collect();
        Self { hashes }
    }

    /// True when no key is configured.
    pub fn is_empty(&self) -> bool {
        self.hashes.is_empty()
    }

    /// Checks the `Authorization: Bearer` header against the keys.
    pub fn check(&self, authorization: Option<&str>) -> Result<(), ApiError> {
        let token = authorization
            .and_then(|v| v.strip_prefix("Bearer "))
            .map(str::trim)
            .ok_or(ApiError::Unauthorized(
                "this route needs an API key: send Authorization: Bearer <key>",
            ))?;
        let presented = hash(token);
        let matched = self
            .hashes
            .iter()
            .fold(false, |found, h| found | constant_time_eq(h, &presented));
        if matched {
            Ok(())
        } else {
            Err(ApiError::Unauthorized("the API key is not valid"))
        }
    }
}

fn hash(key: &str) -> [u8; 32] {
    Sha256::digest(key.as_bytes()).into()
}

fn constant_time_eq(a: &[u8; 32], b: &[u8; 32]) -> bool {
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

fn authorization(parts: &Parts) -> Option<&str> {
    parts
        .headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
}

/// Proof that the request may write: a valid key, or no keys configured
/// (local use; the start-up log warns).
#[derive(Debug, Clone, Copy)]
pub struct WriteAccess;

impl FromRequestParts<Arc<AppState>> for WriteAccess {
    type Rejection = ApiError;

    async fn from_request_parts(
        parts: &mut Parts,
        state: &Arc<AppState>,
    ) -> Result<Self, ApiError> {
        if !state.keys.is_empty() {
            state.keys.check(authorization(parts))?;
        }
        Ok(WriteAccess)
    }
}

/// Proof that the request may read: always, unless `SILVA_READ_REQUIRES_KEY`.
#[derive(Debug, Clone, Copy)]
pub struct ReadAccess;

impl FromRequestParts<Arc<AppState>> for ReadAccess {
    type Rejection = ApiError;

    async fn from_request_parts(
        parts: &mut Parts,
        state: &Arc<AppState>,
    ) -> Result<Self, ApiError> {
        if state.config.read_requires_key {
            state.keys.check(authorization(parts))?;
        }
        Ok(ReadAccess)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_only_configured_bearer_keys() {
        let keys = ApiKeys::new(&["alpha".into(), " beta ".into(), String::new()]);
        assert!(keys.check(Some("Bearer alpha")).is_ok());
        assert!(keys.check(Some("Bearer beta")).is_ok());
        assert!(keys.check(Some("Bearer gamma")).is_err());
        assert!(keys.check(Some("alpha")).is_err());
        assert!(keys.check(None).is_err());
        assert!(ApiKeys::new(&[String::new()]).is_empty());
    }
}
