//! Fuzzes the chain code decoders: the plain and the interpolative byte
//! forms, the symbol decoder and LOD reduction on whatever they accept. Any
//! input must give Ok or a typed error, never a panic, a hang or an
//! unbounded allocation.
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
    // Most random inputs fail at the magic; also try them as payloads.
    let mut framed = b"SLVC\x01".to_vec();
    framed.extend_from_slice(data);
    for bytes in [data, &framed[..]] {
        for parsed in [
            ChainCode::from_bytes(bytes, &limits),
            ChainCode::decompress(bytes, &limits),
        ] {
            if let Ok(code) = parsed {
                let _ = decode(&code);
                let _ = decode(&reduce_lod(&code, 0.01));
            }
        }
    }
});
