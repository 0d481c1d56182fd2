//! The skeleton's JSON form: `{"format":"silva-skeleton","version":1, ...}`.
//!
//! Raw and domain types are kept apart: [`RawSkeleton`] mirrors the document,
//! and only [`Skeleton::from_json`] turns it into a validated [`Skeleton`].
//! Each node is `[x, y, z, radius_m, parent]` with coordinates relative to
//! the anchor and `parent = -1` for the root. Nodes are written in canonical
//! depth-first order, so children order (main extension first) survives the
//! round trip.

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::{Anchor, Node, NodeId, Skeleton, SkeletonError};

const FORMAT: &str = "silva-skeleton";
const VERSION: u32 = 1;

/// Why a skeleton JSON document was rejected.
#[derive(Debug, thiserror::Error)]
pub enum SkeletonJsonError {
    /// Not JSON, or not of the expected shape.
    #[error("skeleton JSON: {0}")]
    Syntax(#[from] serde_json::Error),
    /// The `format` or `version` field is not one this build reads.
    #[error(
        "skeleton JSON: expected format \"{FORMAT}\" version {VERSION}, found \"{0}\" version {1}"
    )]
    Version(String, u32),
    /// A parent index is not an earlier node (or -1 for the root).
    #[error("skeleton JSON: node {0} has parent {1}, not an earlier node")]
    Parent(usize, i64),
    /// The nodes do not form a valid skeleton.
    #[error("skeleton JSON: {0}")]
    Invalid(#[from] SkeletonError),
}

#[derive(Serialize, Deserialize)]
struct RawSkeleton {
    format: String,
    version: u32,
    anchor: RawAnchor,
    /// `[x, y, z, radius_m, parent]`.
    nodes: Vec<(f32, f32, f32, f32, i64)>,
}

#[derive(Serialize, Deserialize)]
struct RawAnchor {
    origin: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    crs: Option<String>,
}

impl Skeleton {
    /// Serialises to the silva skeleton JSON document.
    ///
    /// ```
    /// # use silva::skeleton::{Anchor, NodeId, Skeleton};
    /// # use glam::{DVec3, Vec3};
    /// let mut s = Skeleton::new(Anchor::at(DVec3::new(85_000.5, 446_000.25, -1.0)), 0.25);
    /// s.add_child(NodeId::ROOT, Vec3::new(0.001, 0.0, 3.0), 0.2);
    /// let back = Skeleton::from_json(&s.to_json()).unwrap();
    /// assert_eq!(back, s);
    /// ```
    pub fn to_json(&self) -> String {
        let canon = self.canonical();
        let raw = RawSkeleton {
            format: FORMAT.into(),
            version: VERSION,
            anchor: RawAnchor {
                origin: canon.anchor.origin.to_array(),
                crs: canon.anchor.crs.clone(),
            },
            nodes: canon
                .nodes
                .iter()
                .map(|n| {
                    let p = n.position;
                    let parent = n.parent.map_or(-1, |p| p.index() as i64);
                    (p.x, p.y, p.z, n.radius_m, parent)
                })
                .collect(),
        };
        serde_json::to_string(&raw).expect("skeleton JSON serialisation cannot fail")
    }

    /// Parses and validates a silva skeleton JSON document.
    pub fn from_json(text: &str) -> Result<Skeleton, SkeletonJsonError> {
        let raw: RawSkeleton = serde_json::from_str(text)?;
        if raw.format != FORMAT || raw.version != VERSION {
            return Err(SkeletonJsonError::Version(raw.format, raw.version));
        }
        let nodes = raw
            .nodes
            .iter()
            .enumerate()
            .map(|(i, &(x, y, z, r, parent))| {
                let parent = match parent {
                    -1 => None,
                    p if p >= 0 && (p as usize) < i => Some(NodeId::from_index(p as usize)),
                    p => return Err(SkeletonJsonError::Parent(i, p)),
                };
                Ok(Node {
                    position: Vec3::new(x, y, z),
                    radius_m: r,
                    parent,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let anchor = Anchor {
            origin: DVec3::from_array(raw.anchor.origin),
            crs: raw.anchor.crs,
        };
        Ok(Skeleton::from_nodes(anchor, nodes)?)
    }
}
