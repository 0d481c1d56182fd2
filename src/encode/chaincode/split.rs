//! The split-stream interpolative forms (container kinds 2 and 3): the same
//! interpolative machinery as chain-code paper §3.3 (BWT, MTF, cumulative
//! sums, binary interpolative coding), applied to separate streams instead
//! of one symbol string.
//!
//! Why: on skeletons reconstructed from point clouds, corrections are large
//! (6–8 moves per internode at `r = 5`) and a DBF6 string spends most of its
//! length on move symbols written in unary. Coding each internode's
//! correction as three signed integers, one stream per axis and per kind of
//! internode (a branch's first internode, coded in full, or a continuation,
//! coded as a correction), and the terminators in a stream of their own,
//! shrinks those codes by about a fifth; splitting the radius gaps into tip
//! radii and along-branch increases (mostly zero) saves another fifth of the
//! radius bits. Kind 3 (container version 2) codes the terminators as
//! tip bits, fork bits and lateral counts (their order-0 entropy, which BWT
//! and MTF do not reach on reconstructed trees) and codes the radii in the
//! shortest of three layouts: tip-first, parent-predicted (each lateral's
//! base from its fork node) or child-predicted (each node from its thickest
//! child). Measured figures are in `docs/chaincode.md` §9.
//!
//! The form is lossless for every code whose internodes write their moves
//! clustered by axis (`push_moves` in the encoder) or as the cancelling pair
//! `0 3` before a fork symbol, which is every code [`super::encode`] and
//! [`super::reduce_lod`] produce. Any other code is written in kind 1.
//! Kind 3 relies on the canonical `0 3` pair: only where a fork marker could
//! stand, so the decoder restores it without a structure item.

use super::bits::{BitCounter, BitReader, BitSink, BitWriter, ByteCursor, put_varint};
use super::container::{best_radius_mapping, cumulative, differences, unzigzag, zigzag};
use super::dbf6::Terminator;
use super::radii::{
    GapMapping, branch_gaps, child_gaps, parent_gaps, radii_from_child_gaps, radii_from_gaps,
    radii_from_parent_gaps,
};
use super::{ChainCode, ChainError, END, FORK, MOVE_NEG_X, MOVE_POS_X, TIP, bwt, interpolative};
use super::{lod, mtf};

/// Structure stream: a zero-length fork internode (one more lateral).
const S_MARKER: u8 = 0;
/// An internode ending at a fork.
const S_FORK: u8 = 1;
/// An internode ending at a tip.
const S_TIP: u8 = 2;
/// An internode ending at a node with one child.
const S_END: u8 = 3;
/// An internode with zero correction written as `0 3`, ending at a fork.
const S_FORK_PAIR: u8 = 4;
const STRUCT_ALPHABET: usize = 5;

/// Index of the correction streams: `[first internode of a branch,
/// continuation][axis]`.
type Corrections = [[Vec<u64>; 3]; 2];

/// The streams of a code: structure items and zigzagged corrections.
struct Streams {
    structure: Vec<u8>,
    corrections: Corrections,
}

/// Splits the symbols into streams; `None` if some internode writes its
/// moves in another order than the encoder's (then kind 1 is used).
fn split(symbols: &[u8]) -> Option<Streams> {
    let mut out = Streams {
        structure: Vec::new(),
        corrections: Default::default(),
    };
    let mut corr = [0i64; 3];
    let mut moves_start = 0;
    let mut markers_allowed = true;
    let mut branch_start = true;
    let mut expected = Vec::new();
    for (pos, &s) in symbols.iter().enumerate() {
        if s < FORK {
            let axis = usize::from(s % 3);
            corr[axis] += if s < 3 { 1 } else { -1 };
            continue;
        }
        let moves = &symbols[moves_start..pos];
        moves_start = pos + 1;
        if s == FORK && markers_allowed && moves.is_empty() {
            out.structure.push(S_MARKER);
            continue;
        }
        expected.clear();
        push_moves(&mut expected, corr);
        let item = match s {
            FORK if moves == [MOVE_POS_X, MOVE_NEG_X] && corr == [0; 3] && markers_allowed => {
                S_FORK_PAIR
            }
            _ if moves != expected.as_slice() => return None,
            FORK => S_FORK,
            TIP => S_TIP,
            END => S_END,
            _ => return None,
        };
        out.structure.push(item);
        let kind = usize::from(!branch_start);
        for (stream, &c) in out.corrections[kind].iter_mut().zip(&corr) {
            stream.push(zigzag(c));
        }
        corr = [0; 3];
        markers_allowed = s == FORK;
        branch_start = s == TIP;
    }
    Some(out)
}

/// Moves of a correction clustered by axis: x, then y, then z (as the
/// encoder writes them).
fn push_moves(symbols: &mut Vec<u8>, c: [i64; 3]) {
    for (axis, &v) in c.iter().enumerate() {
        let sym = if v >= 0 { axis as u8 } else { axis as u8 + 3 };
        symbols.extend(std::iter::repeat_n(sym, v.unsigned_abs() as usize));
    }
}

