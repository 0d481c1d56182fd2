//! Fuzzes the LsJSON reader (parse, bounded rule expansion, turtle): any
//! input must give a skeleton or a typed error, never a panic, a hang or an
//! unbounded allocation. An accepted document must print and parse back to
//! itself, and decode to the same skeleton.
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
    let Ok(ls) = LsJson::parse(text, &limits) else {
        return;
    };
    let printed = ls.to_json();
    let reparsed = LsJson::parse(&printed, &Limits::default()).expect("printed LsJSON parses");
    assert!(reparsed == ls, "print/parse round trip: {printed}");
    let decoded = decode(&ls, &limits);
    let again = decode(&reparsed, &limits);
    match (&decoded, &again) {
        (Ok(a), Ok(b)) => assert_eq!(a, b, "the reprinted document decodes alike"),
        (Err(_), Err(_)) => {}
        _ => panic!("decoding differs after printing: {decoded:?} vs {again:?}"),
    }
});
