//! Stanford PLY reader (ascii, binary little and big endian) and a binary
//! little-endian writer.
//!
//! Two layers, as in las-rs: [`RawHeader`] mirrors the header lines as
//! written, and [`VertexLayout`] is the validated form the point loop uses
//! (which element holds the points, where `x y z` sit, how many bytes the
//! body must at least hold). Only the validation knows PLY's quirks.
//! Elements before `vertex` are skipped, elements after it are not read.
//!
//! [`read_document`] reads every element of a document into named columns,
//! for PLY files that are not point clouds (the skeleton PLY,
//! `crate::skeleton`), with the same header parser and row decoding.

use std::io::{BufRead, BufReader, Read, Seek, Write};

use glam::DVec3;

use super::read::{Attributes, CloudBuilder, ReadOptions, remaining_len};
use super::{CloudError, Format, Location, PointCloud};

/// Longest header accepted; real headers are a few hundred bytes.
const MAX_HEADER: usize = 64 * 1024;
/// Longest ascii body line accepted.
const MAX_LINE: usize = 4096;

/// How the body is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Decodes one value from exactly `self.size()` bytes.
    fn decode(self, b: &[u8], enc: Encoding) -> f64 {
        macro_rules! num {
            ($t:ty, $n:literal) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if enc == Encoding::BinaryBe {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            Self::I8 => num!(i8, 1),
            Self::U8 => num!(u8, 1),
            Self::I16 => num!(i16, 2),
            Self::U16 => num!(u16, 2),
            Self::I32 => num!(i32, 4),
            Self::U32 => num!(u32, 4),
            Self::F32 => num!(f32, 4),
            Self::F64 => num!(f64, 8),
        }
    }
}

/// A property line: `property TYPE NAME` or `property list COUNT ITEM NAME`.
#[derive(Debug, Clone, PartialEq, Eq)]
enum RawProperty {
    Scalar {
        ty: Scalar,
        name: String,
    },
    List {
        count: Scalar,
        item: Scalar,
        name: String,
    },
}

/// An `element NAME COUNT` line and its properties.
#[derive(Debug, Clone, PartialEq, Eq)]
struct RawElement {
    name: String,
    count: u64,
    properties: Vec<RawProperty>,
}

/// The header as written, before any check of its meaning.
#[derive(Debug, Clone, PartialEq, Eq)]
struct RawHeader {
    encoding: Encoding,
    elements: Vec<RawElement>,
    /// Header length in bytes, including `end_header` and its newline.
    len: u64,
    /// Number of header lines, so ascii body lines can be numbered.
    lines: u64,
    /// The text of the `comment` lines, in order.
    comments: Vec<String>,
}

/// Which vertex property feeds which output field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    X,
    Y,
    Z,
    Intensity,
    ReturnNumber,
    Classification,
    Ignored,
}

/// The validated vertex layout the point loop follows.
#[derive(Debug)]
struct VertexLayout {
    encoding: Encoding,
    /// Elements before `vertex`, to be skipped.
    skipped: Vec<RawElement>,
    count: u64,
    properties: Vec<(RawProperty, Role)>,
    attrs: Attributes,
}

fn malformed(location: Location, reason: impl Into<String>) -> CloudError {
    CloudError::Malformed {
        format: Format::Ply,
        location,
        reason: reason.into(),
    }
}

