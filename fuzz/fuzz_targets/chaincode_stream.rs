//! Fuzzes the compressed chain code decoder (`ChainCode::decompress`): the
//! single-string form (kind 1: BWT, MTF, interpolative code) and the split
//! streams (kind 2 of version 1, kind 3), then the checks of
//! `checks/chaincode.rs` on whatever it accepts. Any input must give Ok or a
//! typed error, never a panic, a hang or an unbounded allocation; an
//! accepted code must survive every byte form unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use silva::encode::chaincode::{ChainCode, Limits};

#[path = "../checks/chaincode.rs"]
mod checks;
use checks::check_accepted;

fuzz_target!(|data: &[u8]| {
    // Small limits keep each run fast; the limits themselves are under test.
    let limits = Limits {
        max_symbols: 1 << 18,
        max_nodes: 1 << 16,
        max_crs_bytes: 64,
    };
    // Most random inputs fail at the magic; also try them after the magic.
    let mut framed = b"SLVC\x01".to_vec();
    framed.extend_from_slice(data);
    for bytes in [data, &framed[..]] {
        if let Ok(code) = ChainCode::decompress(bytes, &limits) {
            check_accepted(&code, &limits);
        }
    }
});
