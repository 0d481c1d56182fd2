//! Fuzzes the plain chain code decoder (`ChainCode::from_bytes`: header,
//! 4-bit symbols, fixed-width radii, the symbol grammar), then the raw code
//! decoder and LOD reduction on whatever it accepts. Any input must give Ok
//! or a typed error, never a panic, a hang or an unbounded allocation; an
//! accepted code must survive every byte form unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use silva::encode::chaincode::{ChainCode, Limits, decode, reduce_lod};

fuzz_target!(|data: &[u8]| {
    // Small limits keep each run fast; the limits themselves are under test.
    let limits = Limits {
        max_symbols: 1 << 20,
        max_nodes: 1 << 18,
        max_crs_bytes: 64,
    };
    // Most random inputs fail at the magic; also try them after a plain header.
    let mut framed = b"SLVC\x01\x00".to_vec();
    framed.extend_from_slice(data);
    for bytes in [data, &framed[..]] {
        if let Ok(code) = ChainCode::from_bytes(bytes, &limits) {
            check_accepted(&code, &limits);
        }
    }
});

/// Round trips through the plain form and the compressed kinds, and checks
/// that decoding and LOD reduction stay consistent with the code.
fn check_accepted(code: &ChainCode, limits: &Limits) {
    let again = ChainCode::from_bytes(&code.to_bytes(), limits);
    assert_eq!(again.as_ref(), Ok(code), "plain form round trip");
    let single = ChainCode::decompress(&code.compress_single_string(), limits);
    assert_eq!(single.as_ref(), Ok(code), "kind 1 round trip");
    if let Some(split) = code.compress_split() {
        let back = ChainCode::decompress(&split, limits);
        assert_eq!(back.as_ref(), Ok(code), "kind 3 round trip");
    }
    if let Some(split) = code.compress_split_v1() {
        let back = ChainCode::decompress(&split, limits);
        assert_eq!(back.as_ref(), Ok(code), "kind 2 round trip");
    }
    if let Ok(skeleton) = decode(code) {
        assert_eq!(skeleton.len(), code.radii_q().len(), "one node per radius");
    }
    let lod = reduce_lod(code, 0.05);
    assert_eq!(reduce_lod(&lod, 0.1), reduce_lod(code, 0.1), "LOD composes");
    let _ = decode(&lod);
}