/// Reads a PLY file.
pub(super) fn read<R: Read + Seek>(
    mut input: R,
    opts: &ReadOptions,
) -> Result<PointCloud, CloudError> {
    let file_len = remaining_len(&mut input)?;
    let mut reader = BufReader::new(input);
    let raw = read_raw_header(&mut reader)?;
    let layout = validate(&raw, opts)?;
    let body_len = file_len.saturating_sub(raw.len);
    let min_vertex = min_binary_size(
        &layout
            .properties
            .iter()
            .map(|(p, _)| p.clone())
            .collect::<Vec<_>>(),
    );
    // Ascii vertices need at least two bytes per coordinate ("0 0 0\n").
    let per_vertex = match layout.encoding {
        Encoding::Ascii => 6,
        _ => min_vertex.max(1),
    };
    let fits = body_len / per_vertex as u64;
    if layout.encoding != Encoding::Ascii && layout.skipped.is_empty() && layout.count > fits {
        return Err(malformed(
            Location::Byte(raw.len),
            format!(
                "header promises {} vertices of at least {min_vertex} bytes, but only {body_len} bytes follow the header",
                layout.count
            ),
        ));
    }
    let expected = layout.count.min(fits);
    let mut builder = CloudBuilder::new(Format::Ply, opts, expected, layout.attrs);
    match layout.encoding {
        Encoding::Ascii => read_ascii_body(&mut reader, &raw, &layout, &mut builder)?,
        enc => read_binary_body(&mut reader, raw.len, enc, &layout, &mut builder)?,
    }
    Ok(builder.finish())
}

/// Reads one header line (without its line ending), capped in length.
fn header_line<R: BufRead>(reader: &mut R, consumed: &mut u64) -> Result<String, CloudError> {
    let mut buf = Vec::new();
    let remaining = (MAX_HEADER as u64).saturating_sub(*consumed);
    let n = reader.take(remaining).read_until(b'\n', &mut buf)?;
    if n == 0 || buf.last() != Some(&b'\n') {
        return Err(malformed(
            Location::Byte(*consumed + n as u64),
            if *consumed + n as u64 >= MAX_HEADER as u64 {
                format!("header longer than {MAX_HEADER} bytes")
            } else {
                "file ends inside the header (no end_header)".to_owned()
            },
        ));
    }
    *consumed += n as u64;
    let text = std::str::from_utf8(&buf)
        .map_err(|_| malformed(Location::Byte(*consumed), "header is not text"))?;
    Ok(text.trim_end_matches(['\n', '\r']).to_owned())
}

/// Parses the header lines into a [`RawHeader`].
fn read_raw_header<R: BufRead>(reader: &mut R) -> Result<RawHeader, CloudError> {
    let mut consumed = 0u64;
    let mut lines = 0u64;
    let mut encoding = None;
    let mut elements: Vec<RawElement> = Vec::new();
    let mut comments = Vec::new();
    loop {
        let line = header_line(reader, &mut consumed)?;
        lines += 1;
        let at = Location::Line(lines);
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            ["ply"] if lines == 1 => {}
            _ if lines == 1 => return Err(malformed(at, "does not start with \"ply\"")),
            ["format", enc, "1.0"] => {
                encoding = Some(match *enc {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLe,
                    "binary_big_endian" => Encoding::BinaryBe,
                    other => return Err(malformed(at, format!("unknown encoding {other:?}"))),
                });
            }
            ["comment", ..] => {
                let text = line
                    .trim_start()
                    .strip_prefix("comment")
                    .unwrap_or_default();
                comments.push(text.trim().to_owned());
            }
            ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count = count
                    .parse::<u64>()
                    .map_err(|_| malformed(at, format!("bad element count {count:?}")))?;
                elements.push(RawElement {
                    name: (*name).to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let property = parse_property(rest).map_err(|reason| malformed(at, reason))?;
                let element = elements
                    .last_mut()
                    .ok_or_else(|| malformed(at, "property before any element"))?;
                element.properties.push(property);
            }
            ["end_header"] => break,
            _ => {
                return Err(malformed(
                    at,
                    format!("unexpected header line {:?}", truncate(&line)),
                ));
            }
        }
    }
    let encoding = encoding.ok_or_else(|| malformed(Location::Header, "no format line"))?;
    Ok(RawHeader {
        encoding,
        elements,
        len: consumed,
        lines,
        comments,
    })
}

fn truncate(s: &str) -> String {
    s.chars().take(40).collect()
}

fn parse_property(words: &[&str]) -> Result<RawProperty, String> {
    let ty = |w: &str| {
        Scalar::parse(w).ok_or_else(|| format!("unknown property type {:?}", truncate(w)))
    };
    match words {
        ["list", count, item, name] => Ok(RawProperty::List {
            count: ty(count)?,
            item: ty(item)?,
            name: (*name).to_owned(),
        }),
        [t, name] => Ok(RawProperty::Scalar {
            ty: ty(t)?,
            name: (*name).to_owned(),
        }),
        _ => Err("malformed property line".to_owned()),
    }
}