/// Writes one non-negative stream: `max_gap` and the last cumulative sum as
/// varints into `meta`, the interpolative code into `bits`.
fn put_stream(meta: &mut Vec<u8>, bits: &mut impl BitSink, values: &[u64]) {
    let max_gap = values.iter().copied().max().unwrap_or(0);
    let sums = cumulative(values.iter().copied());
    put_varint(meta, max_gap);
    put_varint(meta, sums.last().copied().unwrap_or(0));
    interpolative::encode_into(bits, &sums, max_gap);
}

/// Largest centre of a branch-first correction stream (kind 3).
const MAX_CENTRE: i64 = 3;

/// Kind 3, a branch's first internode (coded in full): its corrections are
/// not centred on 0 (laterals mostly grow upwards), so the stream stores a
/// centre `c` in `-3..=3` (zigzagged, one byte) and codes `zigzag(v − c)`,
/// with the `c` that codes shortest.
fn put_centred_stream(meta: &mut Vec<u8>, bits: &mut impl BitSink, zigzagged: &[u64]) {
    let shifted =
        |c: i64| -> Vec<u64> { zigzagged.iter().map(|&z| zigzag(unzigzag(z) - c)).collect() };
    let cost = |values: &[u64]| {
        let (mut m, mut b) = (Vec::new(), BitCounter::default());
        put_stream(&mut m, &mut b, values);
        m.len() as u64 * 8 + b.bit_len()
    };
    let centre = (-MAX_CENTRE..=MAX_CENTRE)
        .min_by_key(|&c| (cost(&shifted(c)), c.unsigned_abs()))
        .unwrap_or(0);
    put_varint(meta, zigzag(centre));
    put_stream(meta, bits, &shifted(centre));
}

fn get_centre(cur: &mut ByteCursor<'_>) -> Result<i64, ChainError> {
    let c = unzigzag(cur.varint()?);
    if !(-MAX_CENTRE..=MAX_CENTRE).contains(&c) {
        return Err(ChainError::Malformed("correction centre out of range"));
    }
    Ok(c)
}

/// Inverts the centring of [`put_centred_stream`]; values out of range are
/// left for `join` to refuse.
fn uncentre(stream: &mut [u64], centre: i64) {
    for z in stream {
        *z = zigzag(unzigzag(*z).saturating_add(centre));
    }
}

/// Metadata of one stream: `(max_gap, last sum)`.
fn get_meta(cur: &mut ByteCursor<'_>) -> Result<(u64, u64), ChainError> {
    Ok((cur.varint()?, cur.varint()?))
}

fn get_stream(
    r: &mut BitReader<'_>,
    n: usize,
    (max_gap, last): (u64, u64),
) -> Result<Vec<u64>, ChainError> {
    let sums = interpolative::decode_from(r, n, last, max_gap).ok_or(ChainError::Malformed(
        "stream sums inconsistent with their count",
    ))?;
    Ok(differences(&sums).collect())
}

fn put_mapping(meta: &mut Vec<u8>, mapping: GapMapping) {
    match mapping {
        GapMapping::Offset(min) => {
            meta.push(0);
            put_varint(meta, zigzag(min));
        }
        GapMapping::Zigzag => meta.push(1),
    }
}

fn get_mapping(cur: &mut ByteCursor<'_>) -> Result<GapMapping, ChainError> {
    match cur.u8()? {
        0 => Ok(GapMapping::Offset(unzigzag(cur.varint()?))),
        1 => Ok(GapMapping::Zigzag),
        _ => Err(ChainError::Malformed("unknown radius gap mapping")),
    }
}

/// Splits each branch's radius gaps into its tip radius and its increases
/// towards the base.
fn split_radii(gaps: &[i64], chains: &[usize]) -> (Vec<i64>, Vec<i64>) {
    let mut tips = Vec::with_capacity(chains.len());
    let mut inner = Vec::with_capacity(gaps.len());
    let mut start = 0;
    for &len in chains {
        tips.push(gaps[start]);
        inner.extend_from_slice(&gaps[start + 1..start + len]);
        start += len;
    }
    (tips, inner)
}

/// Which split-stream layout: kind 2 (container version 1) or kind 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// Kind 2: structure items through BWT and MTF; tip-first radii.
    Kind2,
    /// Kind 3: structure as tip bits, fork bits and lateral counts; radii
    /// tip-first or parent-predicted, whichever is shorter.
    Kind3,
}

