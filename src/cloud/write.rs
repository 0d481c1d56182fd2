//! Writing point clouds: XYZ text, binary PLY, LAS and LAZ.
//!
//! `silva synth -o` writes test clouds with these, and the service stores
//! raw uploads LAZ-compressed ([`to_laz_bytes`]). LAS/LAZ keep intensity,
//! return number and classification at 1 mm resolution.

use std::fmt::Debug;
use std::fs::File;
use std::io::{BufWriter, Cursor, Seek, Write};
use std::path::Path;

use super::{CloudError, Format, PointCloud, lasfile, ply, xyz};

/// Writes `cloud` in `format` (PLY is binary little-endian).
///
/// The output is taken by value because the LAS writer needs an owned,
/// thread-safe stream; use [`write_path`] for files and [`to_laz_bytes`]
/// for memory.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::{Format, PointCloud, ReadOptions, read_path, write};
///
/// let cloud = PointCloud::from_points(DVec3::new(85_000.0, 446_000.0, 0.0), vec![Vec3::ONE]);
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("tree.bin");
/// write(&cloud, Format::Ply, std::fs::File::create(&path).unwrap()).unwrap();
/// let (back, format) = read_path(&path, &ReadOptions::default()).unwrap();
/// assert_eq!((format, back.absolute(0)), (Format::Ply, cloud.absolute(0)));
/// ```
pub fn write<W>(cloud: &PointCloud, format: Format, out: W) -> Result<(), CloudError>
where
    W: Write + Seek + Send + Sync + Debug + 'static,
{
    match format {
        Format::Xyz => xyz::write(cloud, BufWriter::new(out)),
        Format::Ply => ply::write(cloud, BufWriter::new(out)),
        Format::Las | Format::Laz => {
            let mut out = lasfile::write(cloud, format == Format::Laz, out)?;
            Ok(out.flush()?)
        }
    }
}

/// The format implied by a file name's extension (`.xyz`/`.txt`, `.ply`,
/// `.las`, `.laz`, case-insensitive).
pub fn format_for_path(path: &Path) -> Option<Format> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    Some(match ext.as_str() {
        "xyz" | "txt" => Format::Xyz,
        "ply" => Format::Ply,
        "las" => Format::Las,
        "laz" => Format::Laz,
        _ => return None,
    })
}

/// Writes `cloud` to `path`, choosing the format from the extension.
pub fn write_path(cloud: &PointCloud, path: &Path) -> Result<(), CloudError> {
    let format = format_for_path(path).ok_or_else(|| {
        CloudError::UnknownFormat(format!(
            "cannot choose an output format for {}: use .xyz, .txt, .ply, .las or .laz",
            path.display()
        ))
    })?;
    let file = BufWriter::new(File::create(path)?);
    write(cloud, format, file)
}

/// The cloud as LAZ bytes (for storing raw scans compactly).
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::cloud::{Format, PointCloud, ReadOptions, read_bytes, to_laz_bytes};
///
/// let cloud = PointCloud::from_points(DVec3::ZERO, vec![Vec3::new(1.0, 2.0, 3.0)]);
/// let laz = to_laz_bytes(&cloud).unwrap();
/// let (back, format) = read_bytes(&laz, &ReadOptions::default()).unwrap();
/// assert_eq!(format, Format::Laz);
/// assert_eq!(back.absolute(0), glam::DVec3::new(1.0, 2.0, 3.0));
/// ```
pub fn to_laz_bytes(cloud: &PointCloud) -> Result<Vec<u8>, CloudError> {
    let out = lasfile::write(cloud, true, Cursor::new(Vec::new()))?;
    Ok(out.into_inner())
}
