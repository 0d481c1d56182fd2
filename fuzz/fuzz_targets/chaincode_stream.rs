//! Fuzzes the compressed chain code decoder (`ChainCode::decompress`): the
//! single-string form (kind 1: BWT, MTF, interpolative code) and the split
//! streams (kind 2 of version 1, kind 3), then the checks of
//! `checks/chaincode.rs` on whatever it accepts. Any input must give Ok or a
//! typed error, never a panic, a hang or an unbounded allocation; an
//! accepted code must survive every byte form unchanged. The one-step
//! decoder (`decode_compressed`) must give exactly what decompressing and
//! then decoding gives: the same skeleton or the same error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use silva::encode::chaincode::{ChainCode, Limits, decode, decode_compressed};

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
        let two_steps = ChainCode::decompress(bytes, &limits);
        if let Ok(code) = &two_steps {
            check_accepted(code, &limits);
        }
        let two_steps = two_steps.and_then(|code| decode(&code));
        assert_eq!(decode_compressed(bytes, &limits), two_steps, "one-step decoder");
    }
});