/// How kind 3 codes the radii: its radius layout byte (`docs/chaincode.md`
/// §7). [`ChainCode::compress`] writes the shortest;
/// [`ChainCode::compress_split_with`] a given one.
///
/// [`ChainCode::compress`]: super::ChainCode::compress
/// [`ChainCode::compress_split_with`]: super::ChainCode::compress_split_with
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RadiusLayout {
    /// 0: per branch its tip radius, then the increases towards the base
    /// (chain-code paper §3.3, split in two streams).
    TipFirst,
    /// 1: the root radius, each lateral's base as a decrease from its fork
    /// node, and the decreases along each branch.
    ParentPredicted,
    /// 2: per branch its tip radius, and every other node as an increase
    /// over its thickest child (radii never grow towards the tips).
    ChildPredicted,
}

impl RadiusLayout {
    /// Every layout, in the order of their bytes.
    pub const ALL: [RadiusLayout; 3] = [
        RadiusLayout::TipFirst,
        RadiusLayout::ParentPredicted,
        RadiusLayout::ChildPredicted,
    ];

    /// The layout byte.
    pub fn byte(self) -> u8 {
        self as u8
    }

    fn from_byte(byte: u8) -> Option<Self> {
        Self::ALL.get(usize::from(byte)).copied()
    }
}

/// What a split form's payload was built from, and where its bits went.
pub(crate) struct Built {
    pub(crate) payload: Vec<u8>,
    /// Bits of the structure, correction and radius codes.
    pub(crate) bits: [u64; 3],
    /// Kind 3: the radius layout written.
    pub(crate) radii: Option<RadiusLayout>,
}

/// The payload (everything after the header) and its parts, or `None` if
/// the code is not in the encoder's move order. `radii`: kind 3's radius
/// layout, `None` for the shortest (kind 2 is always tip-first).
pub(crate) fn build(code: &ChainCode, form: Form, radii: Option<RadiusLayout>) -> Option<Built> {
    let streams = split(code.symbols())?;
    let mut meta = Vec::new();
    let mut bits = BitWriter::new();
    match form {
        Form::Kind2 => put_structure_items(&mut meta, &mut bits, &streams.structure),
        Form::Kind3 => put_structure_bits(&mut meta, &mut bits, &streams.structure),
    }
    let structure_bits = bits.bit_len();
    put_corrections(&mut meta, &mut bits, &streams.corrections, form);
    let correction_bits = bits.bit_len() - structure_bits;

    let scan = lod::scan(code.symbols(), code.radii_q().len()).ok()?;
    let streams = RadiusStreams::of(code.radii_q(), &scan);
    let layout = match form {
        Form::Kind2 => {
            streams.put(RadiusLayout::TipFirst, &mut meta, &mut bits);
            None
        }
        Form::Kind3 => {
            let layout = radii.unwrap_or_else(|| streams.shortest());
            meta.push(layout.byte());
            streams.put(layout, &mut meta, &mut bits);
            Some(layout)
        }
    };
    let radius_bits = bits.bit_len() - structure_bits - correction_bits;
    meta.extend(bits.finish());
    Some(Built {
        payload: meta,
        bits: [structure_bits, correction_bits, radius_bits],
        radii: layout,
    })
}

/// The bits kind 3 spends on the corrections of `code` (their six streams
/// with metadata), or `None` if the code is not in the encoder's move
/// order. Only these depend on the step prediction: the encoder compares
/// predictions by them (`dbf6::encode`) without compressing whole codes.
pub(crate) fn correction_bits(code: &ChainCode) -> Option<u64> {
    let streams = split(code.symbols())?;
    let mut meta = Vec::new();
    let mut bits = BitCounter::default();
    put_corrections(&mut meta, &mut bits, &streams.corrections, Form::Kind3);
    Some(meta.len() as u64 * 8 + bits.bit_len())
}

/// Writes the six correction streams: kind 3 centres the three of
/// branch-first internodes, kind 2 does not.
fn put_corrections(
    meta: &mut Vec<u8>,
    bits: &mut impl BitSink,
    corrections: &Corrections,
    form: Form,
) {
    for (k, stream) in corrections.iter().flatten().enumerate() {
        if form == Form::Kind3 && k < 3 {
            put_centred_stream(meta, bits, stream);
        } else {
            put_stream(meta, bits, stream);
        }
    }
}

/// Kind 2 structure: the items through BWT (virtual end marker) and MTF.
fn put_structure_items(meta: &mut Vec<u8>, bits: &mut impl BitSink, structure: &[u8]) {
    let (last, primary) = bwt::bwt_forward(structure, STRUCT_ALPHABET);
    let indices: Vec<u64> = mtf::mtf_forward(&last, STRUCT_ALPHABET)
        .into_iter()
        .map(u64::from)
        .collect();
    put_varint(meta, structure.len() as u64);
    put_varint(meta, primary as u64);
    put_stream(meta, bits, &indices);
}