/// Checks the raw header's meaning: a vertex element with scalar x, y, z
/// within the point limit.
fn validate(raw: &RawHeader, opts: &ReadOptions) -> Result<VertexLayout, CloudError> {
    let index = raw
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| malformed(Location::Header, "no vertex element"))?;
    let vertex = &raw.elements[index];
    if vertex.count > opts.max_points as u64 {
        return Err(CloudError::TooManyPoints {
            format: Format::Ply,
            limit: opts.max_points,
        });
    }
    let mut attrs = Attributes::default();
    let mut properties = Vec::with_capacity(vertex.properties.len());
    for p in &vertex.properties {
        let role = match p {
            RawProperty::Scalar { name, .. } => match name.as_str() {
                "x" => Role::X,
                "y" => Role::Y,
                "z" => Role::Z,
                "intensity" => {
                    attrs.intensity = Some(0);
                    Role::Intensity
                }
                "return_number" => {
                    attrs.return_number = Some(1);
                    Role::ReturnNumber
                }
                "classification" => {
                    attrs.classification = Some(1);
                    Role::Classification
                }
                _ => Role::Ignored,
            },
            RawProperty::List { .. } => Role::Ignored,
        };
        properties.push((p.clone(), role));
    }
    for (axis, role) in [("x", Role::X), ("y", Role::Y), ("z", Role::Z)] {
        let n = properties.iter().filter(|(_, r)| *r == role).count();
        if n != 1 {
            return Err(malformed(
                Location::Header,
                format!("vertex element needs exactly one scalar {axis} property, found {n}"),
            ));
        }
    }
    Ok(VertexLayout {
        encoding: raw.encoding,
        skipped: raw.elements[..index].to_vec(),
        count: vertex.count,
        properties,
        attrs,
    })
}

/// Smallest binary size of one item (lists counted as empty).
fn min_binary_size(properties: &[RawProperty]) -> usize {
    properties
        .iter()
        .map(|p| match p {
            RawProperty::Scalar { ty, .. } => ty.size(),
            RawProperty::List { count, .. } => count.size(),
        })
        .sum()
}

/// Collects one vertex's values into a point and its attributes.
#[derive(Default)]
struct VertexValues {
    xyz: [f64; 3],
    attrs: Attributes,
}

impl VertexValues {
    fn set(&mut self, role: Role, v: f64) {
        match role {
            Role::X => self.xyz[0] = v,
            Role::Y => self.xyz[1] = v,
            Role::Z => self.xyz[2] = v,
            // `as` saturates, which is the right clamp for out-of-range attributes.
            Role::Intensity => self.attrs.intensity = Some(v as u16),
            Role::ReturnNumber => self.attrs.return_number = Some(v as u8),
            Role::Classification => self.attrs.classification = Some(v as u8),
            Role::Ignored => {}
        }
    }
}

/// Binary body: skip earlier elements, then decode vertices.
fn read_binary_body<R: Read>(
    reader: &mut R,
    header_len: u64,
    enc: Encoding,
    layout: &VertexLayout,
    builder: &mut CloudBuilder,
) -> Result<(), CloudError> {
    let mut pos = header_len;
    for element in &layout.skipped {
        // An element without properties occupies no bytes, whatever its count.
        let count = if element.properties.is_empty() {
            0
        } else {
            element.count
        };
        for _ in 0..count {
            for p in &element.properties {
                read_binary_property(reader, &mut pos, enc, p)?;
            }
        }
    }
    for i in 0..layout.count {
        let start = pos;
        let mut values = VertexValues::default();
        for (p, role) in &layout.properties {
            let v = read_binary_property(reader, &mut pos, enc, p).map_err(|e| match e {
                CloudError::Malformed { location, .. } => malformed(
                    location,
                    format!("file ends inside vertex {i} of {}", layout.count),
                ),
                other => other,
            })?;
            values.set(*role, v);
        }
        builder.push(
            DVec3::from_array(values.xyz),
            values.attrs,
            Location::Byte(start),
        )?;
    }
    Ok(())
}

