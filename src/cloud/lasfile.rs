//! LAS 1.0–1.4 and LAZ reading and writing through the `las` and `laz` crates.
//!
//! The `las` crate parses headers and points; silva drives the point loop
//! itself (rather than `las::Reader`) so that it can (1) check the header
//! against the file size *before* anything is allocated, (2) name the point
//! or byte where decoding failed, and (3) read from borrowed, non-`'static`
//! sources such as an upload buffer.
//!
//! The decoders trust their input, and `cargo fuzz run las` showed what that
//! costs. Checked up front: an extended VLR may declare 2^64 bytes, a LAZ
//! chunk table 4 billion chunks, a layered chunk 4 GiB layers (all allocated
//! before reading); a variable-size chunk table may cover fewer points than
//! the header promises (the decoder then indexes past it); odd compressor and
//! item combinations send laz to the wrong offsets. Contained while decoding:
//! corrupt entropy-coded bytes can make laz panic ([`guard::contain`]) or
//! recurse without bound in its GPS time decoder ([`DepthLimitedReader`]).

use std::io::{BufReader, Read, Seek, SeekFrom, Write};

use glam::DVec3;
use las::raw;
use laz::DecompressionSelection;
use laz::laszip::{ChunkTable, LasZipDecompressor, LazVlr};

use super::read::{Attributes, CloudBuilder, FileDetails, LasDetails, ReadOptions, remaining_len};
use super::{CloudError, Format, Location, PointCloud, guard};

/// Size of an extended VLR header (LAS 1.4 §2.7).
const EVLR_HEADER_LEN: u64 = 60;

fn malformed(format: Format, location: Location, reason: impl Into<String>) -> CloudError {
    CloudError::Malformed {
        format,
        location,
        reason: reason.into(),
    }
}

/// Reads LAS or LAZ (the header's compression bit decides).
pub(super) fn read<R: Read + Seek + Send + Sync>(
    input: R,
    opts: &ReadOptions,
) -> Result<(PointCloud, FileDetails), CloudError> {
    let mut input = BufReader::new(input);
    // LAS offsets (point data, EVLRs, the LAZ chunk table) are absolute.
    if input.stream_position()? != 0 {
        return Err(malformed(
            Format::Las,
            Location::Byte(0),
            "LAS data must start at the beginning of the stream",
        ));
    }
    let file_len = remaining_len(&mut input)?;
    let raw_header = raw::Header::read_from(&mut input)
        .map_err(|e| malformed(Format::Las, Location::Header, las_reason(&e)))?;
    let format = if raw_header.point_data_record_format & 0b1100_0000 != 0 {
        Format::Laz
    } else {
        Format::Las
    };
    let points = precheck_header(&raw_header, format, &mut input, file_len, opts)?;
    input.rewind()?;
    let header = guard::contain(|| las::Header::new(&mut input))
        .map_err(|panic| malformed(format, Location::Header, panic))?
        .map_err(|e| malformed(format, Location::Header, las_reason(&e)))?;
    let details = FileDetails {
        format,
        las: Some(LasDetails {
            version: format!("{}.{}", header.version().major, header.version().minor),
            point_format: raw_header.point_data_record_format & 0b0011_1111,
        }),
    };
    let points_start = u64::from(raw_header.offset_to_point_data);
    let record_len = u64::from(raw_header.point_data_record_length);
    let expected = points.min((file_len - points_start.min(file_len)) / record_len.max(1));
    let with = Attributes {
        intensity: Some(0),
        return_number: Some(1),
        classification: Some(1),
    };
    let mut builder = CloudBuilder::new(format, opts, expected, with);
    input.seek(SeekFrom::Start(points_start))?;
    guard::contain(|| {
        if format == Format::Laz {
            read_laz_points(&mut input, &header, points, file_len, &mut builder)
        } else {
            read_las_points(&mut input, &header, points, points_start, &mut builder)
        }
    })
    .map_err(|panic| {
        malformed(
            format,
            Location::Point(builder.len() as u64),
            format!("corrupt data: the decoder failed ({panic})"),
        )
    })??;
    Ok((builder.finish(), details))
}

