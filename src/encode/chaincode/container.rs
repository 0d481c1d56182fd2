//! The self-describing byte forms of a [`ChainCode`]: plain binary and
//! interpolatively compressed (chain-code paper §3.3).
//!
//! Both start with the same header, so `silva decode` recognises a chain code
//! by its first four bytes:
//!
//! | field | bytes |
//! |---|---|
//! | magic `SLVC` | 4 |
//! | version (1) | 1 |
//! | kind: 0 plain, 1 interpolative | 1 |
//! | flags: bit 0 CRS present, bit 1 resolution present, bit 2 damped prediction | 1 |
//! | voxel size `d` (f64 LE, metres) | 8 |
//! | radius step (f32 LE, metres) | 4 |
//! | resolution `r` (f32 LE), if flagged | 4 |
//! | prediction weight in quarters, 0–3, if flagged | 1 |
//! | anchor origin x, y, z (f64 LE) | 24 |
//! | root position x, y, z relative to the anchor (f32 LE) | 12 |
//! | CRS: varint length + UTF-8, if flagged | 1 + n |
//! | symbol count, node count (LEB128 varints) | 2+ |
//!
//! *Plain* payload (the paper's "cc bin"): symbols as 4-bit nibbles, high
//! nibble first; one byte `w`; each radius in `w` bits, MSB first.
//!
//! *Interpolative* payload: varints for the BWT key, the last cumulative sum
//! of the MTF indices, the radius gap mapping (byte 0 = offset followed by
//! the zigzagged offset, byte 1 = zigzag), the largest mapped radius gap and
//! the last radius cumulative sum; then one bit stream holding the
//! interpolative code of the symbols' MTF cumulative sum (gaps ≤ 8) followed
//! by that of the radius gaps' cumulative sum.

use super::bits::{BitCounter, BitReader, BitSink, BitWriter, ByteCursor, put_varint};
use super::radii::{GapMapping, branch_gaps, radii_from_gaps};
use super::split::{Form, RadiusLayout};
use super::{
    ALPHABET, ChainCode, ChainError, ChainHeader, Limits, Prediction, bwt, dbf6, interpolative,
    lod, mtf, split,
};
use crate::skeleton::{Anchor, Skeleton};
use glam::{DVec3, Vec3};

/// The first bytes of every chain code stream.
pub const MAGIC: &[u8; 4] = b"SLVC";
/// The container version this build writes. Version 2 added kind 3; this
/// build still reads version 1 (kinds 0–2, unchanged).
pub const VERSION: u8 = 2;
/// The first version, whose kinds 0–2 this build writes and reads unchanged.
const VERSION_1: u8 = 1;

const KIND_PLAIN: u8 = 0;
const KIND_INTERPOLATIVE: u8 = 1;
const KIND_SPLIT: u8 = 2;
const KIND_SPLIT_3: u8 = 3;
const FLAG_CRS: u8 = 1;
const FLAG_RESOLUTION: u8 = 2;
/// A damped step prediction: one byte with its weight in quarters (0–3)
/// follows the resolution. Without the flag the prediction is the paper's
/// (four quarters), so streams written before the flag existed read as
/// they always did, and each code has one byte form.
const FLAG_PREDICTION: u8 = 4;
const MAX_SYMBOL_GAP: u64 = (ALPHABET - 1) as u64;