/// Kind 3 structure: the number of leading fork markers (laterals of the
/// root beyond the first), then three streams: one bit per internode (1 at
/// a tip), one bit per other internode (1 at a fork), and per fork the
/// number of further laterals (its zero-length internodes). Coding which
/// internodes are tips as a set of positions costs close to its order-0
/// entropy, which BWT and MTF on the mixed items do not reach.
fn put_structure_bits(meta: &mut Vec<u8>, bits: &mut impl BitSink, structure: &[u8]) {
    let leading = structure.iter().take_while(|&&i| i == S_MARKER).count();
    let mut tips = Vec::new();
    let mut forks = Vec::new();
    let mut laterals: Vec<u64> = Vec::new();
    for &item in &structure[leading..] {
        match item {
            S_MARKER => *laterals.last_mut().expect("a marker follows a fork") += 1,
            S_TIP => tips.push(1),
            _ => {
                tips.push(0);
                let fork = item == S_FORK || item == S_FORK_PAIR;
                forks.push(u64::from(fork));
                if fork {
                    laterals.push(0);
                }
            }
        }
    }
    put_varint(meta, leading as u64);
    for stream in [&tips, &forks, &laterals] {
        put_stream(meta, bits, stream);
    }
}

/// The radius streams of a code, in every layout.
struct RadiusStreams {
    /// Tip-first: per branch its tip radius, then increases towards the base.
    tips: Vec<i64>,
    inner: Vec<i64>,
    /// Parent-predicted: root radius, lateral bases below their fork node's
    /// radius, decreases along each branch.
    root: u64,
    bases: Vec<i64>,
    along: Vec<i64>,
    /// Child-predicted: `tips`, then each other node's increase over its
    /// thickest child.
    over_children: Vec<i64>,
}

impl RadiusStreams {
    fn of(radii_q: &[u32], scan: &lod::Scan) -> Self {
        let chains = scan.branch_lengths();
        let gaps = branch_gaps(radii_q, &chains);
        let (tips, inner) = split_radii(&gaps, &chains);
        let parents = scan.branch_parents();
        let (bases, along) = parent_gaps(radii_q, &chains, &parents);
        let (_, over_children) = child_gaps(radii_q, &chains, &parents);
        Self {
            tips,
            inner,
            root: radii_q.first().map_or(0, |&q| u64::from(q)),
            bases,
            along,
            over_children,
        }
    }

    /// The metadata and interpolative codes of one layout (without its
    /// layout byte).
    fn put(&self, layout: RadiusLayout, meta: &mut Vec<u8>, bits: &mut impl BitSink) {
        let (first, second) = match layout {
            RadiusLayout::TipFirst => (&self.tips, &self.inner),
            RadiusLayout::ParentPredicted => {
                put_varint(meta, self.root);
                (&self.bases, &self.along)
            }
            RadiusLayout::ChildPredicted => {
                put_escaped_stream(meta, bits, &self.tips);
                put_escaped_stream(meta, bits, &self.over_children);
                return;
            }
        };
        put_signed_stream(meta, bits, first);
        put_signed_stream(meta, bits, second);
    }

    /// The layout that codes shortest (metadata included); the lowest byte
    /// on a tie.
    fn shortest(&self) -> RadiusLayout {
        let cost = |layout| {
            let (mut m, mut b) = (Vec::new(), BitCounter::default());
            self.put(layout, &mut m, &mut b);
            m.len() as u64 * 8 + b.bit_len()
        };
        RadiusLayout::ALL
            .into_iter()
            .min_by_key(|&layout| cost(layout))
            .unwrap_or(RadiusLayout::TipFirst)
    }
}

/// A signed stream made non-negative by the shorter mapping (the mapping
/// goes into `meta` before the stream's own metadata).
fn put_signed_stream(meta: &mut Vec<u8>, bits: &mut impl BitSink, values: &[i64]) {
    let (mapping, _) = best_radius_mapping(values);
    put_mapping(meta, mapping);
    let mapped: Vec<u64> = values.iter().map(|&g| mapping.apply(g)).collect();
    put_stream(meta, bits, &mapped);
}

/// Radius layout 2: a signed stream as its most common value `m` (a
/// zigzagged varint in `meta`), a flag stream marking the values other than
/// `m`, and those values as a signed stream. Most tips of a reconstruction
/// carry the pipe model's tip radius and most nodes their thickest child's:
/// the flags code their positions close to the order-0 entropy, where one
/// interpolative code over all values pays for every outlier's neighbours.
fn put_escaped_stream(meta: &mut Vec<u8>, bits: &mut impl BitSink, values: &[i64]) {
    let mode = most_common(values);
    let flags: Vec<u64> = values.iter().map(|&v| u64::from(v != mode)).collect();
    let others: Vec<i64> = values.iter().copied().filter(|&v| v != mode).collect();
    put_varint(meta, zigzag(mode));
    put_stream(meta, bits, &flags);
    put_signed_stream(meta, bits, &others);
}

/// The most common value (the smallest of equally common ones; 0 if empty).
fn most_common(values: &[i64]) -> i64 {
    let mut sorted = values.to_vec();
    sorted.sort_unstable();
    sorted
        .chunk_by(|a, b| a == b)
        .max_by_key(|run| (run.len(), std::cmp::Reverse(run[0])))
        .map_or(0, |run| run[0])
}

