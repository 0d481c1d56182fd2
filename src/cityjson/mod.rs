//! CityJSON 2.0 and CityJSONSeq output (issue 5).
//!
//! lsystem-from-adtree-skeletons §3.4 stored trees as CityJSON that no
//! reader could open: radii hidden in semantic surfaces, the skeleton in the
//! boundaries, rejected by the validator. Here every tree is a plain,
//! schema-valid `SolitaryVegetationObject`:
//! - attributes: the CityGML vegetation attributes `species`, `height`,
//!   `trunkDiameter`, `crownDiameter` (metres), plus the caller's metrics;
//! - geometry: one `MultiSurface` of the branch mesh per requested LOD (the
//!   levels of [`crate::mesh::lod`], `"lod": "0"`–`"3"`), and the skeleton as
//!   a `MultiLineString` at the finest requested LOD, so that analysis tools
//!   get the branch axes without parsing a mesh;
//! - integer vertices at 1 mm (`transform.scale` 0.001) translated to the
//!   trunk base, deduplicated;
//! - metadata with the `referenceSystem` (an OGC CRS URL) and the
//!   `geographicalExtent` of the vertices.
//!
//! CityJSONSeq (`application/city+json-seq`) streams many trees: a header
//! CityJSON object with the shared transform and metadata and empty
//! `CityObjects`/`vertices`, then one `CityJSONFeature` per line. No IO here:
//! documents are returned as JSON values or lines.
//!
//! ```
//! use glam::{DVec3, Vec3};
//! use silva::cityjson::{self, TreeInfo};
//! use silva::mesh::Lod;
//! use silva::{Anchor, NodeId, Skeleton};
//!
//! let anchor = Anchor { origin: DVec3::new(85_000.0, 446_000.0, 0.0), crs: Some("EPSG:28992".into()) };
//! let mut tree = Skeleton::new(anchor, 0.2);
//! let top = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.15);
//! tree.add_child(top, Vec3::new(1.0, 0.0, 5.0), 0.05);
//! let info = TreeInfo::new("oak-17", &tree);
//! let doc = cityjson::city_json(&info, &[Lod::L1, Lod::L3]);
//! assert_eq!(doc["CityObjects"]["oak-17"]["type"], "SolitaryVegetationObject");
//! assert_eq!(doc["metadata"]["referenceSystem"], "https://www.opengis.net/def/crs/EPSG/0/28992");
//! ```

use std::collections::HashSet;

use glam::DVec3;
use serde_json::{Map, Value, json};

use crate::mesh::Lod;
use crate::skeleton::Skeleton;

pub mod attributes;
mod figures;
mod geometry;

pub use figures::{LodFigures, lod_figures};
pub use geometry::SCALE_M;
use geometry::{VertexPool, mesh_surface, round_mm, skeleton_extent, skeleton_lines, union};

/// Media type of a CityJSON document.
pub const MEDIA_TYPE: &str = "application/city+json";
/// Media type of a CityJSONSeq stream.
pub const MEDIA_TYPE_SEQ: &str = "application/city+json-seq";

/// One tree to write: its id, skeleton, species and measured attributes.
#[derive(Debug, Clone)]
pub struct TreeInfo<'a> {
    /// City object id, unique within a document or stream.
    pub id: String,
    /// The tree's skeleton; its anchor gives the georeference and CRS.
    pub skeleton: &'a Skeleton,
    /// Species name, e.g. `"Quercus robur"`, when known.
    pub species: Option<String>,
    /// Further attributes (silva's metrics). A `height`, `trunkDiameter` or
    /// `crownDiameter` given here wins over the skeleton estimate.
    pub attributes: Map<String, Value>,
}

impl<'a> TreeInfo<'a> {
    /// A tree with no species and no extra attributes.
    pub fn new(id: impl Into<String>, skeleton: &'a Skeleton) -> Self {
        Self {
            id: id.into(),
            skeleton,
            species: None,
            attributes: Map::new(),
        }
    }

