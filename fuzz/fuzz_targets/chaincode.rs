//! Fuzzes the plain chain code decoder (`ChainCode::from_bytes`: header,
//! 4-bit symbols, fixed-width radii, the symbol grammar), then the raw code
//! decoder and LOD reduction on whatever it accepts. Any input must give Ok
//! or a typed error, never a panic, a hang or an unbounded allocation; an
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
