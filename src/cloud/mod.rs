//! Point clouds: the [`PointCloud`] type, format readers, and clean-up passes.
//!
//! First stage of the pipeline (`cloud` → `reconstruct` → `encode` → …).
//! Readers detect the format from content, never from the file name, and
//! stream, so memory is bounded by a point limit. Clean-up passes prepare
//! clouds for reconstruction (AdTree's near-duplicate removal, statistical
//! outlier removal, voxel downsampling).
//!
//! ```
//! use silva::cloud::{Format, ReadOptions, read_bytes};
//!
//! let (cloud, format) = read_bytes(b"0 0 0\n1 0 0\n", &ReadOptions::default()).unwrap();
//! assert_eq!((format, cloud.len()), (Format::Xyz, 2));
//!
//! let broken = read_bytes(b"0 0 0\n1 nan 0\n", &ReadOptions::default()).unwrap_err();
//! assert_eq!(broken.to_string(), "XYZ: line 2: non-finite coordinate (1, NaN, 0)");
//! ```

use glam::{DVec3, Vec3};

/// A point cloud in metres, relative to an `f64` offset.
///
/// Coordinates in national grids are large (x ≈ 155,000 m in EPSG:28992), so
/// points are stored as `f32` offsets from [`PointCloud::offset`], which keeps
/// sub-millimetre resolution for anything tree-sized. Per-point attributes
/// are optional and, when present, have one entry per point.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::PointCloud;
///
/// let mut cloud = PointCloud::new(DVec3::new(155_000.0, 463_000.0, 0.0));
/// cloud.points.push(Vec3::new(0.5, 0.25, 1.0));
/// assert_eq!(cloud.absolute(0), DVec3::new(155_000.5, 463_000.25, 1.0));
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Origin of the relative coordinates, in CRS units (metres).
    pub offset: DVec3,
    /// Points relative to `offset`, in metres.
    pub points: Vec<Vec3>,
    /// Return intensity (LAS semantics), one per point when present.
    pub intensity: Option<Vec<u16>>,
    /// Return number (1-based), one per point when present.
    pub return_number: Option<Vec<u8>>,
    /// ASPRS classification (2 = ground), one per point when present.
    pub classification: Option<Vec<u8>>,
}

/// ASPRS LAS classification code for ground points.
pub const CLASS_GROUND: u8 = 2;

/// ASPRS LAS classification codes of noise: 7, "low point (noise)", and 18,
/// "high noise" (LAS 1.4 point formats 6–10 only).
pub const CLASSES_NOISE: [u8; 2] = [7, 18];

impl PointCloud {
    /// An empty cloud with the given offset.
    pub fn new(offset: DVec3) -> Self {
        Self {
            offset,
            ..Self::default()
        }
    }

    /// A cloud without attributes from relative points.
    pub fn from_points(offset: DVec3, points: Vec<Vec3>) -> Self {
        Self {
            offset,
            points,
            ..Self::default()
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Absolute coordinates of point `i`, in full `f64` precision.
    pub fn absolute(&self, i: usize) -> DVec3 {
        self.offset + self.points[i].as_dvec3()
    }

    /// Relative bounds `(min, max)`, or `None` for an empty cloud.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.points.first()?;
        Some(
            self.points
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Absolute bounds `(min, max)`, or `None` for an empty cloud.
    pub fn absolute_bounds(&self) -> Option<(DVec3, DVec3)> {
        let (lo, hi) = self.bounds()?;
        Some((self.offset + lo.as_dvec3(), self.offset + hi.as_dvec3()))
    }

    /// A new cloud with the points at `indices` (in that order), attributes
    /// carried along.
    pub fn select(&self, indices: &[usize]) -> PointCloud {
        fn pick<T: Copy>(v: &Option<Vec<T>>, idx: &[usize]) -> Option<Vec<T>> {
            v.as_ref().map(|v| idx.iter().map(|&i| v[i]).collect())
        }
        PointCloud {
            offset: self.offset,
            points: indices.iter().map(|&i| self.points[i]).collect(),
            intensity: pick(&self.intensity, indices),
            return_number: pick(&self.return_number, indices),
            classification: pick(&self.classification, indices),
        }
    }

    /// Keeps the points for which `keep(i)` is true, attributes carried along.
    pub fn retain_indices(&self, mut keep: impl FnMut(usize) -> bool) -> PointCloud {
        let idx: Vec<usize> = (0..self.len()).filter(|&i| keep(i)).collect();
        self.select(&idx)
    }

    /// The same points expressed relative to a new offset.
    pub fn rebased(&self, offset: DVec3) -> PointCloud {
        let old = self.offset;
        PointCloud {
            offset,
            points: self
                .points
                .iter()
                .map(|&p| (old + p.as_dvec3() - offset).as_vec3())
                .collect(),
            intensity: self.intensity.clone(),
            return_number: self.return_number.clone(),
            classification: self.classification.clone(),
        }
    }
}

pub mod clean;
mod error;
mod guard;
mod lasfile;
mod ply;
mod read;
mod write;
mod xyz;

pub use error::{CloudError, Format, Location};
pub(crate) use ply::{PlyDocument, read_document};
pub use read::{
    DETECT_LEN, FileDetails, LasDetails, MAX_ABS_COORDINATE_M, ReadOptions, detect, read, read_as,
    read_bytes, read_path, read_path_with_details, read_with_details,
};
pub use write::{format_for_path, to_laz_bytes, write, write_path};