    /// The object's attributes: the caller's, then `species`, and the
    /// CityGML dimensions estimated from the skeleton where not given.
    pub fn city_attributes(&self) -> Map<String, Value> {
        let mut out = self.attributes.clone();
        if let Some(species) = &self.species {
            out.insert("species".into(), json!(species));
        }
        let s = self.skeleton;
        let derived = [
            ("height", attributes::height_m(s)),
            ("trunkDiameter", attributes::trunk_diameter_m(s)),
            ("crownDiameter", attributes::crown_diameter_m(s)),
        ];
        for (name, value) in derived {
            out.entry(name)
                .or_insert_with(|| json!(round_mm(f64::from(value))));
        }
        out
    }
}

/// Why a CityJSONSeq stream could not be written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CityJsonError {
    /// All trees of one stream share the header's CRS.
    #[error("tree {id:?} is in CRS {found:?}, but the stream is in {expected:?}")]
    MixedCrs {
        /// The offending tree.
        id: String,
        /// The first tree's CRS.
        expected: Option<String>,
        /// This tree's CRS.
        found: Option<String>,
    },
    /// City object ids must be unique within a stream.
    #[error("tree id {0:?} appears more than once")]
    DuplicateId(String),
}

/// The OGC CRS URL for a CRS string: `"EPSG:28992"` (or
/// `"urn:ogc:def:crs:EPSG::28992"`) becomes
/// `"https://www.opengis.net/def/crs/EPSG/0/28992"`; an OGC URL is kept.
/// `None` for anything else, which is then left out of the metadata rather
/// than written wrongly.
pub fn reference_system_url(crs: &str) -> Option<String> {
    let crs = crs.trim();
    if crs.starts_with("https://www.opengis.net/def/crs/")
        || crs.starts_with("http://www.opengis.net/def/crs/")
    {
        return Some(crs.to_string());
    }
    let code = crs
        .strip_prefix("EPSG:")
        .or_else(|| crs.strip_prefix("epsg:"))
        .or_else(|| crs.strip_prefix("urn:ogc:def:crs:EPSG::"))?;
    (!code.is_empty() && code.bytes().all(|b| b.is_ascii_digit()))
        .then(|| format!("https://www.opengis.net/def/crs/EPSG/0/{code}"))
}

/// A single-tree CityJSON 2.0 document with a geometry per LOD in `lods`
/// (duplicates ignored) and the skeleton lines.
pub fn city_json(tree: &TreeInfo, lods: &[Lod]) -> Value {
    let translate = snap_mm(tree.skeleton.anchor().origin);
    let mut pool = VertexPool::new(translate);
    let object = city_object(tree, lods, &mut pool);
    let mut metadata = metadata(tree.skeleton.anchor().crs.as_deref());
    if let Some(extent) = pool.extent() {
        metadata.insert("geographicalExtent".into(), json!(extent));
    }
    json!({
        "type": "CityJSON",
        "version": "2.0",
        "transform": transform(translate),
        "metadata": metadata,
        "CityObjects": {tree.id.clone(): object},
        "vertices": pool.to_json(),
    })
}

/// The header line of a CityJSONSeq stream: a CityJSON object holding the
/// `transform` every feature's vertices use (scale [`SCALE_M`], `translate`)
/// and the metadata, with empty `CityObjects` and `vertices`.
pub fn seq_header(translate: DVec3, crs: Option<&str>, extent: Option<[f64; 6]>) -> Value {
    let mut metadata = metadata(crs);
    if let Some(extent) = extent {
        metadata.insert("geographicalExtent".into(), json!(extent));
    }
    json!({
        "type": "CityJSON",
        "version": "2.0",
        "transform": transform(translate),
        "metadata": metadata,
        "CityObjects": {},
        "vertices": [],
    })
}