/// Reads one property (a list is skipped and yields 0).
fn read_binary_property<R: Read>(
    reader: &mut R,
    pos: &mut u64,
    enc: Encoding,
    p: &RawProperty,
) -> Result<f64, CloudError> {
    match p {
        RawProperty::Scalar { ty, .. } => read_scalar(reader, pos, enc, *ty),
        RawProperty::List { count, item, .. } => {
            let n = read_scalar(reader, pos, enc, *count)?;
            if !(0.0..=u32::MAX as f64).contains(&n) {
                return Err(malformed(
                    Location::Byte(*pos),
                    format!("bad list length {n}"),
                ));
            }
            let bytes = n as u64 * item.size() as u64;
            let skipped = std::io::copy(&mut reader.take(bytes), &mut std::io::sink())?;
            *pos += skipped;
            if skipped < bytes {
                return Err(malformed(Location::Byte(*pos), "file ends inside a list"));
            }
            Ok(0.0)
        }
    }
}

fn read_scalar<R: Read>(
    reader: &mut R,
    pos: &mut u64,
    enc: Encoding,
    ty: Scalar,
) -> Result<f64, CloudError> {
    let mut buf = [0u8; 8];
    let b = &mut buf[..ty.size()];
    reader.read_exact(b).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => {
            malformed(Location::Byte(*pos), "unexpected end of file")
        }
        _ => CloudError::Io(e),
    })?;
    *pos += ty.size() as u64;
    Ok(ty.decode(b, enc))
}

/// Ascii body: one line per item; earlier elements are skipped line by line.
fn read_ascii_body<R: BufRead>(
    reader: &mut R,
    raw: &RawHeader,
    layout: &VertexLayout,
    builder: &mut CloudBuilder,
) -> Result<(), CloudError> {
    let mut lines = AsciiLines::after(raw);
    for element in &layout.skipped {
        for i in 0..element.count {
            lines.next(reader, &|| {
                format!("{} {i} of {}", element.name, element.count)
            })?;
        }
    }
    for i in 0..layout.count {
        let at = Location::Line(lines.next(reader, &|| format!("vertex {i} of {}", layout.count))?);
        let values = parse_ascii_vertex(&lines.line, &layout.properties)
            .map_err(|reason| malformed(at, reason))?;
        builder.push(DVec3::from_array(values.xyz), values.attrs, at)?;
    }
    Ok(())
}

/// The body lines of an ascii PLY, numbered as in the file.
struct AsciiLines {
    line_no: u64,
    /// The line last read, with its line ending.
    line: Vec<u8>,
}

impl AsciiLines {
    /// Lines after `raw`'s header.
    fn after(raw: &RawHeader) -> Self {
        AsciiLines {
            line_no: raw.lines,
            line: Vec::new(),
        }
    }

    /// Reads the next line into `self.line` and returns its number; `what`
    /// names the item it should hold, for the error at the end of the file.
    fn next<R: BufRead>(
        &mut self,
        reader: &mut R,
        what: &dyn Fn() -> String,
    ) -> Result<u64, CloudError> {
        self.line.clear();
        let n = reader
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut self.line)?;
        self.line_no += 1;
        if n == 0 {
            return Err(malformed(
                Location::Line(self.line_no),
                format!("file ends before {}", what()),
            ));
        }
        if n > MAX_LINE {
            return Err(malformed(
                Location::Line(self.line_no),
                format!("line longer than {MAX_LINE} bytes"),
            ));
        }
        Ok(self.line_no)
    }
}

fn parse_ascii_vertex(
    line: &[u8],
    properties: &[(RawProperty, Role)],
) -> Result<VertexValues, String> {
    let mut values = VertexValues::default();
    parse_ascii_row(line, properties.iter().map(|(p, _)| p), |i, v| {
        values.set(properties[i].1, v)
    })?;
    Ok(values)
}