/// The number of point records, after checking that the header's sizes are
/// consistent with the file and within the point limit.
fn precheck_header<R: Read + Seek>(
    h: &raw::Header,
    format: Format,
    input: &mut R,
    file_len: u64,
    opts: &ReadOptions,
) -> Result<u64, CloudError> {
    let points = match h.large_file {
        Some(large) if h.number_of_point_records == 0 => large.number_of_point_records,
        _ => u64::from(h.number_of_point_records),
    };
    if points > opts.max_points as u64 {
        return Err(CloudError::TooManyPoints {
            format,
            limit: opts.max_points,
        });
    }
    let points_start = u64::from(h.offset_to_point_data);
    if points_start > file_len || h.offset_to_point_data < u32::from(h.header_size) {
        return Err(malformed(
            format,
            Location::Byte(96),
            format!(
                "offset to point data {} is outside the file ({} bytes) or inside the header",
                h.offset_to_point_data, file_len
            ),
        ));
    }
    let record_len = u64::from(h.point_data_record_length);
    let point_bytes = points.saturating_mul(record_len);
    if format == Format::Las && point_bytes > file_len - points_start {
        let held = (file_len - points_start) / record_len.max(1);
        return Err(malformed(
            format,
            Location::Byte(file_len),
            format!("header promises {points} points but the file holds only {held}"),
        ));
    }
    if let Some(evlr) = h.evlr {
        precheck_evlr(evlr.start_of_first_evlr, format, input, file_len)?;
    }
    Ok(points)
}

/// Reads the first extended VLR's declared length and rejects it when it
/// runs past the end of the file (the `las` crate would allocate it whole).
fn precheck_evlr<R: Read + Seek>(
    at: u64,
    format: Format,
    input: &mut R,
    file_len: u64,
) -> Result<(), CloudError> {
    let bad = |reason: &str| malformed(format, Location::Byte(at), reason.to_owned());
    if at.saturating_add(EVLR_HEADER_LEN) > file_len {
        return Err(bad("extended VLR starts beyond the end of the file"));
    }
    input.seek(SeekFrom::Start(at + 20))?;
    let mut len = [0u8; 8];
    input.read_exact(&mut len)?;
    if u64::from_le_bytes(len) > file_len - at - EVLR_HEADER_LEN {
        return Err(bad("extended VLR is longer than the rest of the file"));
    }
    Ok(())
}

/// Uncompressed points: fixed-size records read in sequence.
fn read_las_points<R: Read>(
    input: &mut R,
    header: &las::Header,
    points: u64,
    points_start: u64,
    builder: &mut CloudBuilder,
) -> Result<(), CloudError> {
    let record_len = u64::from(header.point_format().len());
    for i in 0..points {
        let at = points_start + i * record_len;
        let p = raw::Point::read_from(&mut *input, header.point_format())
            .map_err(|e| malformed(Format::Las, Location::Byte(at), format!("point {i}: {e}")))?;
        push_raw(builder, &p, header, Location::Point(i))?;
    }
    Ok(())
}

/// Compressed points: validate the LASzip VLR and chunk table, then
/// decompress one record at a time.
fn read_laz_points<R: Read + Seek + Send + Sync>(
    input: &mut R,
    header: &las::Header,
    points: u64,
    file_len: u64,
    builder: &mut CloudBuilder,
) -> Result<(), CloudError> {
    let bad_header = |reason: String| malformed(Format::Laz, Location::Header, reason);
    let vlr = header.laz_vlr().map_err(|e| bad_header(las_reason(&e)))?;
    let record_len = header.point_format().len();
    if vlr.items_size() != u64::from(record_len) {
        return Err(bad_header(format!(
            "LASzip items describe {}-byte records but the point format has {record_len} bytes",
            vlr.items_size()
        )));
    }
    let data_start = input.stream_position()?;
    let table = precheck_chunk_table(input, &vlr, points, file_len)?;
    let compressor = laszip_compressor(header)?;
    precheck_layers(input, &vlr, compressor, table.as_ref(), points, file_len)?;
    // The decoder runs on its own thread so that its recursion (see
    // `DepthLimitedReader`) has a known stack to stay within.
    std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("laz-decoder".to_owned())
            .stack_size(DECODER_STACK)
            .spawn_scoped(scope, || {
                guard::contain(|| decode_laz(input, header, vlr, data_start, points, builder))
                    .unwrap_or_else(|panic| {
                        Err(malformed(
                            Format::Laz,
                            Location::Point(builder.len() as u64),
                            format!("corrupt data: the decoder failed ({panic})"),
                        ))
                    })
            })
            .map_err(CloudError::Io)?
            .join()
            .unwrap_or_else(|_| {
                Err(malformed(
                    Format::Laz,
                    Location::Header,
                    "decoder thread failed",
                ))
            })
    })
}