/// Reads a split-stream payload into the symbols and radii of `n_symbols`
/// and `n_nodes` (already checked against the limits).
pub(crate) fn decompress_payload(
    cur: &mut ByteCursor<'_>,
    n_symbols: usize,
    n_nodes: usize,
    form: Form,
) -> Result<(Vec<u8>, Vec<u32>), ChainError> {
    let (terminators, radii_q) = read_payload(cur, n_symbols, n_nodes, form)?;
    Ok((symbols_of(&terminators, n_symbols), radii_q))
}

/// Reads a split-stream payload into its internodes' terminators (checked
/// against the grammar) and radii.
pub(crate) fn read_payload(
    cur: &mut ByteCursor<'_>,
    n_symbols: usize,
    n_nodes: usize,
    form: Form,
) -> Result<(Vec<Terminator>, Vec<u32>), ChainError> {
    if n_nodes == 0 {
        return Err(ChainError::RadiiCount { nodes: 1, radii: 0 });
    }
    let structure_meta = match form {
        Form::Kind2 => StructureMeta::items(cur, n_symbols)?,
        Form::Kind3 => StructureMeta::bits(cur, n_symbols)?,
    };
    let mut centres = [0i64; 3];
    let mut corr_meta = [(0, 0); 6];
    for (k, m) in corr_meta.iter_mut().enumerate() {
        if form == Form::Kind3 && k < 3 {
            centres[k] = get_centre(cur)?;
        }
        *m = get_meta(cur)?;
    }
    let radius_meta = match form {
        Form::Kind2 => RadiusMeta::tip_first(cur)?,
        Form::Kind3 => match RadiusLayout::from_byte(cur.u8()?) {
            Some(RadiusLayout::TipFirst) => RadiusMeta::tip_first(cur)?,
            Some(RadiusLayout::ParentPredicted) => RadiusMeta::parent_predicted(cur)?,
            Some(RadiusLayout::ChildPredicted) => RadiusMeta::child_predicted(cur)?,
            None => return Err(ChainError::Malformed("unknown radius layout")),
        },
    };
    let bit_bytes = cur.rest();
    let mut r = BitReader::new(bit_bytes);

    let structure = structure_meta.read(&mut r, n_nodes - 1)?;
    let counts = internode_counts(&structure);
    if counts[0] + counts[1] + 1 != n_nodes {
        return Err(ChainError::Malformed(
            "structure disagrees with the node count",
        ));
    }
    let mut corrections: Corrections = Default::default();
    for (k, m) in corr_meta.iter().enumerate() {
        corrections[k / 3][k % 3] = get_stream(&mut r, counts[k / 3], *m)?;
    }
    for (stream, &centre) in corrections[0].iter_mut().zip(&centres) {
        uncentre(stream, centre);
    }
    let terminators = join(&structure, &corrections, n_symbols, form == Form::Kind3)?;

    let scan = lod::scan_terminators(&terminators, n_symbols, n_nodes)?;
    let radii_q = radius_meta.read(&mut r, &scan, n_nodes)?;
    if r.overrun() {
        return Err(ChainError::Truncated);
    }
    if r.bytes_consumed() != bit_bytes.len() {
        return Err(ChainError::Malformed("bytes after the compressed stream"));
    }
    Ok((terminators, radii_q))
}

type Meta = (u64, u64);

/// The structure's metadata, read before the bit stream.
enum StructureMeta {
    Items {
        len: usize,
        primary: usize,
        meta: Meta,
    },
    Bits {
        leading: usize,
        tips: Meta,
        forks: Meta,
        laterals: Meta,
    },
}

impl StructureMeta {
    fn items(cur: &mut ByteCursor<'_>, n_symbols: usize) -> Result<Self, ChainError> {
        let len = cur.varint()?;
        if len > n_symbols as u64 {
            return Err(ChainError::Malformed("structure longer than the symbols"));
        }
        let primary = usize::try_from(cur.varint()?)
            .map_err(|_| ChainError::Malformed("BWT key out of range"))?;
        Ok(Self::Items {
            len: len as usize,
            primary,
            meta: get_meta(cur)?,
        })
    }

    fn bits(cur: &mut ByteCursor<'_>, n_symbols: usize) -> Result<Self, ChainError> {
        let leading = cur.varint()?;
        if leading > n_symbols as u64 {
            return Err(ChainError::Malformed("structure longer than the symbols"));
        }
        Ok(Self::Bits {
            leading: leading as usize,
            tips: get_meta(cur)?,
            forks: get_meta(cur)?,
            laterals: get_meta(cur)?,
        })
    }

