//! Fuzzes `silva decode`'s content sniffing (`silva::encode::decode_stored`):
//! chain code magic, silva skeleton JSON or LsJSON, each with its reader's
//! default limits. Any input must give a skeleton or a typed error, never a
//! panic, a hang or an unbounded allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(skeleton) = silva::encode::decode_stored(data) {
        assert!(!skeleton.is_empty(), "a skeleton has its root");
    }
});
