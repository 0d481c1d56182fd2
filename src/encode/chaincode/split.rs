//! The split-stream interpolative form (container kind 2): the same
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
//! radius bits. Measured figures are in `docs/chaincode.md` §9.
//!
//! The form is lossless for every code whose internodes write their moves
//! clustered by axis (`push_moves` in the encoder) or as the cancelling pair
//! `0 3` before a fork symbol, which is every code [`super::encode`] and
//! [`super::reduce_lod`] produce. Any other code is written in kind 1.

use super::bits::{BitReader, BitWriter, ByteCursor, put_varint};
use super::container::{best_radius_mapping, cumulative, differences, unzigzag, zigzag};
use super::radii::{GapMapping, branch_gaps, radii_from_gaps};
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
            FORK if moves == [MOVE_POS_X, MOVE_NEG_X] && corr == [0; 3] => S_FORK_PAIR,
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
fn put_stream(meta: &mut Vec<u8>, bits: &mut BitWriter, values: &[u64]) {
    let max_gap = values.iter().copied().max().unwrap_or(0);
    let sums = cumulative(values.iter().copied());
    put_varint(meta, max_gap);
    put_varint(meta, sums.last().copied().unwrap_or(0));
    interpolative::encode_into(bits, &sums, max_gap);
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

/// The kind-2 payload (everything after the header), or `None` if the code
/// is not in the encoder's move order.
pub(crate) fn compress_payload(code: &ChainCode) -> Option<Vec<u8>> {
    build(code).map(|(payload, _)| payload)
}

/// Bits of the structure, correction and radius codes of the kind-2 form.
pub(crate) fn stream_bits(code: &ChainCode) -> Option<[u64; 3]> {
    build(code).map(|(_, bits)| bits)
}

fn build(code: &ChainCode) -> Option<(Vec<u8>, [u64; 3])> {
    let streams = split(code.symbols())?;
    let mut meta = Vec::new();
    let mut bits = BitWriter::new();

    let (last, primary) = bwt::bwt_forward(&streams.structure, STRUCT_ALPHABET);
    let indices: Vec<u64> = mtf::mtf_forward(&last, STRUCT_ALPHABET)
        .into_iter()
        .map(u64::from)
        .collect();
    put_varint(&mut meta, streams.structure.len() as u64);
    put_varint(&mut meta, primary as u64);
    put_stream(&mut meta, &mut bits, &indices);
    let structure_bits = bits.bit_len();
    for stream in streams.corrections.iter().flatten() {
        put_stream(&mut meta, &mut bits, stream);
    }
    let correction_bits = bits.bit_len() - structure_bits;

    let scan = lod::scan(code.symbols(), code.radii_q().len()).ok()?;
    let chains = scan.branch_lengths();
    let gaps = branch_gaps(code.radii_q(), &chains);
    let (tips, inner) = split_radii(&gaps, &chains);
    for part in [tips, inner] {
        let (mapping, _) = best_radius_mapping(&part);
        put_mapping(&mut meta, mapping);
        let mapped: Vec<u64> = part.iter().map(|&g| mapping.apply(g)).collect();
        put_stream(&mut meta, &mut bits, &mapped);
    }
    let radius_bits = bits.bit_len() - structure_bits - correction_bits;
    meta.extend(bits.finish());
    Some((meta, [structure_bits, correction_bits, radius_bits]))
}

/// Reads a kind-2 payload into the symbols and radii of `n_symbols` and
/// `n_nodes` (already checked against the limits).
pub(crate) fn decompress_payload(
    cur: &mut ByteCursor<'_>,
    n_symbols: usize,
    n_nodes: usize,
) -> Result<(Vec<u8>, Vec<u32>), ChainError> {
    let n_struct = cur.varint()?;
    if n_struct > n_symbols as u64 {
        return Err(ChainError::Malformed("structure longer than the symbols"));
    }
    let n_struct = n_struct as usize;
    let primary = usize::try_from(cur.varint()?)
        .map_err(|_| ChainError::Malformed("BWT key out of range"))?;
    let struct_meta = get_meta(cur)?;
    let mut corr_meta = [(0, 0); 6];
    for m in &mut corr_meta {
        *m = get_meta(cur)?;
    }
    let tip_mapping = get_mapping(cur)?;
    let tip_meta = get_meta(cur)?;
    let inner_mapping = get_mapping(cur)?;
    let inner_meta = get_meta(cur)?;
    let bit_bytes = cur.rest();
    let mut r = BitReader::new(bit_bytes);

    let indices = get_stream(&mut r, n_struct, struct_meta)?;
    let indices: Vec<u8> = indices
        .into_iter()
        .map(|i| u8::try_from(i).unwrap_or(u8::MAX))
        .collect();
    let last = mtf::mtf_inverse(&indices, STRUCT_ALPHABET)
        .ok_or(ChainError::Malformed("move-to-front index out of range"))?;
    let structure = bwt::bwt_inverse(&last, primary, STRUCT_ALPHABET).ok_or(
        ChainError::Malformed("BWT key does not invert the transform"),
    )?;
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
    let symbols = join(&structure, &corrections, n_symbols)?;

    let scan = lod::scan(&symbols, n_nodes)?;
    let chains = scan.branch_lengths();
    let tips = get_stream(&mut r, chains.len(), tip_meta)?;
    let inner = get_stream(&mut r, n_nodes - chains.len(), inner_meta)?;
    if r.overrun() {
        return Err(ChainError::Truncated);
    }
    if r.bytes_consumed() != bit_bytes.len() {
        return Err(ChainError::Malformed("bytes after the compressed stream"));
    }
    let gaps = join_radii(&tips, tip_mapping, &inner, inner_mapping, &chains)
        .ok_or(ChainError::Malformed("radius gap out of range"))?;
    let radii_q =
        radii_from_gaps(&gaps, &chains).ok_or(ChainError::Malformed("radius out of range"))?;
    Ok((symbols, radii_q))
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

/// Rebuilds the DBF6 symbols, never more than `n_symbols` of them.
fn join(
    structure: &[u8],
    corrections: &Corrections,
    n_symbols: usize,
) -> Result<Vec<u8>, ChainError> {
    let too_long = || ChainError::Malformed("streams describe more symbols than declared");
    let mut symbols = Vec::with_capacity(n_symbols);
    let mut next = [0usize; 2];
    let mut branch_start = true;
    for &item in structure {
        if item == S_MARKER {
            if symbols.len() >= n_symbols {
                return Err(too_long());
            }
            symbols.push(FORK);
            continue;
        }
        let kind = usize::from(!branch_start);
        let i = next[kind];
        next[kind] += 1;
        let mut corr = [0i64; 3];
        let mut moves = 0u64;
        for (axis, c) in corr.iter_mut().enumerate() {
            let z = corrections[kind][axis][i];
            if z > n_symbols as u64 * 2 + 1 {
                return Err(too_long());
            }
            *c = unzigzag(z);
            moves += c.unsigned_abs();
        }
        let ending = if item == S_FORK_PAIR { 3 } else { 1 };
        if symbols.len() as u64 + moves + ending > n_symbols as u64 {
            return Err(too_long());
        }
        push_moves(&mut symbols, corr);
        match item {
            S_FORK_PAIR if corr == [0; 3] => symbols.extend([MOVE_POS_X, MOVE_NEG_X, FORK]),
            S_FORK => symbols.push(FORK),
            S_TIP => symbols.push(TIP),
            S_END => symbols.push(END),
            _ => return Err(ChainError::Malformed("bad structure item")),
        }
        branch_start = item == S_TIP;
    }
    if symbols.len() != n_symbols {
        return Err(ChainError::Malformed(
            "streams disagree with the symbol count",
        ));
    }
    Ok(symbols)
}

/// Interleaves tip radii and inner increases back into per-branch gaps.
fn join_radii(
    tips: &[u64],
    tip_mapping: GapMapping,
    inner: &[u64],
    inner_mapping: GapMapping,
    chains: &[usize],
) -> Option<Vec<i64>> {
    let mut gaps = Vec::with_capacity(tips.len() + inner.len());
    let mut inner = inner.iter();
    for (&tip, &len) in tips.iter().zip(chains) {
        gaps.push(tip_mapping.invert(tip)?);
        for _ in 1..len {
            gaps.push(inner_mapping.invert(*inner.next()?)?);
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
        let back = join(&streams.structure, &streams.corrections, symbols.len()).unwrap();
        assert_eq!(back, symbols);
        assert!(join(&streams.structure, &streams.corrections, symbols.len() - 1).is_err());
    }

    #[test]
    fn unclustered_moves_are_not_split() {
        // "0 1 0" is not the clustered order "0 0 1".
        assert!(split(&[0, 1, 0, 7]).is_none());
        // A cancelling pair before an END is not the encoder's.
        assert!(split(&[2, 0, 3, 7]).is_none());
    }
}