/// Stack of the decoder thread, and how deep the decoder may recurse in it.
/// Between two byte reads a saturated arithmetic model lets the recursion
/// go about 36 000 levels (≈ 2–5 MB) deeper, which the margin covers.
const DECODER_STACK: usize = 64 << 20;
const DECODER_MAX_DEPTH: usize = 16 << 20;

/// The point loop proper, on the decoder thread.
fn decode_laz<R: Read + Seek + Send + Sync>(
    input: &mut R,
    header: &las::Header,
    vlr: LazVlr,
    data_start: u64,
    points: u64,
    builder: &mut CloudBuilder,
) -> Result<(), CloudError> {
    let record_len = usize::from(header.point_format().len());
    let reader = DepthLimitedReader {
        inner: input,
        base: stack_address(),
    };
    // silva keeps x, y, z, return number, intensity and classification. Not
    // decoding GPS time also avoids the layered decoder's recursive GPS path.
    let selection = DecompressionSelection::base()
        .decompress_z()
        .decompress_intensity()
        .decompress_classification();
    let mut decompressor = LasZipDecompressor::selective(reader, vlr, selection).map_err(|e| {
        malformed(
            Format::Laz,
            Location::Byte(data_start),
            format!("cannot start LASzip decompression ({e})"),
        )
    })?;
    let mut buf = vec![0u8; record_len];
    for i in 0..points {
        decompressor.decompress_one(&mut buf).map_err(|e| {
            malformed(
                Format::Laz,
                Location::Point(i),
                format!("compressed data truncated or corrupt ({e})"),
            )
        })?;
        let p = raw::Point::read_from(buf.as_slice(), header.point_format())
            .map_err(|e| malformed(Format::Laz, Location::Point(i), e.to_string()))?;
        push_raw(builder, &p, header, Location::Point(i))?;
    }
    Ok(())
}

/// An address on the current stack, to measure how deep a call chain went.
/// Only compared, never dereferenced.
fn stack_address() -> usize {
    let marker = 0u8;
    std::hint::black_box(&marker) as *const u8 as usize
}

/// The reader handed to the LASzip decoder. laz's point-wise GPS time
/// decoder (LASzip v1/v2, used by LAS 1.2 formats 1 and 3) calls itself once
/// per "switch sequence" symbol; corrupt data can repeat that symbol for
/// millions of levels and overflow the stack, which no `Result` or
/// `catch_unwind` survives (found by `cargo fuzz run las`). Every level
/// eventually reads input, so this reader refuses to read once the call chain
/// is deeper than [`DECODER_MAX_DEPTH`], and the decoder unwinds with an error.
struct DepthLimitedReader<'a, R> {
    inner: &'a mut R,
    base: usize,
}

impl<R: Read> Read for DepthLimitedReader<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.base.abs_diff(stack_address()) > DECODER_MAX_DEPTH {
            return Err(std::io::Error::other(
                "the decoder recursed too deeply (corrupt GPS time data)",
            ));
        }
        self.inner.read(buf)
    }
}