/// One CityJSONFeature for a stream whose header has `translate`.
pub fn city_json_feature(tree: &TreeInfo, lods: &[Lod], translate: DVec3) -> Value {
    let mut pool = VertexPool::new(translate);
    let object = city_object(tree, lods, &mut pool);
    json!({
        "type": "CityJSONFeature",
        "id": tree.id,
        "CityObjects": {tree.id.clone(): object},
        "vertices": pool.to_json(),
    })
}

/// A CityJSONSeq stream of `trees`: the header line, then one feature line
/// per tree, each without a trailing newline. Features are built lazily, one
/// tree at a time. The header's translate is the first tree's anchor and its
/// extent the union of conservative per-tree bounds (node bounds grown by
/// twice the largest radius), computed without building any mesh.
pub fn city_json_seq<'a>(
    trees: &'a [TreeInfo<'a>],
    lods: &'a [Lod],
) -> Result<impl Iterator<Item = String> + 'a, CityJsonError> {
    let crs = trees.first().and_then(|t| t.skeleton.anchor().crs.clone());
    let mut ids = HashSet::new();
    for tree in trees {
        let found = &tree.skeleton.anchor().crs;
        if *found != crs {
            return Err(CityJsonError::MixedCrs {
                id: tree.id.clone(),
                expected: crs,
                found: found.clone(),
            });
        }
        if !ids.insert(tree.id.as_str()) {
            return Err(CityJsonError::DuplicateId(tree.id.clone()));
        }
    }
    let translate = trees
        .first()
        .map_or(DVec3::ZERO, |t| snap_mm(t.skeleton.anchor().origin));
    let extent = trees
        .iter()
        .map(|t| skeleton_extent(t.skeleton))
        .reduce(union);
    let header = seq_header(translate, crs.as_deref(), extent).to_string();
    let features = trees
        .iter()
        .map(move |t| city_json_feature(t, lods, translate).to_string());
    Ok(std::iter::once(header).chain(features))
}

/// The SolitaryVegetationObject of one tree, its vertices added to `pool`.
fn city_object(tree: &TreeInfo, lods: &[Lod], pool: &mut VertexPool) -> Value {
    let mut levels = lods.to_vec();
    levels.sort();
    levels.dedup();
    let mut geometry: Vec<Value> = levels
        .iter()
        .filter_map(|&lod| mesh_surface(tree.skeleton, lod, pool))
        .collect();
    let finest = levels.last().copied().unwrap_or(Lod::L3);
    geometry.extend(skeleton_lines(tree.skeleton, finest, pool));
    let mut object = json!({
        "type": "SolitaryVegetationObject",
        "attributes": tree.city_attributes(),
    });
    if !geometry.is_empty() {
        object["geometry"] = json!(geometry);
    }
    object
}

fn transform(translate: DVec3) -> Value {
    json!({"scale": [SCALE_M, SCALE_M, SCALE_M], "translate": translate.to_array()})
}

fn metadata(crs: Option<&str>) -> Map<String, Value> {
    let mut metadata = Map::new();
    if let Some(url) = crs.and_then(reference_system_url) {
        metadata.insert("referenceSystem".into(), json!(url));
    }
    metadata
}

/// `p` rounded to the millimetre grid of the integer vertices.
fn snap_mm(p: DVec3) -> DVec3 {
    DVec3::new(round_mm(p.x), round_mm(p.y), round_mm(p.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crs_urls() {
        let url = "https://www.opengis.net/def/crs/EPSG/0/28992";
        assert_eq!(reference_system_url("EPSG:28992").as_deref(), Some(url));
        assert_eq!(
            reference_system_url("urn:ogc:def:crs:EPSG::28992").as_deref(),
            Some(url)
        );
        assert_eq!(reference_system_url(url).as_deref(), Some(url));
        assert_eq!(reference_system_url("EPSG:"), None);
        assert_eq!(reference_system_url("EPSG:28992; DROP"), None);
        assert_eq!(reference_system_url("+proj=utm"), None);
    }
}