/// Parses one ascii row of `properties`, handing each scalar's index and
/// value to `set` (lists are checked and skipped).
fn parse_ascii_row<'p>(
    line: &[u8],
    properties: impl Iterator<Item = &'p RawProperty>,
    mut set: impl FnMut(usize, f64),
) -> Result<(), String> {
    let text = std::str::from_utf8(line).map_err(|_| "not UTF-8 text".to_owned())?;
    let mut words = text.split_ascii_whitespace();
    let mut next = |what: &str| -> Result<f64, String> {
        let w = words
            .next()
            .ok_or_else(|| format!("missing value for {what}"))?;
        w.parse::<f64>()
            .map_err(|_| format!("not a number: {:?}", truncate(w)))
    };
    for (i, p) in properties.enumerate() {
        match p {
            RawProperty::Scalar { name, .. } => set(i, next(name)?),
            RawProperty::List { name, .. } => {
                let n = next(name)?;
                if !(0.0..=MAX_LINE as f64).contains(&n) || n.fract() != 0.0 {
                    return Err(format!("bad list length {n}"));
                }
                for _ in 0..n as usize {
                    next(name)?;
                }
            }
        }
    }
    Ok(())
}

/// One element of a document read by [`read_document`]: its row count and
/// the scalar columns the caller kept.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PlyElement {
    /// The element's name (`vertex`, `edge`, `face`, …).
    pub(crate) name: String,
    /// Rows in the body.
    pub(crate) rows: u64,
    /// `(property name, one value per row)` for each kept scalar property.
    pub(crate) columns: Vec<(String, Vec<f64>)>,
}

impl PlyElement {
    /// The values of the kept scalar property `name`, one per row.
    pub(crate) fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
}

/// A whole PLY document, read for the properties its caller keeps.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PlyDocument {
    /// The text of the header's `comment` lines, in order.
    pub(crate) comments: Vec<String>,
    /// Every element, in file order.
    pub(crate) elements: Vec<PlyElement>,
}

impl PlyDocument {
    /// The first element called `name`.
    pub(crate) fn element(&self, name: &str) -> Option<&PlyElement> {
        self.elements.iter().find(|e| e.name == name)
    }
}

/// Reads every element of the PLY document `bytes` (ascii or binary),
/// keeping the scalar properties for which `keep(element, property)` holds.
///
/// An element with kept properties may hold at most `max_rows` rows, and
/// its header count must fit in the bytes that follow the header before any
/// column is allocated, so a hostile header cannot make it allocate more
/// than a small multiple of the input.
pub(crate) fn read_document(
    bytes: &[u8],
    keep: &dyn Fn(&str, &str) -> bool,
    max_rows: u64,
) -> Result<PlyDocument, CloudError> {
    let mut body = Body {
        reader: bytes,
        pos: 0,
        lines: None,
    };
    let raw = read_raw_header(&mut body.reader)?;
    body.pos = raw.len;
    body.lines = (raw.encoding == Encoding::Ascii).then(|| AsciiLines::after(&raw));
    let mut elements = Vec::with_capacity(raw.elements.len());
    for element in &raw.elements {
        let mut columns = Columns::new(element, keep);
        // A binary element without properties occupies no bytes, whatever its count.
        let rows = if raw.encoding != Encoding::Ascii && element.properties.is_empty() {
            0
        } else {
            element.count
        };
        if !columns.values.is_empty() {
            check_rows(element, rows, max_rows, &raw, body.reader.len() as u64)?;
            columns.reserve(rows);
        }
        for i in 0..rows {
            body.read_row(element, i, raw.encoding, &mut columns)?;
        }
        elements.push(PlyElement {
            name: element.name.clone(),
            rows,
            columns: columns.values,
        });
    }
    Ok(PlyDocument {
        comments: raw.comments,
        elements,
    })
}

/// The kept scalar columns of one element, filled row by row.
struct Columns {
    /// Per property of the element: its column, if kept.
    slot: Vec<Option<usize>>,
    /// `(property name, values)` of the kept properties.
    values: Vec<(String, Vec<f64>)>,
}