impl<R: Seek> Seek for DepthLimitedReader<'_, R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// Bounds the chunk table before `laz` allocates it, and checks that a
/// variable-size table covers every point the header promises. Leaves the
/// stream where it found it (the start of the point data). Returns the
/// table when there is one.
fn precheck_chunk_table<R: Read + Seek>(
    input: &mut R,
    vlr: &LazVlr,
    points: u64,
    file_len: u64,
) -> Result<Option<ChunkTable>, CloudError> {
    let data_start = input.stream_position()?;
    let bad = |at: u64, reason: String| malformed(Format::Laz, Location::Byte(at), reason);
    let Some(table_start) = chunk_table_start(input, data_start, file_len)? else {
        // No table: `laz` falls back to sequential reading or reports it.
        input.seek(SeekFrom::Start(data_start))?;
        return Ok(None);
    };
    input.seek(SeekFrom::Start(table_start))?;
    let mut head = [0u8; 8];
    input.read_exact(&mut head).map_err(|_| {
        bad(
            table_start,
            format!("truncated: the chunk table lies past the end of the file ({file_len} bytes)"),
        )
    })?;
    let chunks = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
    // Every chunk holds at least one point and one byte.
    if chunks > points.saturating_add(1) || chunks > file_len {
        return Err(bad(
            table_start,
            format!("chunk table lists {chunks} chunks for {points} points"),
        ));
    }
    input.seek(SeekFrom::Start(data_start))?;
    let table = ChunkTable::read_from(&mut *input, vlr)
        .map_err(|e| bad(table_start, format!("unreadable chunk table ({e})")))?;
    if vlr.uses_variable_size_chunks() {
        let covered = table
            .as_ref()
            .iter()
            .fold(0u64, |sum, entry| sum.saturating_add(entry.point_count));
        if covered < points {
            return Err(bad(
                table_start,
                format!("chunk table covers {covered} points but the header promises {points}"),
            ));
        }
    }
    input.seek(SeekFrom::Start(data_start))?;
    Ok(Some(table))
}

/// LASzip's compressor codes (LASzip VLR, first `u16`).
const POINT_WISE: u16 = 1;
const POINT_WISE_CHUNKED: u16 = 2;
const LAYERED_CHUNKED: u16 = 3;

/// The compressor code of the LASzip VLR. laz does not expose it, and some
/// combinations it accepts lead it astray (a point-wise stream with variable
/// chunks panics; layered items without chunks are looked for 8 bytes early),
/// so silva accepts only the combinations LASzip writes.
fn laszip_compressor(header: &las::Header) -> Result<u16, CloudError> {
    let data = header
        .vlrs()
        .iter()
        .find(|v| las::laz::is_laszip_vlr(v))
        .map(|v| v.data.as_slice())
        .unwrap_or_default();
    let byte = |i: usize| data.get(i).copied().unwrap_or(0);
    let code = u16::from_le_bytes([byte(0), byte(1)]);
    // Chunk size u32::MAX (bytes 12..16) marks variable-size chunks.
    let variable = (12..16).all(|i| byte(i) == 0xff);
    match code {
        POINT_WISE if !variable => Ok(code),
        POINT_WISE_CHUNKED | LAYERED_CHUNKED => Ok(code),
        _ => Err(malformed(
            Format::Laz,
            Location::Header,
            format!("unsupported LASzip compressor {code} (variable chunks: {variable})"),
        )),
    }
}

/// Number of layers an item contributes to a layered (LAS 1.4, LASzip v3/v4)
/// chunk; `None` for items of the older point-wise compressors.
fn layer_count(item: &laz::LazItem) -> Option<u64> {
    use laz::LazItemType as T;
    Some(match item.item_type() {
        // channel/returns/xy, z, classification, flags, intensity,
        // scan angle, user data, point source, gps time
        T::Point14 => 9,
        T::RGB14 | T::WavePacket14 => 1,
        T::RGBNIR14 => 2,
        T::Byte14(n) => u64::from(n),
        _ => return None,
    })
}