    /// The structure items of a code with `n_internodes` internodes.
    fn read(&self, r: &mut BitReader<'_>, n_internodes: usize) -> Result<Vec<u8>, ChainError> {
        match *self {
            Self::Items { len, primary, meta } => {
                let indices: Vec<u8> = get_stream(r, len, meta)?
                    .into_iter()
                    .map(|i| u8::try_from(i).unwrap_or(u8::MAX))
                    .collect();
                let last = mtf::mtf_inverse(&indices, STRUCT_ALPHABET)
                    .ok_or(ChainError::Malformed("move-to-front index out of range"))?;
                bwt::bwt_inverse(&last, primary, STRUCT_ALPHABET).ok_or(ChainError::Malformed(
                    "BWT key does not invert the transform",
                ))
            }
            Self::Bits {
                leading,
                tips,
                forks,
                laterals,
            } => {
                let tips = get_flags(r, n_internodes, tips)?;
                let n_other = tips.iter().filter(|&&t| !t).count();
                let forks = get_flags(r, n_other, forks)?;
                let n_forks = forks.iter().filter(|&&f| f).count();
                if laterals.1 > (n_internodes + leading) as u64 {
                    return Err(ChainError::Malformed("more laterals than internodes"));
                }
                let laterals = get_stream(r, n_forks, laterals)?;
                Ok(structure_items(leading, &tips, &forks, &laterals))
            }
        }
    }
}

/// A stream of 0/1 values.
fn get_flags(r: &mut BitReader<'_>, n: usize, meta: Meta) -> Result<Vec<bool>, ChainError> {
    if meta.0 > 1 {
        return Err(ChainError::Malformed("flag stream with values above 1"));
    }
    Ok(get_stream(r, n, meta)?
        .into_iter()
        .map(|v| v == 1)
        .collect())
}

/// Rebuilds the kind-2 structure items from the kind-3 streams (every
/// internode ending at a fork as `S_FORK`; `join` restores the `0 3` pair).
fn structure_items(leading: usize, tips: &[bool], forks: &[bool], laterals: &[u64]) -> Vec<u8> {
    let mut items = vec![S_MARKER; leading];
    let (mut forks, mut laterals) = (forks.iter(), laterals.iter());
    for &tip in tips {
        if tip {
            items.push(S_TIP);
        } else if forks.next() == Some(&true) {
            items.push(S_FORK);
            let extra = laterals.next().copied().unwrap_or(0) as usize;
            items.extend(std::iter::repeat_n(S_MARKER, extra));
        } else {
            items.push(S_END);
        }
    }
    items
}

/// The radius metadata, read before the bit stream.
enum RadiusMeta {
    TipFirst {
        tips: (GapMapping, Meta),
        inner: (GapMapping, Meta),
    },
    ParentPredicted {
        root: u64,
        bases: (GapMapping, Meta),
        along: (GapMapping, Meta),
    },
    ChildPredicted {
        tips: EscapedMeta,
        over_children: EscapedMeta,
    },
}

/// The metadata of a [`put_escaped_stream`]: most common value, flags,
/// the other values.
#[derive(Clone, Copy)]
struct EscapedMeta {
    mode: i64,
    flags: Meta,
    others: (GapMapping, Meta),
}

impl EscapedMeta {
    fn read(cur: &mut ByteCursor<'_>) -> Result<Self, ChainError> {
        Ok(Self {
            mode: unzigzag(cur.varint()?),
            flags: get_meta(cur)?,
            others: (get_mapping(cur)?, get_meta(cur)?),
        })
    }

    /// The `n` values of the stream.
    fn values(self, r: &mut BitReader<'_>, n: usize) -> Result<Vec<i64>, ChainError> {
        let flags = get_flags(r, n, self.flags)?;
        let n_others = flags.iter().filter(|&&f| f).count();
        let mut others = get_signed_stream(r, n_others, self.others)?.into_iter();
        Ok(flags
            .iter()
            .map(|&f| if f { others.next() } else { None }.unwrap_or(self.mode))
            .collect())
    }
}

impl RadiusMeta {
    fn tip_first(cur: &mut ByteCursor<'_>) -> Result<Self, ChainError> {
        Ok(Self::TipFirst {
            tips: (get_mapping(cur)?, get_meta(cur)?),
            inner: (get_mapping(cur)?, get_meta(cur)?),
        })
    }

    fn child_predicted(cur: &mut ByteCursor<'_>) -> Result<Self, ChainError> {
        Ok(Self::ChildPredicted {
            tips: EscapedMeta::read(cur)?,
            over_children: EscapedMeta::read(cur)?,
        })
    }

    fn parent_predicted(cur: &mut ByteCursor<'_>) -> Result<Self, ChainError> {
        Ok(Self::ParentPredicted {
            root: cur.varint()?,
            bases: (get_mapping(cur)?, get_meta(cur)?),
            along: (get_mapping(cur)?, get_meta(cur)?),
        })
    }

