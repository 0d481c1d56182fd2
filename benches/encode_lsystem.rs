//! LsJSON encode and decode of a 2,000-internode Weber-Penn birch.
//!
//! `CARGO_TARGET_DIR=/work/target cargo bench --bench encode_lsystem`
//! Prints the document's raw and gzip size and its errors once, then times
//! `encode` (closed-loop writer plus its verifying decode), `to_json`,
//! `parse` and `decode`.

use std::hint::black_box;
use std::io::Write as _;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use silva::encode::lsystem::{Limits, LsJson, LsOptions, decode, encode};
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, Skeleton};

/// The first 2,001 nodes (canonical order) of a generated birch: a
/// connected tree of exactly 2,000 internodes.
fn skeleton() -> Skeleton {
    let anchor = Anchor::at(DVec3::new(155_000.0, 463_000.0, 0.0));
    let tree = generate(&TreeParams::preset(Species::Birch), 1, anchor).canonical();
    let keep: Vec<bool> = (0..tree.len()).map(|i| i <= 2000).collect();
    tree.retain(&keep)
}

fn gzip_len(text: &str) -> usize {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    enc.write_all(text.as_bytes()).expect("in-memory write");
    enc.finish().expect("in-memory gzip").len()
}

fn bench(c: &mut Criterion) {
    let tree = skeleton();
    let opts = LsOptions::default();
    let limits = Limits::default();
    let ls = encode(&tree, &opts);
    let text = ls.to_json();
    let e = ls.error();
    eprintln!(
        "{} internodes: {} B raw, {} B gzip, max error {} m, mean {} m",
        tree.internode_count(),
        text.len(),
        gzip_len(&text),
        e.max_m,
        e.mean_m
    );
    let parsed = LsJson::parse(&text, &limits).expect("own document parses");
    c.bench_function("lsjson_encode_2000", |b| {
        b.iter(|| encode(black_box(&tree), &opts))
    });
    c.bench_function("lsjson_to_json_2000", |b| {
        b.iter(|| black_box(&ls).to_json())
    });
    c.bench_function("lsjson_parse_2000", |b| {
        b.iter(|| LsJson::parse(black_box(&text), &limits))
    });
    c.bench_function("lsjson_decode_2000", |b| {
        b.iter(|| decode(black_box(&parsed), &limits))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