/// Walks the chunks of a layered LAZ and checks every declared layer size
/// against the file, because `laz` allocates each layer before reading it
/// (a corrupt 4 GiB size would exhaust memory). A layered chunk is: the first
/// point raw, a `u32` point count, one `u32` size per layer, the layers.
fn precheck_layers<R: Read + Seek>(
    input: &mut R,
    vlr: &LazVlr,
    compressor: u16,
    table: Option<&ChunkTable>,
    points: u64,
    file_len: u64,
) -> Result<(), CloudError> {
    let Some(layers) = layers_per_chunk(vlr, compressor)? else {
        return Ok(());
    };
    let data_start = input.stream_position()?;
    let prefix = vlr.items_size() + 4 + 4 * layers;
    // Past the 8-byte chunk table offset.
    let mut at = data_start + 8;
    let mut seen = 0u64;
    let mut chunk = 0usize;
    while seen < points {
        let bad = |reason: String| malformed(Format::Laz, Location::Byte(at), reason);
        if at.saturating_add(prefix) > file_len {
            return Err(bad(format!(
                "truncated: chunk {chunk} starts past the end of the file ({file_len} bytes)"
            )));
        }
        input.seek(SeekFrom::Start(at + vlr.items_size()))?;
        let (count, layer_bytes) = read_chunk_sizes(input, layers)?;
        let end = at + prefix + layer_bytes;
        if end > file_len {
            return Err(bad(format!(
                "truncated or corrupt: chunk {chunk} declares {layer_bytes} bytes of layers but the file ends at byte {file_len}"
            )));
        }
        let in_chunk = points_in_chunk(vlr, table, chunk, count);
        if in_chunk == 0 {
            // The decoder then never leaves this chunk; nothing further to check.
            break;
        }
        seen = seen.saturating_add(in_chunk);
        at = end;
        chunk += 1;
    }
    input.seek(SeekFrom::Start(data_start))?;
    Ok(())
}

/// The number of layers in each chunk of a layered LAZ (LASzip v3/v4 items),
/// `None` for point-wise compression; an error when the compressor and the
/// item versions disagree or the items mix both kinds.
fn layers_per_chunk(vlr: &LazVlr, compressor: u16) -> Result<Option<u64>, CloudError> {
    let layered = vlr
        .items()
        .first()
        .is_some_and(|i| matches!(i.version(), 3 | 4));
    if layered != (compressor == LAYERED_CHUNKED) {
        // laz would then look for the chunks elsewhere than LASzip writes them.
        return Err(malformed(
            Format::Laz,
            Location::Header,
            format!("LASzip compressor {compressor} does not match the item versions"),
        ));
    }
    if !layered {
        return Ok(None);
    }
    vlr.items()
        .iter()
        .map(layer_count)
        .try_fold(0u64, |sum, n| n.map(|n| sum + n))
        .ok_or_else(|| {
            malformed(
                Format::Laz,
                Location::Header,
                "LASzip items mix layered and point-wise compression",
            )
        })
        .map(Some)
}

/// A layered chunk's point count and the summed size of its `layers`
/// layers, read from just after its raw first point.
fn read_chunk_sizes<R: Read>(input: &mut R, layers: u64) -> Result<(u64, u64), CloudError> {
    let mut word = [0u8; 4];
    input.read_exact(&mut word)?;
    let count = u64::from(u32::from_le_bytes(word));
    let mut layer_bytes = 0u64;
    for _ in 0..layers {
        input.read_exact(&mut word)?;
        layer_bytes += u64::from(u32::from_le_bytes(word));
    }
    Ok((count, layer_bytes))
}

/// Points in chunk `chunk` by the decoder's own rule: the fixed chunk size,
/// else the chunk table's count, else the count the chunk declares.
fn points_in_chunk(vlr: &LazVlr, table: Option<&ChunkTable>, chunk: usize, count: u64) -> u64 {
    if !vlr.uses_variable_size_chunks() {
        u64::from(vlr.chunk_size())
    } else if let Some(t) = table {
        t.as_ref().get(chunk).map_or(0, |e| e.point_count)
    } else {
        count
    }
}

