//! Fuzzes `silva decode`'s content sniffing (`silva::encode::decode_stored`):
//! chain code magic, silva skeleton JSON or PLY, or LsJSON, each with its reader's
//! default limits. Any input must give a skeleton or a typed error, never a
//! panic, a hang or an unbounded allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(skeleton) = silva::encode::decode_stored(data) {
        // Whatever the form, the skeleton is one the other stages can use.
        assert!(skeleton.anchor().origin.is_finite());
        for node in skeleton.nodes() {
            assert!(node.position.is_finite(), "{:?}", node.position);
            assert!(node.radius_m.is_finite() && node.radius_m >= 0.0, "{}", node.radius_m);
        }
    }
});
