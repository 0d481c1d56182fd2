//! What every chain-code fuzz target checks on a code that a reader
//! accepted: it round-trips through the plain form and every compressed
//! kind unchanged, decodes to one node per radius (the same skeleton in one
//! step from every compressed form), and its LOD reductions compose. Included by `fuzz_targets/chaincode.rs` and
//! `fuzz_targets/chaincode_stream.rs` with `#[path]`.

use silva::encode::chaincode::{
    ChainCode, Limits, RadiusLayout, decode, decode_compressed, reduce_lod,
};

/// Round trips through the plain form and the compressed kinds, and checks
/// that decoding and LOD reduction stay consistent with the code.
pub fn check_accepted(code: &ChainCode, limits: &Limits) {
    let again = ChainCode::from_bytes(&code.to_bytes(), limits);
    assert_eq!(again.as_ref(), Ok(code), "plain form round trip");
    let best = ChainCode::decompress(&code.compress(), limits);
    assert_eq!(best.as_ref(), Ok(code), "compressed round trip");
    let single = ChainCode::decompress(&code.compress_single_string(), limits);
    assert_eq!(single.as_ref(), Ok(code), "kind 1 round trip");
    if let Some(split) = code.compress_split() {
        let back = ChainCode::decompress(&split, limits);
        assert_eq!(back.as_ref(), Ok(code), "kind 3 round trip");
    }
    for layout in RadiusLayout::ALL {
        if let Some(split) = code.compress_split_with(layout) {
            let back = ChainCode::decompress(&split, limits);
            assert_eq!(back.as_ref(), Ok(code), "kind 3 round trip, {layout:?}");
        }
    }
    if let Some(split) = code.compress_split_v1() {
        let back = ChainCode::decompress(&split, limits);
        assert_eq!(back.as_ref(), Ok(code), "kind 2 round trip");
    }
    let decoded = decode(code);
    if let Ok(skeleton) = &decoded {
        assert_eq!(skeleton.len(), code.radii_q().len(), "one node per radius");
    }
    let mut forms = vec![code.compress(), code.compress_single_string()];
    forms.extend(code.compress_split());
    forms.extend(code.compress_split_v1());
    for bytes in forms {
        assert_eq!(decode_compressed(&bytes, limits), decoded, "one-step decoder");
    }
    let lod = reduce_lod(code, 0.05);
    assert_eq!(reduce_lod(&lod, 0.1), reduce_lod(code, 0.1), "LOD composes");
    let _ = decode(&lod);
}