impl ChainCode {
    /// Plain binary form: header, 4-bit symbols, radii in the fewest bits
    /// that hold the largest.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = self.header_bytes(KIND_PLAIN);
        out.reserve(self.symbols.len() / 2 + self.radii_q.len() * 2 + 2);
        for pair in self.symbols.chunks(2) {
            out.push(pair[0] << 4 | pair.get(1).copied().unwrap_or(0));
        }
        let max = self.radii_q.iter().copied().max().unwrap_or(0);
        let width = 32 - max.leading_zeros();
        out.push(width as u8);
        let mut w = BitWriter::new();
        for &q in &self.radii_q {
            w.write(u64::from(q), width);
        }
        out.extend(w.finish());
        out
    }

    /// Reads the plain binary form, checking everything against `limits`.
    pub fn from_bytes(bytes: &[u8], limits: &Limits) -> Result<ChainCode, ChainError> {
        let mut cur = ByteCursor::new(bytes);
        let (header, kind, n_symbols, n_nodes) = read_header(&mut cur, limits)?;
        if kind != KIND_PLAIN {
            return Err(ChainError::Malformed(
                "not a plain chain code; use decompress",
            ));
        }
        let packed = cur.take(n_symbols.div_ceil(2))?;
        let mut symbols = Vec::with_capacity(n_symbols);
        for &b in packed {
            symbols.push(b >> 4);
            symbols.push(b & 0x0F);
        }
        if symbols.len() > n_symbols && symbols.pop() != Some(0) {
            return Err(ChainError::Malformed("padding nibble is not zero"));
        }
        let width = u32::from(cur.u8()?);
        if width > 32 {
            return Err(ChainError::Malformed("radius width above 32 bits"));
        }
        let radius_bytes = (n_nodes as u64 * u64::from(width)).div_ceil(8) as usize;
        let rest = cur.take(radius_bytes)?;
        if !cur.rest().is_empty() {
            return Err(ChainError::Malformed("bytes after the radii"));
        }
        let mut r = BitReader::new(rest);
        let radii_q = (0..n_nodes).map(|_| r.read(width) as u32).collect();
        ChainCode::new(header, symbols, radii_q)
    }

    /// Interpolative compression (§3.3): BWT, MTF, cumulative sums and
    /// binary interpolative coding of the symbols and of the per-branch
    /// radius gaps.
    ///
    /// Writes the split-stream form (kind 3, `split.rs`) when the code is in
    /// the encoder's move order and that is shorter, else the paper's single
    /// string form ([`ChainCode::compress_single_string`], kind 1).
    pub fn compress(&self) -> Vec<u8> {
        let single = self.compress_single_string();
        match self.compress_split() {
            Some(split) if split.len() < single.len() => split,
            _ => single,
        }
    }

    /// Kind 3, the split streams (`split.rs`), or `None` if some internode
    /// writes its moves in another order than the encoder's.
    /// [`ChainCode::decompress`] reads it; [`ChainCode::compress`] uses it
    /// when it is shorter than kind 1.
    pub fn compress_split(&self) -> Option<Vec<u8>> {
        self.split_bytes(None)
    }

    /// Kind 3 with the given radius layout instead of the shortest, or
    /// `None` as for [`ChainCode::compress_split`]. For tests and fuzzing:
    /// every layout must stay readable.
    pub fn compress_split_with(&self, radii: RadiusLayout) -> Option<Vec<u8>> {
        self.split_bytes(Some(radii))
    }

    fn split_bytes(&self, radii: Option<RadiusLayout>) -> Option<Vec<u8>> {
        split::build(self, Form::Kind3, radii).map(|built| {
            let mut out = self.header_bytes(KIND_SPLIT_3);
            out.extend(built.payload);
            out
        })
    }

    /// Kind 2 as container version 1 wrote it (BWT and MTF structure,
    /// tip-first radii), or `None` as for [`ChainCode::compress_split`].
    /// [`ChainCode::decompress`] still reads it; nothing writes it by
    /// default. Kept to test and fuzz the reader of stored version-1 codes.
    pub fn compress_split_v1(&self) -> Option<Vec<u8>> {
        split::build(self, Form::Kind2, None).map(|built| {
            let mut out = self.header_bytes(KIND_SPLIT);
            out[MAGIC.len()] = VERSION_1;
            out.extend(built.payload);
            out
        })
    }

    /// Kind 1, the paper's form (§3.3): the whole symbol string through BWT,
    /// MTF, cumulative sum and binary interpolative coding, and one radius gap
    /// sequence. [`ChainCode::decompress`] reads it; [`ChainCode::compress`]
    /// uses it when the split streams are not shorter.
    pub fn compress_single_string(&self) -> Vec<u8> {
        let mut out = self.header_bytes(KIND_INTERPOLATIVE);
        let (last, primary) = bwt::bwt_forward(&self.symbols, ALPHABET);
        let indices = mtf::mtf_forward(&last, ALPHABET);
        let code_sums = cumulative(indices.iter().map(|&i| u64::from(i)));
        put_varint(&mut out, primary as u64);
        put_varint(&mut out, code_sums.last().copied().unwrap_or(0));

        let scan = lod::scan(&self.symbols, self.radii_q.len())
            .expect("ChainCode is validated on construction");
        let gaps = branch_gaps(&self.radii_q, &scan.branch_lengths());
        let (mapping, radius_sums) = best_radius_mapping(&gaps);
        match mapping {
            GapMapping::Offset(min) => {
                out.push(0);
                put_varint(&mut out, zigzag(min));
            }
            GapMapping::Zigzag => out.push(1),
        }
        let max_gap = gaps.iter().map(|&g| mapping.apply(g)).max().unwrap_or(0);
        put_varint(&mut out, max_gap);
        put_varint(&mut out, radius_sums.last().copied().unwrap_or(0));

        let mut w = BitWriter::new();
        interpolative::encode_into(&mut w, &code_sums, MAX_SYMBOL_GAP);
        interpolative::encode_into(&mut w, &radius_sums, max_gap);
        out.extend(w.finish());
        out
    }

    /// Where the bytes of [`ChainCode::compress`] go: header, stream
    /// metadata (varints), and the bits of each interpolative code.
    pub fn compressed_sizes(&self) -> CompressedSizes {
        let total = self.compress();
        let header_bytes = self.header_bytes(total[5]).len();
        let ([structure_bits, move_bits, radius_bits], radius_layout) = if total[5] == KIND_SPLIT_3
        {
            let built = split::build(self, Form::Kind3, None).expect("the split form was written");
            (built.bits, built.radii)
        } else {
            let (last, _) = bwt::bwt_forward(&self.symbols, ALPHABET);
            let indices = mtf::mtf_forward(&last, ALPHABET);
            let code_sums = cumulative(indices.iter().map(|&i| u64::from(i)));
            let mut w = BitCounter::default();
            interpolative::encode_into(&mut w, &code_sums, MAX_SYMBOL_GAP);
            let symbol_bits = w.bit_len();
            let payload_bits = (total.len() - header_bytes) as u64 * 8;
            (
                [0, symbol_bits, payload_bits.saturating_sub(symbol_bits)],
                None,
            )
        };
        let payload = (structure_bits + move_bits + radius_bits).div_ceil(8) as usize;
        CompressedSizes {
            total_bytes: total.len(),
            kind: total[5],
            header_bytes,
            metadata_bytes: total.len().saturating_sub(header_bytes + payload),
            structure_bits,
            move_bits,
            radius_bits,
            radius_layout,
        }
    }

    /// Reads the interpolative form, checking everything against `limits`.
    pub fn decompress(bytes: &[u8], limits: &Limits) -> Result<ChainCode, ChainError> {
        let mut cur = ByteCursor::new(bytes);
        let (header, kind, n_symbols, n_nodes) = read_header(&mut cur, limits)?;
        let Some(form) = split_form(bytes, kind)? else {
            return decompress_kind1(&mut cur, header, n_symbols, n_nodes);
        };
        // The payload reader has checked the symbols' grammar and the
        // radius count (`lod::scan_terminators`), and `read_header` the
        // header: the checks of `ChainCode::new`, not repeated here.
        let (symbols, radii_q) = split::decompress_payload(&mut cur, n_symbols, n_nodes, form)?;
        Ok(ChainCode {
            header,
            symbols,
            radii_q,
        })
    }

    /// Bits of the parts of kind 3 that the voxel choice changes: the
    /// header (its symbol count) and the correction streams. The structure
    /// streams and the radii depend on the skeleton alone.
    pub(crate) fn voxel_dependent_bits(&self) -> Option<u64> {
        let header = self.header_bytes(KIND_SPLIT_3).len() as u64 * 8;
        Some(header + split::correction_bits(self)?)
    }

    fn header_bytes(&self, kind: u8) -> Vec<u8> {
        let h = &self.header;
        let damped = h.prediction != Prediction::DIFFERENTIAL;
        let mut out = Vec::with_capacity(64);
        out.extend_from_slice(MAGIC);
        out.push(VERSION);
        out.push(kind);
        let flags = if h.anchor.crs.is_some() { FLAG_CRS } else { 0 }
            | if h.resolution.is_some() {
                FLAG_RESOLUTION
            } else {
                0
            }
            | if damped { FLAG_PREDICTION } else { 0 };
        out.push(flags);
        out.extend_from_slice(&h.voxel_size_m.to_le_bytes());
        out.extend_from_slice(&h.radius_step_m.to_le_bytes());
        if let Some(r) = h.resolution {
            out.extend_from_slice(&r.to_le_bytes());
        }
        if damped {
            out.push(h.prediction.quarters());
        }
        for c in h.anchor.origin.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        for c in h.root_position.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(crs) = &h.anchor.crs {
            put_varint(&mut out, crs.len() as u64);
            out.extend_from_slice(crs.as_bytes());
        }
        put_varint(&mut out, self.symbols.len() as u64);
        put_varint(&mut out, self.radii_q.len() as u64);
        out
    }
}