/// Where the chunk table starts, following LASzip's convention: the first
/// 8 bytes of the point data, or, when the writer could not go back and fill
/// them in, the last 8 bytes of the file.
fn chunk_table_start<R: Read + Seek>(
    input: &mut R,
    data_start: u64,
    file_len: u64,
) -> Result<Option<u64>, CloudError> {
    let mut read_i64_at = |at: u64| -> Result<Option<i64>, CloudError> {
        if at.saturating_add(8) > file_len {
            return Ok(None);
        }
        input.seek(SeekFrom::Start(at))?;
        let mut b = [0u8; 8];
        input.read_exact(&mut b)?;
        Ok(Some(i64::from_le_bytes(b)))
    };
    let valid = |offset: i64| u64::try_from(offset).ok().filter(|&o| o > data_start);
    if let Some(start) = read_i64_at(data_start)?.and_then(valid) {
        return Ok(Some(start));
    }
    Ok(read_i64_at(file_len.saturating_sub(8))?.and_then(valid))
}

/// One-line reason for a `las` error; an early end of file says so plainly.
fn las_reason(e: &las::Error) -> String {
    match e {
        las::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated: the file ends inside the header or its VLRs".to_owned()
        }
        other => other.to_string(),
    }
}

/// Converts a raw record into an absolute point with its attributes.
fn push_raw(
    builder: &mut CloudBuilder,
    p: &raw::Point,
    header: &las::Header,
    location: Location,
) -> Result<(), CloudError> {
    let t = header.transforms();
    let xyz = DVec3::new(t.x.direct(p.x), t.y.direct(p.y), t.z.direct(p.z));
    let classification = match p.flags {
        raw::point::Flags::TwoByte(_, b) => b & 0b0001_1111,
        raw::point::Flags::ThreeByte(_, _, c) => c,
    };
    let attrs = Attributes {
        intensity: Some(p.intensity),
        return_number: Some(p.flags.return_number()),
        classification: Some(classification),
    };
    builder.push(xyz, attrs, location)
}

/// LAS scale: millimetres, the precision of airborne and terrestrial scans.
const SCALE_M: f64 = 0.001;

/// Writes LAS 1.4 point format 6 (return numbers up to 15, full-byte
/// classes), LASzip-compressed when `compressed`. The LAS offset is the
/// cloud offset, the scale 1 mm. Returns the finished output.
pub(super) fn write<W>(cloud: &PointCloud, compressed: bool, out: W) -> Result<W, CloudError>
where
    W: Write + Seek + Send + Sync + std::fmt::Debug + 'static,
{
    let format = if compressed { Format::Laz } else { Format::Las };
    let fail = |e: las::Error| {
        CloudError::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("writing {format}: {e}"),
        ))
    };
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(6).map_err(fail)?;
    builder.point_format.is_compressed = compressed;
    builder.generating_software = "silva".to_owned();
    let o = cloud.offset;
    builder.transforms = las::Vector {
        x: las::Transform {
            scale: SCALE_M,
            offset: o.x,
        },
        y: las::Transform {
            scale: SCALE_M,
            offset: o.y,
        },
        z: las::Transform {
            scale: SCALE_M,
            offset: o.z,
        },
    };
    let header = builder.into_header().map_err(fail)?;
    let mut writer = las::Writer::new(out, header).map_err(fail)?;
    for i in 0..cloud.len() {
        writer.write_point(las_point(cloud, i)).map_err(fail)?;
    }
    writer.into_inner().map_err(fail)
}

/// One cloud point as a `las::Point`, attributes carried over.
fn las_point(cloud: &PointCloud, i: usize) -> las::Point {
    let p = cloud.absolute(i);
    // Format 6 stores 4-bit return numbers.
    let return_number = cloud.return_number.as_ref().map_or(1, |r| r[i].min(15));
    let class = cloud.classification.as_ref().map_or(1, |c| c[i]);
    // Class 12 means "overlap" in LAS; the las crate stores it as a flag.
    let (classification, is_overlap) = match las::point::Classification::new(class) {
        Ok(c) => (c, false),
        Err(_) => (las::point::Classification::Unclassified, true),
    };
    las::Point {
        x: p.x,
        y: p.y,
        z: p.z,
        intensity: cloud.intensity.as_ref().map_or(0, |v| v[i]),
        return_number,
        number_of_returns: return_number,
        classification,
        is_overlap,
        gps_time: Some(0.0),
        ..Default::default()
    }
}
