//! Fuzzes the LsJSON reader (parse, rule expansion, turtle): any input must
//! give a skeleton or a typed error, never a panic, a hang or an unbounded
//! allocation.
//!
//! `cd fuzz && cargo +nightly fuzz run -s none lsjson corpus/lsjson -- -max_total_time=300 -rss_limit_mb=2048 -timeout=10`
#![no_main]

use libfuzzer_sys::fuzz_target;
use silva::encode::lsystem::{Limits, LsJson, decode};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Smaller limits keep each run fast; the limits themselves are tested.
    let limits = Limits {
        max_symbols: 100_000,
        max_nodes: 50_000,
        ..Limits::default()
    };
    if let Ok(ls) = LsJson::parse(text, &limits) {
        let _ = decode(&ls, &limits);
    }
});