    fn read(
        &self,
        r: &mut BitReader<'_>,
        scan: &lod::Scan,
        n_nodes: usize,
    ) -> Result<Vec<u32>, ChainError> {
        let chains = scan.branch_lengths();
        let out_of_range = ChainError::Malformed("radius out of range");
        match *self {
            Self::TipFirst { tips, inner } => {
                let tips = get_signed_stream(r, chains.len(), tips)?;
                let inner = get_signed_stream(r, n_nodes - chains.len(), inner)?;
                let gaps = join_radii(&tips, &inner, &chains)
                    .ok_or(ChainError::Malformed("radius gap out of range"))?;
                radii_from_gaps(&gaps, &chains).ok_or(out_of_range)
            }
            Self::ParentPredicted { root, bases, along } => {
                let bases = get_signed_stream(r, chains.len() - 1, bases)?;
                let along = get_signed_stream(r, n_nodes - chains.len(), along)?;
                let parents = scan.branch_parents();
                radii_from_parent_gaps(root, (&bases, &along), &chains, &parents)
                    .ok_or(out_of_range)
            }
            Self::ChildPredicted {
                tips,
                over_children,
            } => {
                let tips = tips.values(r, chains.len())?;
                let over = over_children.values(r, n_nodes - chains.len())?;
                let parents = scan.branch_parents();
                radii_from_child_gaps((&tips, &over), &chains, &parents).ok_or(out_of_range)
            }
        }
    }
}

/// A stream written by [`put_signed_stream`].
fn get_signed_stream(
    r: &mut BitReader<'_>,
    n: usize,
    (mapping, meta): (GapMapping, Meta),
) -> Result<Vec<i64>, ChainError> {
    get_stream(r, n, meta)?
        .into_iter()
        .map(|u| mapping.invert(u))
        .collect::<Option<Vec<i64>>>()
        .ok_or(ChainError::Malformed("radius gap out of range"))
}

/// Internodes that start a branch and continuations, from the structure.
fn internode_counts(structure: &[u8]) -> [usize; 2] {
    let mut counts = [0usize; 2];
    let mut branch_start = true;
    for &item in structure {
        if item == S_MARKER {
            continue;
        }
        counts[usize::from(!branch_start)] += 1;
        branch_start = item == S_TIP;
    }
    counts
}

/// Rebuilds the internodes' terminators of a code of `n_symbols` symbols,
/// never describing more symbols than that.
///
/// With `restore_pairs` (kind 3), an internode ending at a fork with a zero
/// correction where a fork marker could stand is the encoder's `0 3 6`.
fn join(
    structure: &[u8],
    corrections: &Corrections,
    n_symbols: usize,
    restore_pairs: bool,
) -> Result<Vec<Terminator>, ChainError> {
    let too_long = || ChainError::Malformed("streams describe more symbols than declared");
    let mut terminators = Vec::with_capacity(structure.len());
    // Symbols described so far.
    let mut len = 0u64;
    let mut next = [0usize; 2];
    let mut branch_start = true;
    let mut markers_allowed = true;
    for &item in structure {
        if item == S_MARKER {
            if len >= n_symbols as u64 {
                return Err(too_long());
            }
            terminators.push(Terminator {
                pos: len as usize,
                symbol: FORK,
                correction: [0; 3],
                has_moves: false,
            });
            len += 1;
            continue;
        }
        let kind = usize::from(!branch_start);
        let i = next[kind];
        next[kind] += 1;
        let mut correction = [0i32; 3];
        let mut moves = 0u64;
        for (axis, c) in correction.iter_mut().enumerate() {
            let z = corrections[kind][axis][i];
            *c = i32::try_from(unzigzag(z)).map_err(|_| too_long())?;
            moves += u64::from(c.unsigned_abs());
        }
        let item = match item {
            S_FORK if restore_pairs && markers_allowed && correction == [0; 3] => S_FORK_PAIR,
            _ => item,
        };
        let symbol = match item {
            S_FORK_PAIR if correction == [0; 3] => {
                moves = 2;
                FORK
            }
            S_FORK => FORK,
            S_TIP => TIP,
            S_END => END,
            _ => return Err(ChainError::Malformed("bad structure item")),
        };
        len += moves;
        if len >= n_symbols as u64 {
            return Err(too_long());
        }
        terminators.push(Terminator {
            pos: len as usize,
            symbol,
            correction,
            has_moves: moves > 0,
        });
        len += 1;
        branch_start = item == S_TIP;
        markers_allowed = item == S_FORK || item == S_FORK_PAIR;
    }
    if len != n_symbols as u64 {
        return Err(ChainError::Malformed(
            "streams disagree with the symbol count",
        ));
    }
    Ok(terminators)
}

