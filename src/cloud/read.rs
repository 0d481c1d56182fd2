//! Reading point clouds: format detection by content, and the shared
//! bounded accumulator every reader feeds.
//!
//! Readers never trust a header: point counts only size allocations after
//! they are capped by the configured point limit *and* by what the file can
//! physically hold, so a 100-byte file claiming 4 billion points costs
//! nothing. Every coordinate is checked to be finite where it is read, so
//! downstream stages (the kd-tree, reconstruction) may assume finite input.

use std::fs::File;
use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::Path;

use glam::{DVec3, Vec3};

use super::{CloudError, Format, Location, PointCloud, lasfile, ply, xyz};

/// Limits applied while reading.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadOptions {
    /// Largest number of points a reader accepts before it stops with
    /// [`CloudError::TooManyPoints`]. Memory use is about 16 bytes per point.
    pub max_points: usize,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            max_points: 50_000_000,
        }
    }
}

/// LAS facts worth reporting (`silva info`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct LasDetails {
    /// LAS version, e.g. `"1.2"`.
    pub version: String,
    /// Point data record format (0–10), without the compression bit.
    pub point_format: u8,
}

/// What a reader found besides the points.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileDetails {
    /// The detected format.
    pub format: Format,
    /// Header facts for LAS and LAZ input.
    pub las: Option<LasDetails>,
}

/// How many leading bytes [`detect`] needs to decide.
pub const DETECT_LEN: usize = 4096;

/// Detects the format from the first bytes of a file (up to [`DETECT_LEN`]).
///
/// LAS/LAZ start with `LASF` (LAZ sets a compression bit in the point format
/// byte), PLY starts with a `ply` line, and anything else that looks like
/// text is taken as XYZ. Zero bytes match nothing: no format can be told
/// from an empty file (a comment-only text file is an empty XYZ, though).
///
/// ```
/// use silva::cloud::{Format, detect};
///
/// assert_eq!(detect(b"ply\nformat ascii 1.0\n"), Some(Format::Ply));
/// assert_eq!(detect(b"1.0 2.0 3.0\n"), Some(Format::Xyz));
/// assert_eq!(detect(&[0xff, 0x00, 0x13]), None);
/// assert_eq!(detect(b""), None);
/// ```
pub fn detect(head: &[u8]) -> Option<Format> {
    if head.is_empty() {
        return None;
    }
    const POINT_FORMAT_BYTE: usize = 104;
    if head.starts_with(b"LASF") {
        // Bit 7 (LASzip) or bit 6 (old LASzip) of the point format id.
        let compressed = head
            .get(POINT_FORMAT_BYTE)
            .is_some_and(|b| b & 0b1100_0000 != 0);
        return Some(if compressed { Format::Laz } else { Format::Las });
    }
    if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
        return Some(Format::Ply);
    }
    looks_like_text(head).then_some(Format::Xyz)
}

/// UTF-8 without control characters other than tab, CR and LF. A multi-byte
/// character cut off by the end of `head` is allowed.
fn looks_like_text(head: &[u8]) -> bool {
    let valid = match std::str::from_utf8(head) {
        Ok(s) => s,
        Err(e) if e.error_len().is_none() => {
            // Only an incomplete character at the very end.
            std::str::from_utf8(&head[..e.valid_up_to()]).unwrap_or_default()
        }
        Err(_) => return false,
    };
    valid
        .chars()
        .all(|c| !c.is_control() || matches!(c, '\t' | '\r' | '\n'))
}

/// Reads a point cloud, detecting the format from its content.
///
/// Reading starts at the stream's current position, except that LAS/LAZ
/// must start at position 0 (their internal offsets are absolute). The
/// `Send + Sync` bounds come from the LASzip decoder.
///
/// ```
/// use std::io::Cursor;
/// use silva::cloud::{Format, ReadOptions, read};
///
/// let text = "# x y z\n100.5 200.25 3\n101.5,200.25,4\n";
/// let (cloud, format) = read(Cursor::new(text), &ReadOptions::default()).unwrap();
/// assert_eq!((format, cloud.len()), (Format::Xyz, 2));
/// assert_eq!(cloud.absolute(1).x, 101.5);
/// ```
pub fn read<R: Read + Seek + Send + Sync>(
    input: R,
    opts: &ReadOptions,
) -> Result<(PointCloud, Format), CloudError> {
    read_with_details(input, opts).map(|(cloud, details)| (cloud, details.format))
}