impl Columns {
    fn new(element: &RawElement, keep: &dyn Fn(&str, &str) -> bool) -> Self {
        let mut columns = Columns {
            slot: Vec::with_capacity(element.properties.len()),
            values: Vec::new(),
        };
        for p in &element.properties {
            let kept = match p {
                RawProperty::Scalar { name, .. } if keep(&element.name, name) => {
                    columns.values.push((name.clone(), Vec::new()));
                    Some(columns.values.len() - 1)
                }
                _ => None,
            };
            columns.slot.push(kept);
        }
        columns
    }

    fn reserve(&mut self, rows: u64) {
        for (_, values) in &mut self.values {
            values.reserve_exact(rows as usize);
        }
    }

    /// Records the value of the element's `property`-th property, if kept.
    fn set(&mut self, property: usize, value: f64) {
        if let Some(c) = self.slot[property] {
            self.values[c].1.push(value);
        }
    }
}

/// The body of a document in memory, read row by row.
struct Body<'a> {
    reader: &'a [u8],
    /// Byte offset in the file, for binary errors.
    pos: u64,
    /// Line numbering, for ascii bodies.
    lines: Option<AsciiLines>,
}

impl Body<'_> {
    /// Reads row `i` of `element` into `columns`.
    fn read_row(
        &mut self,
        element: &RawElement,
        i: u64,
        encoding: Encoding,
        columns: &mut Columns,
    ) -> Result<(), CloudError> {
        let Some(lines) = &mut self.lines else {
            for (k, p) in element.properties.iter().enumerate() {
                let value = read_binary_property(&mut self.reader, &mut self.pos, encoding, p)?;
                columns.set(k, value);
            }
            return Ok(());
        };
        let at = lines.next(&mut self.reader, &|| {
            format!("{} {i} of {}", element.name, element.count)
        })?;
        parse_ascii_row(&lines.line, element.properties.iter(), |k, v| {
            columns.set(k, v)
        })
        .map_err(|reason| malformed(Location::Line(at), reason))
    }
}

/// Refuses an element whose rows exceed `max_rows` or cannot fit in the
/// `remaining` bytes (at least two per ascii row: a value and a newline).
fn check_rows(
    element: &RawElement,
    rows: u64,
    max_rows: u64,
    raw: &RawHeader,
    remaining: u64,
) -> Result<(), CloudError> {
    if rows > max_rows {
        return Err(malformed(
            Location::Header,
            format!(
                "element {} has {rows} rows, more than the limit of {max_rows}",
                element.name
            ),
        ));
    }
    let per_row = match raw.encoding {
        Encoding::Ascii => 2,
        _ => min_binary_size(&element.properties).max(1) as u64,
    };
    if rows > remaining / per_row {
        return Err(malformed(
            Location::Byte(raw.len),
            format!(
                "header promises {rows} {} rows of at least {per_row} bytes, but at most \
                 {remaining} bytes are left for them",
                element.name
            ),
        ));
    }
    Ok(())
}

/// Writes binary little-endian PLY with absolute `double` coordinates and,
/// when present, `intensity`, `return_number` and `classification`.
pub(super) fn write<W: Write>(cloud: &PointCloud, mut out: W) -> Result<(), CloudError> {
    writeln!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment written by silva"
    )?;
    writeln!(out, "element vertex {}", cloud.len())?;
    writeln!(
        out,
        "property double x\nproperty double y\nproperty double z"
    )?;
    if cloud.intensity.is_some() {
        writeln!(out, "property ushort intensity")?;
    }
    if cloud.return_number.is_some() {
        writeln!(out, "property uchar return_number")?;
    }
    if cloud.classification.is_some() {
        writeln!(out, "property uchar classification")?;
    }
    writeln!(out, "end_header")?;
    for i in 0..cloud.len() {
        let p = cloud.absolute(i);
        for c in p.to_array() {
            out.write_all(&c.to_le_bytes())?;
        }
        if let Some(v) = &cloud.intensity {
            out.write_all(&v[i].to_le_bytes())?;
        }
        if let Some(v) = &cloud.return_number {
            out.write_all(&[v[i]])?;
        }
        if let Some(v) = &cloud.classification {
            out.write_all(&[v[i]])?;
        }
    }
    out.flush()?;
    Ok(())
}
