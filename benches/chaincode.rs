//! Chain code throughput in internodes per second (issue 4 target: decoding
//! at least 5 million per second at r = 5).
//!
//! `cargo bench --bench chaincode`. Trees come from the test generator
//! (`tests/chaincode_support`): smooth, ~3,000 internodes; and, as a stand-in
//! for skeletons reconstructed from point clouds (wiggly, bushy), a random
//! skeleton of 3,000 nodes.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use silva::encode::chaincode::{
    ChainCode, ChainOptions, Limits, Prediction, RadiusLayout, Resolution, Voxelisation, decode,
    decode_compressed, encode,
};

#[allow(dead_code)]
#[path = "../tests/chaincode_support/mod.rs"]
mod chaincode_support;

fn chaincode(c: &mut Criterion) {
    let tree = chaincode_support::botanical_tree(1, 3000);
    let internodes = tree.internode_count() as u64;
    let limits = Limits::default();
    for r in [3.0f32, 5.0, 10.0] {
        let opts = ChainOptions {
            resolution: Resolution::PerInternode(r),
            ..ChainOptions::default()
        };
        let code = encode(&tree, &opts).expect("encodable");
        let packed = code.compress();
        let plain = code.to_bytes();
        let mut group = c.benchmark_group(format!("chaincode_r{r}"));
        group.throughput(Throughput::Elements(internodes));
        group.bench_function("decode", |b| {
            b.iter(|| decode(black_box(&code)).expect("valid"))
        });
        group.bench_function("decompress", |b| {
            b.iter(|| ChainCode::decompress(black_box(&packed), &limits).expect("valid"))
        });
        group.bench_function("decompress+decode", |b| {
            b.iter(|| {
                let code = ChainCode::decompress(black_box(&packed), &limits).expect("valid");
                decode(&code).expect("valid")
            })
        });
        group.bench_function("decode_compressed", |b| {
            b.iter(|| decode_compressed(black_box(&packed), &limits).expect("valid"))
        });
        group.bench_function("from_bytes+decode", |b| {
            b.iter(|| {
                let code = ChainCode::from_bytes(black_box(&plain), &limits).expect("valid");
                decode(&code).expect("valid")
            })
        });
        // The default tries every step prediction; the cost of that
        // against one fixed prediction.
        group.bench_function("encode", |b| {
            b.iter(|| encode(black_box(&tree), &opts).expect("encodable"))
        });
        let differential = ChainOptions {
            prediction: Some(Prediction::DIFFERENTIAL),
            ..opts
        };
        group.bench_function("encode differential only", |b| {
            b.iter(|| encode(black_box(&tree), &differential).expect("encodable"))
        });
        group.bench_function("compress", |b| b.iter(|| black_box(&code).compress()));
        group.finish();
    }
    let tree = chaincode_support::random_skeleton(7, 3000);
    let code = encode(&tree, &ChainOptions::default()).expect("encodable");
    let packed = code.compress();
    let packed_v1 = code.compress_split_v1().expect("the encoder's move order");
    let mut group = c.benchmark_group("chaincode_random_r5");
    group.throughput(Throughput::Elements(tree.internode_count() as u64));
    // The current form (kind 3) and the version-1 split form (kind 2) in one
    // run, so that a loaded machine affects both alike.
    for (name, bytes) in [
        ("decompress+decode", &packed),
        ("v1 decompress+decode", &packed_v1),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let code = ChainCode::decompress(black_box(bytes), &limits).expect("valid");
                decode(&code).expect("valid")
            })
        });
    }
    group.bench_function("decode_compressed", |b| {
        b.iter(|| decode_compressed(black_box(&packed), &limits).expect("valid"))
    });
    // What an ingest pays for a bushy tree: every step prediction tried,
    // then the smallest byte form chosen.
    group.bench_function("encode", |b| {
        b.iter(|| encode(black_box(&tree), &ChainOptions::default()).expect("encodable"))
    });
    // The same with each node's voxel chosen greedily instead of planned
    // for the whole tree: what the plan costs.
    let greedy = ChainOptions {
        voxelisation: Voxelisation::Predictive,
        ..ChainOptions::default()
    };
    group.bench_function("encode greedy voxels", |b| {
        b.iter(|| encode(black_box(&tree), &greedy).expect("encodable"))
    });
    group.bench_function("compress", |b| b.iter(|| black_box(&code).compress()));
    // The default picks a damped prediction for this skeleton; the same
    // skeleton with the paper's, to see what the scaling costs a decoder.
    let differential = ChainOptions {
        prediction: Some(Prediction::DIFFERENTIAL),
        ..ChainOptions::default()
    };
    let paper = encode(&tree, &differential).expect("encodable").compress();
    group.bench_function("decode_compressed differential", |b| {
        b.iter(|| decode_compressed(black_box(&paper), &limits).expect("valid"))
    });
    // Decompressing each radius layout of kind 3 (the same code), one run.
    for layout in RadiusLayout::ALL {
        let bytes = code
            .compress_split_with(layout)
            .expect("the encoder's move order");
        group.bench_function(format!("decompress radii {layout:?}"), |b| {
            b.iter(|| ChainCode::decompress(black_box(&bytes), &limits).expect("valid"))
        });
    }
    group.finish();
}

criterion_group!(benches, chaincode);
criterion_main!(benches);