/// Like [`read`], and also returns header details (LAS version, …).
pub fn read_with_details<R: Read + Seek + Send + Sync>(
    mut input: R,
    opts: &ReadOptions,
) -> Result<(PointCloud, FileDetails), CloudError> {
    let start = input.stream_position()?;
    let mut head = Vec::with_capacity(DETECT_LEN);
    (&mut input)
        .take(DETECT_LEN as u64)
        .read_to_end(&mut head)?;
    if head.is_empty() {
        return Err(CloudError::UnknownFormat(
            "the input is empty (0 bytes)".to_owned(),
        ));
    }
    let format = detect(&head).ok_or_else(|| {
        CloudError::UnknownFormat(format!(
            "the first bytes are neither LAS/LAZ, PLY nor text (starts with {})",
            hex_preview(&head)
        ))
    })?;
    if format == Format::Xyz && looks_like_json(&head) {
        return Err(CloudError::UnknownFormat(
            "the input is JSON (a skeleton, LsJSON or CityJSON document?), not a point cloud"
                .to_owned(),
        ));
    }
    input.seek(SeekFrom::Start(start))?;
    read_as_with_details(input, format, opts)
}

/// Whether text starts like a JSON document: with `{` or `[` after any
/// byte-order mark and white space, which no XYZ line does (a comment
/// starts with `#` or `//`, a header row with a letter, a point with a
/// number).
fn looks_like_json(head: &[u8]) -> bool {
    let text = head.strip_prefix(super::xyz::BOM).unwrap_or(head);
    text.iter()
        .find(|b| !b.is_ascii_whitespace())
        .is_some_and(|b| matches!(b, b'{' | b'['))
}

/// Reads input known to be in `format`, skipping detection (fuzzing, tests).
/// For [`Format::Las`] and [`Format::Laz`] the header decides compression.
pub fn read_as<R: Read + Seek + Send + Sync>(
    input: R,
    format: Format,
    opts: &ReadOptions,
) -> Result<PointCloud, CloudError> {
    read_as_with_details(input, format, opts).map(|(cloud, _)| cloud)
}

fn read_as_with_details<R: Read + Seek + Send + Sync>(
    input: R,
    format: Format,
    opts: &ReadOptions,
) -> Result<(PointCloud, FileDetails), CloudError> {
    let (cloud, details) = match format {
        Format::Xyz => (xyz::read(input, opts)?, FileDetails { format, las: None }),
        Format::Ply => (ply::read(input, opts)?, FileDetails { format, las: None }),
        Format::Las | Format::Laz => lasfile::read(input, opts)?,
    };
    if cloud.is_empty() {
        return Err(CloudError::Empty(details.format));
    }
    Ok((cloud, details))
}

/// Reads a file, detecting the format from its content (never its name).
pub fn read_path(path: &Path, opts: &ReadOptions) -> Result<(PointCloud, Format), CloudError> {
    read_path_with_details(path, opts).map(|(cloud, details)| (cloud, details.format))
}

/// Like [`read_path`], and also returns header details.
pub fn read_path_with_details(
    path: &Path,
    opts: &ReadOptions,
) -> Result<(PointCloud, FileDetails), CloudError> {
    let file = File::open(path)?;
    read_with_details(BufReader::new(file), opts)
}

/// Reads a point cloud held in memory (an HTTP upload), detecting the format.
pub fn read_bytes(bytes: &[u8], opts: &ReadOptions) -> Result<(PointCloud, Format), CloudError> {
    read(Cursor::new(bytes), opts)
}

/// The first bytes in hex, for error messages about unknown content.
fn hex_preview(head: &[u8]) -> String {
    let shown: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
    format!("0x{}", shown.join(""))
}

/// Remaining bytes from the current position to the end of the stream; the
/// position is left unchanged.
pub(super) fn remaining_len<R: Seek>(input: &mut R) -> Result<u64, CloudError> {
    let here = input.stream_position()?;
    let end = input.seek(SeekFrom::End(0))?;
    input.seek(SeekFrom::Start(here))?;
    Ok(end.saturating_sub(here))
}

/// Optional per-point attributes in the order a reader produces them.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Attributes {
    pub(super) intensity: Option<u16>,
    pub(super) return_number: Option<u8>,
    pub(super) classification: Option<u8>,
}

/// Largest absolute coordinate a reader accepts, in metres: beyond any
/// projected or geocentric CRS, so larger values are corrupt data. Every
/// stored tree lies within it (plus its span), which is what lets exports
/// bound their integer vertices.
pub const MAX_ABS_COORDINATE_M: f64 = 1e9;
/// Largest distance from the offset (the first point, see [`CloudBuilder`]):
/// relative `f32` coordinates keep 1 mm resolution to about 8 km and 8 mm
/// at 100 km; beyond that the cloud is not a tree or a tile, and the
/// coordinates would be meaningless.
const MAX_SPAN_M: f64 = 1e5;

/// Points whose median places the offset when the first point lies apart
/// from them ([`CloudBuilder`]).
const OFFSET_SAMPLE: usize = 16;

/// Distance from the median of the first [`OFFSET_SAMPLE`] points beyond
/// which the first point is a stray and the offset is that median instead
/// (metres): within it, relative `f32` coordinates keep 0.06 mm.
const STRAY_FIRST_M: f64 = 1000.0;

