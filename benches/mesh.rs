//! Mesh, GLB and CityJSON build times (issue 5 target: the LOD 3 GLB of a
//! 5,000-internode tree in under 20 ms), and a size table per LOD printed
//! before the measurements.
//!
//! Run: `CARGO_TARGET_DIR=/work/target cargo bench --bench mesh`

#[path = "../tests/mesh_support/mod.rs"]
mod mesh_support;

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use silva::cityjson::{self, TreeInfo};
use silva::mesh::{self, Lod, MeshFormat};
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, Skeleton};

fn trees() -> Vec<(String, Skeleton)> {
    let anchor = Anchor {
        origin: DVec3::new(84_512.3, 447_123.7, -0.4),
        crs: Some("EPSG:28992".into()),
    };
    let mut trees: Vec<(String, Skeleton)> = Species::ALL
        .iter()
        .map(|&s| {
            (
                s.name().to_string(),
                generate(&TreeParams::preset(s), 1, anchor.clone()),
            )
        })
        .collect();
    trees.push(("random".into(), mesh_support::random_tree(1, 5000)));
    trees
}

/// Prints triangles and bytes per LOD: the figures docs/lod.md reports.
fn print_sizes(trees: &[(String, Skeleton)]) {
    println!(
        "tree       internodes  lod  triangles  vertices  glb_bytes  obj_bytes  cityjson_bytes"
    );
    for (name, tree) in trees {
        for f in cityjson::lod_figures(tree) {
            println!(
                "{name:<10} {:>10}  {:>3}  {:>9}  {:>8}  {:>9}  {:>9}  {:>14}",
                tree.internode_count(),
                f.lod.level(),
                f.triangles,
                f.vertices,
                f.glb_bytes,
                f.obj_bytes,
                f.cityjson_bytes
            );
        }
    }
}

fn bench(c: &mut Criterion) {
    let trees = trees();
    print_sizes(&trees);
    let mut group = c.benchmark_group("glb_lod3");
    for (name, tree) in &trees {
        let id = format!("{name}_{}_internodes", tree.internode_count());
        group.bench_function(id, |b| {
            b.iter(|| {
                let m = mesh::build_mesh(black_box(tree), Lod::L3);
                MeshFormat::Glb.encode(&m, tree.anchor(), tree.anchor().origin)
            })
        });
    }
    group.finish();
    let (name, tree) = &trees[trees.len() - 1];
    c.bench_function(&format!("mesh_lod3/{name}"), |b| {
        b.iter(|| mesh::build_mesh(black_box(tree), Lod::L3))
    });
    c.bench_function(&format!("cityjson_all_lods/{name}"), |b| {
        b.iter(|| cityjson::city_json(&TreeInfo::new("t", black_box(tree)), &Lod::ALL).to_string())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