/// The parts of a compressed chain code ([`ChainCode::compressed_sizes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CompressedSizes {
    /// Length of [`ChainCode::compress`]'s output.
    pub total_bytes: usize,
    /// The common header (georeference, voxel size, counts).
    pub header_bytes: usize,
    /// Container kind: 1 single symbol string, 3 split streams.
    pub kind: u8,
    /// Varints and flags between the header and the bit stream.
    pub metadata_bytes: usize,
    /// Kind 3: the interpolative codes of the structure (tips, forks and
    /// lateral counts); 0 for kind 1.
    pub structure_bits: u64,
    /// Kind 3: the six correction streams; kind 1: the whole symbol string.
    pub move_bits: u64,
    /// The radius codes (kind 1: with the bit stream's padding).
    pub radius_bits: u64,
    /// Kind 3: the radius layout written; `None` for kind 1.
    pub radius_layout: Option<RadiusLayout>,
}

/// True if `bytes` start like a chain code stream of either kind.
pub fn is_chain_code(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// The payload of kind 1 (one interpolative code of the BWT/MTF symbol
/// string, then one of the radius gaps) after its header.
/// Decodes the interpolative form straight into a skeleton: the result of
/// `decode(&ChainCode::decompress(bytes, limits)?)`, faster because the
/// split forms (kinds 2 and 3, what [`ChainCode::compress`] writes for every
/// encoder-made code) are decoded internode by internode without writing
/// out the move symbols and reading them again.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use silva::encode::chaincode::{self, ChainCode, ChainOptions, Limits};
/// use silva::{Anchor, NodeId, Skeleton};
///
/// let mut tree = Skeleton::new(Anchor::at(DVec3::ZERO), 0.2);
/// let top = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.1);
/// tree.add_child(top, Vec3::new(0.5, 0.0, 2.5), 0.05);
/// let bytes = chaincode::encode(&tree, &ChainOptions::default()).unwrap().compress();
///
/// let fast = chaincode::decode_compressed(&bytes, &Limits::default()).unwrap();
/// let code = ChainCode::decompress(&bytes, &Limits::default()).unwrap();
/// assert_eq!(fast, chaincode::decode(&code).unwrap());
/// ```
pub fn decode_compressed(bytes: &[u8], limits: &Limits) -> Result<Skeleton, ChainError> {
    let mut cur = ByteCursor::new(bytes);
    let (header, kind, n_symbols, n_nodes) = read_header(&mut cur, limits)?;
    let Some(form) = split_form(bytes, kind)? else {
        return dbf6::decode(&decompress_kind1(&mut cur, header, n_symbols, n_nodes)?);
    };
    let (terminators, radii_q) = split::read_payload(&mut cur, n_symbols, n_nodes, form)?;
    dbf6::decode_terminators(&header, &radii_q, n_symbols, &terminators)
}

/// Decodes either byte form into a skeleton, told apart by the header's
/// kind byte: the plain form ([`ChainCode::from_bytes`], then
/// [`decode`](super::decode)) or a compressed one ([`decode_compressed`]).
/// An error is the one of the form the bytes declare.
pub fn decode_bytes(bytes: &[u8], limits: &Limits) -> Result<Skeleton, ChainError> {
    if bytes.get(MAGIC.len() + 1) == Some(&KIND_PLAIN) {
        return dbf6::decode(&ChainCode::from_bytes(bytes, limits)?);
    }
    decode_compressed(bytes, limits)
}

/// The split form of a compressed stream of `kind`; `None` for kind 1.
fn split_form(bytes: &[u8], kind: u8) -> Result<Option<Form>, ChainError> {
    match kind {
        KIND_SPLIT => Ok(Some(Form::Kind2)),
        KIND_SPLIT_3 if bytes[MAGIC.len()] >= VERSION => Ok(Some(Form::Kind3)),
        KIND_SPLIT_3 => Err(ChainError::Malformed("kind 3 in a version 1 stream")),
        KIND_INTERPOLATIVE => Ok(None),
        _ => Err(ChainError::Malformed(
            "not a compressed chain code; use from_bytes",
        )),
    }
}

fn decompress_kind1(
    cur: &mut ByteCursor<'_>,
    header: ChainHeader,
    n_symbols: usize,
    n_nodes: usize,
) -> Result<ChainCode, ChainError> {
    let primary = usize::try_from(cur.varint()?)
        .map_err(|_| ChainError::Malformed("BWT key out of range"))?;
    let code_last = cur.varint()?;
    let mapping = match cur.u8()? {
        0 => GapMapping::Offset(unzigzag(cur.varint()?)),
        1 => GapMapping::Zigzag,
        _ => return Err(ChainError::Malformed("unknown radius gap mapping")),
    };
    let max_gap = cur.varint()?;
    let radius_last = cur.varint()?;
    let bit_bytes = cur.rest();
    let mut r = BitReader::new(bit_bytes);
    let symbols = kind1_symbols(&mut r, n_symbols, code_last, primary)?;
    let scan = lod::scan(&symbols, n_nodes)?;
    let radius_sums = interpolative::decode_from(&mut r, n_nodes, radius_last, max_gap).ok_or(
        ChainError::Malformed("radius sums inconsistent with their count"),
    )?;
    if r.overrun() {
        return Err(ChainError::Truncated);
    }
    if r.bytes_consumed() != bit_bytes.len() {
        return Err(ChainError::Malformed("bytes after the compressed stream"));
    }
    let gaps = differences(&radius_sums)
        .map(|u| mapping.invert(u))
        .collect::<Option<Vec<i64>>>()
        .ok_or(ChainError::Malformed("radius gap out of range"))?;
    let radii_q = radii_from_gaps(&gaps, &scan.branch_lengths())
        .ok_or(ChainError::Malformed("radius out of range"))?;
    ChainCode::new(header, symbols, radii_q)
}

/// Kind 1's symbols: the interpolative code of the cumulative MTF indices,
/// then inverse MTF and inverse BWT with key `primary`.
fn kind1_symbols(
    r: &mut BitReader<'_>,
    n_symbols: usize,
    code_last: u64,
    primary: usize,
) -> Result<Vec<u8>, ChainError> {
    let code_sums = interpolative::decode_from(r, n_symbols, code_last, MAX_SYMBOL_GAP).ok_or(
        ChainError::Malformed("symbol sums inconsistent with their count"),
    )?;
    let indices: Vec<u8> = differences(&code_sums).map(|g| g as u8).collect();
    let last = mtf::mtf_inverse(&indices, ALPHABET)
        .ok_or(ChainError::Malformed("move-to-front index out of range"))?;
    bwt::bwt_inverse(&last, primary, ALPHABET).ok_or(ChainError::Malformed(
        "BWT key does not invert the transform",
    ))
}

/// Parses and checks the common header: `(header, kind, symbols, nodes)`.
fn read_header(
    cur: &mut ByteCursor<'_>,
    limits: &Limits,
) -> Result<(ChainHeader, u8, usize, usize), ChainError> {
    if cur.take(4).map_err(|_| ChainError::BadMagic)? != MAGIC {
        return Err(ChainError::BadMagic);
    }
    let version = cur.u8()?;
    if !(VERSION_1..=VERSION).contains(&version) {
        return Err(ChainError::UnsupportedVersion(version));
    }
    let kind = cur.u8()?;
    let flags = cur.u8()?;
    if flags & !(FLAG_CRS | FLAG_RESOLUTION | FLAG_PREDICTION) != 0 {
        return Err(ChainError::Malformed("unknown flags"));
    }
    let voxel_size_m = cur.f64()?;
    let radius_step_m = cur.f32()?;
    let resolution = if flags & FLAG_RESOLUTION != 0 {
        Some(cur.f32()?)
    } else {
        None
    };
    let prediction = if flags & FLAG_PREDICTION != 0 {
        match Prediction::from_quarters(cur.u8()?) {
            Some(p) if p != Prediction::DIFFERENTIAL => p,
            _ => {
                return Err(ChainError::Malformed(
                    "prediction weight is not 0-3 quarters",
                ));
            }
        }
    } else {
        Prediction::DIFFERENTIAL
    };
    let origin = DVec3::new(cur.f64()?, cur.f64()?, cur.f64()?);
    let root_position = Vec3::new(cur.f32()?, cur.f32()?, cur.f32()?);
    let crs = if flags & FLAG_CRS != 0 {
        let len = cur.varint()?;
        if len > limits.max_crs_bytes as u64 {
            return Err(ChainError::Malformed("CRS longer than the limit"));
        }
        let raw = cur.take(len as usize)?;
        let text =
            std::str::from_utf8(raw).map_err(|_| ChainError::Malformed("CRS is not UTF-8"))?;
        Some(text.to_owned())
    } else {
        None
    };
    let n_symbols = cur.varint()?;
    if n_symbols > limits.max_symbols as u64 {
        return Err(ChainError::TooManySymbols {
            found: usize::try_from(n_symbols).unwrap_or(usize::MAX),
            limit: limits.max_symbols,
        });
    }
    let n_nodes = cur.varint()?;
    if n_nodes > limits.max_nodes as u64 {
        return Err(ChainError::TooManyNodes {
            found: usize::try_from(n_nodes).unwrap_or(usize::MAX),
            limit: limits.max_nodes,
        });
    }
    let header = ChainHeader {
        voxel_size_m,
        resolution,
        radius_step_m,
        anchor: Anchor { origin, crs },
        root_position,
        prediction,
    };
    header.validate()?;
    Ok((header, kind, n_symbols as usize, n_nodes as usize))
}

/// The mapping that codes the radius gaps in fewer bits, with its
/// cumulative sums.
pub(super) fn best_radius_mapping(gaps: &[i64]) -> (GapMapping, Vec<u64>) {
    let min = gaps.iter().copied().min().unwrap_or(0);
    [GapMapping::Offset(min), GapMapping::Zigzag]
        .into_iter()
        .map(|mapping| {
            let mapped: Vec<u64> = gaps.iter().map(|&g| mapping.apply(g)).collect();
            let max_gap = mapped.iter().copied().max().unwrap_or(0);
            let sums = cumulative(mapped.iter().copied());
            let mut w = BitCounter::default();
            interpolative::encode_into(&mut w, &sums, max_gap);
            (mapping, sums, w.bit_len())
        })
        .min_by_key(|(_, _, bits)| *bits)
        .map(|(mapping, sums, _)| (mapping, sums))
        .expect("two candidates")
}

pub(super) fn cumulative(values: impl Iterator<Item = u64>) -> Vec<u64> {
    values
        .scan(0u64, |acc, v| {
            *acc += v;
            Some(*acc)
        })
        .collect()
}

pub(super) fn differences(sums: &[u64]) -> impl Iterator<Item = u64> + '_ {
    // Zipped with the previous sums rather than scanned, so that the
    // iterator knows its length and `collect` allocates once.
    let previous = std::iter::once(0).chain(sums.iter().copied());
    sums.iter().zip(previous).map(|(&s, p)| s - p)
}

pub(super) fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

pub(super) fn unzigzag(u: u64) -> i64 {
    ((u >> 1) as i64) ^ -((u & 1) as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gaps between cumulative sums; the iterator knows its length, so
    /// collecting the decoded streams allocates once.
    #[test]
    fn differences_are_the_gaps_and_know_their_length() {
        let sums = [2u64, 2, 5, 9];
        let gaps = differences(&sums);
        assert_eq!(gaps.size_hint(), (4, Some(4)));
        assert_eq!(gaps.collect::<Vec<_>>(), [2, 0, 3, 4]);
        assert_eq!(differences(&[]).count(), 0);
    }
}