/// The DBF6 symbols of a code given as its terminators: each internode's
/// moves clustered by axis (`0 3` for a moving internode with a zero sum),
/// then its terminator.
fn symbols_of(terminators: &[Terminator], n_symbols: usize) -> Vec<u8> {
    let mut symbols = Vec::with_capacity(n_symbols);
    for t in terminators {
        if t.has_moves && t.correction == [0; 3] {
            symbols.extend([MOVE_POS_X, MOVE_NEG_X]);
        } else {
            push_moves(&mut symbols, t.correction.map(i64::from));
        }
        symbols.push(t.symbol);
    }
    symbols
}

/// Interleaves tip radii and inner increases back into per-branch gaps.
fn join_radii(tips: &[i64], inner: &[i64], chains: &[usize]) -> Option<Vec<i64>> {
    let mut gaps = Vec::with_capacity(tips.len() + inner.len());
    let mut inner = inner.iter();
    for (&tip, &len) in tips.iter().zip(chains) {
        gaps.push(tip);
        for _ in 1..len {
            gaps.push(*inner.next()?);
        }
    }
    Some(gaps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_and_join_round_trip_a_stream_with_markers_and_pairs() {
        // The trifurcation test of the encoder: "266036857073717".
        let symbols = [2, 6, 6, 0, 3, 6, 8, 5, 7, 0, 7, 3, 7, 1, 7];
        let streams = split(&symbols).unwrap();
        assert_eq!(
            streams.structure,
            vec![
                S_FORK,
                S_MARKER,
                S_FORK_PAIR,
                S_END,
                S_TIP,
                S_TIP,
                S_TIP,
                S_TIP
            ]
        );
        assert_eq!(internode_counts(&streams.structure), [4, 3]);
        let back = join(
            &streams.structure,
            &streams.corrections,
            symbols.len(),
            false,
        )
        .unwrap();
        assert_eq!(symbols_of(&back, symbols.len()), symbols);
        assert!(
            join(
                &streams.structure,
                &streams.corrections,
                symbols.len() - 1,
                false
            )
            .is_err()
        );

        // Kind 3: tip bits, fork bits and lateral counts; the `0 3` pair is
        // restored by `join`.
        let (mut meta, mut bits) = (Vec::new(), BitWriter::new());
        put_structure_bits(&mut meta, &mut bits, &streams.structure);
        let bytes = bits.finish();
        let mut cur = ByteCursor::new(&meta);
        let structure_meta = StructureMeta::bits(&mut cur, symbols.len()).unwrap();
        let items = structure_meta.read(&mut BitReader::new(&bytes), 7).unwrap();
        let back = join(&items, &streams.corrections, symbols.len(), true).unwrap();
        assert_eq!(symbols_of(&back, symbols.len()), symbols);
        assert!(join(&items, &streams.corrections, symbols.len(), false).is_err());
    }

    #[test]
    fn centres_round_trip_and_hostile_centres_are_refused() {
        let raw = [3i64, 2, 2, 1, 0, 4, 2];
        let values: Vec<u64> = raw.iter().map(|&v| zigzag(v)).collect();
        let (mut meta, mut bits) = (Vec::new(), BitWriter::new());
        put_centred_stream(&mut meta, &mut bits, &values);
        let bytes = bits.finish();
        let mut cur = ByteCursor::new(&meta);
        let centre = get_centre(&mut cur).unwrap();
        assert_eq!(centre, 2, "the values cluster around 2");
        let meta = get_meta(&mut cur).unwrap();
        let mut back = get_stream(&mut BitReader::new(&bytes), raw.len(), meta).unwrap();
        uncentre(&mut back, centre);
        assert_eq!(back, values);
        for hostile in [u64::MAX, zigzag(4), zigzag(-4)] {
            let mut meta = Vec::new();
            put_varint(&mut meta, hostile);
            assert!(get_centre(&mut ByteCursor::new(&meta)).is_err());
        }
    }

    #[test]
    fn escaped_streams_round_trip_and_refuse_flags_above_one() {
        let values = [4i64, 4, 58, 4, 5, 4, 4, -3, 4];
        assert_eq!(most_common(&values), 4);
        assert_eq!(most_common(&[]), 0);
        let (mut meta, mut bits) = (Vec::new(), BitWriter::new());
        put_escaped_stream(&mut meta, &mut bits, &values);
        let bytes = bits.finish();
        let escaped = EscapedMeta::read(&mut ByteCursor::new(&meta)).unwrap();
        assert_eq!(escaped.mode, 4);
        let back = escaped.values(&mut BitReader::new(&bytes), values.len());
        assert_eq!(back.unwrap(), values);
        let hostile = EscapedMeta {
            flags: (2, 3),
            ..escaped
        };
        assert!(
            hostile
                .values(&mut BitReader::new(&bytes), values.len())
                .is_err()
        );
    }

    #[test]
    fn unclustered_moves_are_not_split() {
        // "0 1 0" is not the clustered order "0 0 1".
        assert!(split(&[0, 1, 0, 7]).is_none());
        // A cancelling pair before an END is not the encoder's.
        assert!(split(&[2, 0, 3, 7]).is_none());
    }
}