/// Collects absolute points into a [`PointCloud`] under the point limit.
///
/// The offset is the first point rounded to whole metres, so that relative
/// `f32` coordinates stay sub-millimetre for anything within a few km of it;
/// unless the first point lies more than [`STRAY_FIRST_M`] from the median
/// of the first [`OFFSET_SAMPLE`] points (a stray return 99 km east would
/// otherwise leave the tree with 8 mm resolution once the stray is dropped),
/// in which case the offset is that median, rounded. The first points wait
/// in `pending` until the offset is chosen.
/// Attribute columns exist when the reader said so at construction: `with`
/// holds, per column, the value used when a point does not supply one.
pub(super) struct CloudBuilder {
    format: Format,
    limit: usize,
    cloud: PointCloud,
    with: Attributes,
    pending: Option<Vec<(DVec3, Attributes)>>,
}

impl CloudBuilder {
    /// `expected` only sizes the first allocation; callers cap it by what
    /// the file can hold. `with` marks the attribute columns to fill.
    pub(super) fn new(format: Format, opts: &ReadOptions, expected: u64, with: Attributes) -> Self {
        let cap = usize::try_from(expected)
            .unwrap_or(usize::MAX)
            .min(opts.max_points);
        let mut cloud = PointCloud::default();
        cloud.points.reserve(cap);
        cloud.intensity = with.intensity.map(|_| Vec::with_capacity(cap));
        cloud.return_number = with.return_number.map(|_| Vec::with_capacity(cap));
        cloud.classification = with.classification.map(|_| Vec::with_capacity(cap));
        Self {
            format,
            limit: opts.max_points,
            cloud,
            with,
            pending: Some(Vec::with_capacity(OFFSET_SAMPLE)),
        }
    }

    /// Adds one point; rejects non-finite coordinates and enforces the limit.
    pub(super) fn push(
        &mut self,
        p: DVec3,
        attrs: Attributes,
        location: Location,
    ) -> Result<(), CloudError> {
        let reason = if !p.is_finite() {
            Some(format!("non-finite coordinate ({}, {}, {})", p.x, p.y, p.z))
        } else if p.abs().max_element() > MAX_ABS_COORDINATE_M {
            Some(format!(
                "implausible coordinate ({}, {}, {}) m",
                p.x, p.y, p.z
            ))
        } else if self.len() > 0 && (p - self.cloud.offset).abs().max_element() > MAX_SPAN_M {
            Some(format!(
                "point ({}, {}, {}) lies more than {} km from the cloud's first points",
                p.x,
                p.y,
                p.z,
                MAX_SPAN_M / 1000.0
            ))
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(CloudError::Malformed {
                format: self.format,
                location,
                reason,
            });
        }
        if self.len() >= self.limit {
            return Err(CloudError::TooManyPoints {
                format: self.format,
                limit: self.limit,
            });
        }
        let Some(pending) = &mut self.pending else {
            self.append(p, attrs);
            return Ok(());
        };
        if pending.is_empty() {
            self.cloud.offset = p.round();
        }
        pending.push((p, attrs));
        if pending.len() == OFFSET_SAMPLE {
            self.place_offset();
        }
        Ok(())
    }

    /// Chooses the offset from the pending first points (see
    /// [`CloudBuilder`]) and appends them.
    fn place_offset(&mut self) {
        let Some(pending) = self.pending.take() else {
            return;
        };
        let median = |axis: fn(&DVec3) -> f64| {
            let mut v: Vec<f64> = pending.iter().map(|(p, _)| axis(p)).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        if let Some((first, _)) = pending.first() {
            let centre = DVec3::new(median(|p| p.x), median(|p| p.y), median(|p| p.z));
            if first.distance(centre) > STRAY_FIRST_M {
                self.cloud.offset = centre.round();
            }
        }
        for (p, attrs) in pending {
            self.append(p, attrs);
        }
    }

    /// Appends one point that [`CloudBuilder::push`] accepted, relative to
    /// the chosen offset.
    fn append(&mut self, p: DVec3, attrs: Attributes) {
        let cloud = &mut self.cloud;
        let rel: Vec3 = (p - cloud.offset).as_vec3();
        cloud.points.push(rel);
        push_attr(&mut cloud.intensity, attrs.intensity, self.with.intensity);
        push_attr(
            &mut cloud.return_number,
            attrs.return_number,
            self.with.return_number,
        );
        push_attr(
            &mut cloud.classification,
            attrs.classification,
            self.with.classification,
        );
    }

    /// Points accepted so far.
    pub(super) fn len(&self) -> usize {
        self.cloud.len() + self.pending.as_ref().map_or(0, Vec::len)
    }

    /// The finished cloud (possibly empty; callers report emptiness).
    pub(super) fn finish(mut self) -> PointCloud {
        self.place_offset();
        self.cloud
    }
}

/// Appends `value` to a present column, or the column default when the
/// reader did not supply one for this point.
fn push_attr<T: Copy>(column: &mut Option<Vec<T>>, value: Option<T>, default: Option<T>) {
    if let (Some(col), Some(d)) = (column.as_mut(), default) {
        col.push(value.unwrap_or(d));
    }
}
