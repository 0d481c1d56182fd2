//! LsJSON: round trips, error bound, sizes, generalisation, hostile input.

mod lsystem_common;

use std::io::Write as _;

use lsystem_common::{max_errors, random_tree, synthetic_tree};
use silva::encode::lsystem::{self, Limits, LsJson, LsOptions};

fn gzip_len(text: &str) -> usize {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    enc.write_all(text.as_bytes()).unwrap();
    enc.finish().unwrap().len()
}

fn round_trip(s: &silva::Skeleton, opts: &LsOptions) -> (LsJson, silva::Skeleton) {
    let ls = lsystem::encode(s, opts);
    let text = ls.to_json();
    let parsed = LsJson::parse(&text, &Limits::default()).unwrap();
    assert_eq!(parsed, ls, "to_json/parse round trip");
    let back = lsystem::decode(&parsed, &Limits::default()).unwrap();
    (ls, back)
}

#[test]
fn synthetic_sizes() {
    for seed in 0..3 {
        let s = synthetic_tree(seed, 2000);
        let (ls, back) = round_trip(&s, &LsOptions::default());
        let (err, rerr) = max_errors(&s, &back);
        let text = ls.to_json();
        println!(
            "seed {seed}: {} internodes, {} B raw, {} B gzip, max {err:.6} m, radius {rerr:.6}, {:?}",
            s.internode_count(),
            text.len(),
            gzip_len(&text),
            ls.error()
        );
        println!("{}", &text[..600.min(text.len())]);
        assert!(err <= 0.001);
    }
}

#[test]
#[ignore]
fn dump_synthetic() {
    let s = synthetic_tree(0, 2000);
    let ls = lsystem::encode(&s, &LsOptions::default());
    std::fs::write("/tmp/ls_dump.json", ls.to_json()).unwrap();
}
