//! Generated downloads (meshes, CityJSON, stored encodings) kept in memory.
//!
//! A model never changes once stored (a rescan makes a new model), so an
//! entry keyed by model id can never be stale; the cache only has to bound
//! its memory. It evicts the oldest entries first once over budget.

use std::collections::{HashMap, VecDeque};
use std::sync::Mutex;

use axum::http::HeaderValue;
use bytes::Bytes;
use sha2::{Digest, Sha256};
use uuid::Uuid;

/// One download: its bytes, media type and strong ETag.
#[derive(Debug, Clone)]
pub struct Artifact {
    /// The representation.
    pub bytes: Bytes,
    /// Its media type.
    pub content_type: &'static str,
    /// Strong ETag: a hash of `bytes`.
    pub etag: HeaderValue,
}

impl Artifact {
    /// Wraps `bytes`, hashing them for the ETag.
    pub fn new(bytes: impl Into<Bytes>, content_type: &'static str) -> Self {
        let bytes = bytes.into();
        let digest = Sha256::digest(&bytes);
        let etag = HeaderValue::from_str(&format!("\"{}\"", hex::encode(&digest[..16])))
            .expect("hex is a valid header value");
        Self {
            bytes,
            content_type,
            etag,
        }
    }
}

/// What an artifact is, for one model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ArtifactKind {
    /// A stored column served as is.
    Stored(crate::store::ModelColumn),
    /// A mesh in a format at a level of detail.
    Mesh(crate::mesh::MeshFormat, crate::mesh::Lod),
    /// A single-tree CityJSON document at a level of detail.
    CityJson(crate::mesh::Lod),
    /// The skeleton as PLY.
    SkeletonPly,
    /// The compressed chain code cut down to a level of detail.
    ChainCode(crate::mesh::Lod),
}

/// A bounded map from (model, kind) to artifact.
#[derive(Debug)]
pub struct ArtifactCache {
    budget_bytes: usize,
    inner: Mutex<Entries>,
}

#[derive(Debug, Default)]
struct Entries {
    map: HashMap<(Uuid, ArtifactKind), Artifact>,
    order: VecDeque<(Uuid, ArtifactKind)>,
    bytes: usize,
}

impl ArtifactCache {
    /// A cache holding at most `budget_bytes` of artifacts.
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            budget_bytes,
            inner: Mutex::default(),
        }
    }

    /// The cached artifact, if any.
    pub fn get(&self, model: Uuid, kind: ArtifactKind) -> Option<Artifact> {
        let entries = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        entries.map.get(&(model, kind)).cloned()
    }

    /// Stores an artifact, evicting the oldest ones beyond the budget.
    /// Artifacts larger than the whole budget are not kept.
    pub fn insert(&self, model: Uuid, kind: ArtifactKind, artifact: Artifact) {
        let size = artifact.bytes.len();
        if size > self.budget_bytes {
            return;
        }
        let mut entries = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(old) = entries.map.insert((model, kind), artifact) {
            entries.bytes -= old.bytes.len();
        } else {
            entries.order.push_back((model, kind));
        }
        entries.bytes += size;
        while entries.bytes > self.budget_bytes {
            let Some(oldest) = entries.order.pop_front() else {
                break;
            };
            if let Some(old) = entries.map.remove(&oldest) {
                entries.bytes -= old.bytes.len();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::ModelColumn;

    #[test]
    fn evicts_oldest_beyond_budget() {
        let cache = ArtifactCache::new(10);
        let kind = ArtifactKind::Stored(ModelColumn::Skeleton);
        let (a, b) = (Uuid::now_v7(), Uuid::now_v7());
        cache.insert(a, kind, Artifact::new(vec![0u8; 6], "x/y"));
        cache.insert(b, kind, Artifact::new(vec![1u8; 6], "x/y"));
        assert!(cache.get(a, kind).is_none());
        assert_eq!(cache.get(b, kind).unwrap().bytes.len(), 6);
        cache.insert(a, kind, Artifact::new(vec![0u8; 11], "x/y"));
        assert!(cache.get(a, kind).is_none());
    }

    #[test]
    fn etag_names_the_bytes() {
        let one = Artifact::new(&b"tree"[..], "x/y");
        assert_eq!(one.etag, Artifact::new(&b"tree"[..], "x/y").etag);
        assert_ne!(one.etag, Artifact::new(&b"tree2"[..], "x/y").etag);
        assert!(one.etag.to_str().unwrap().starts_with('"'));
    }
}
