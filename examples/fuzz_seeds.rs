//! Writes a handful of small, valid stored forms of synthetic skeletons as
//! seed corpora for the decoder fuzz targets (`fuzz/README.md`):
//! `cargo run --example fuzz_seeds -- fuzz/corpus`.
//!
//! Per skeleton: the plain chain code (`chaincode/`), both compressed kinds
//! (`chaincode_stream/`), LsJSON with and without tip rules (`lsjson/`), the
//! skeleton PLY as silva and as AdTree write it (`skeleton_ply/`), and one of
//! each file form for the content sniffing (`decode_stored/`).
//! And small synthetic scans for the whole reconstruction (`reconstruct/`,
//! in that target's input form: a pipeline byte, then `i16` millimetres).

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use silva::encode::chaincode::{self, ChainCode, ChainOptions, Prediction};
use silva::encode::lsystem::{self, LsOptions};
use silva::synth::{
    AlsOptions, Species, TlsOptions, TreeParams, generate, simulate_als, simulate_tls,
};
use silva::{Anchor, NodeId, Skeleton};

/// A fork with a thin lateral, as in the chain code module's example.
fn fork() -> Skeleton {
    let mut tree = Skeleton::new(Anchor::at(DVec3::new(155_000.0, 463_000.0, 0.0)), 0.30);
    let a = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.25);
    tree.add_child(a, Vec3::new(0.1, 0.0, 2.0), 0.20);
    tree.add_child(a, Vec3::new(0.8, 0.0, 1.6), 0.05);
    tree
}

/// A three-way fork and a zero-length internode, with a CRS.
fn trifurcation() -> Skeleton {
    let mut anchor = Anchor::at(DVec3::new(85_000.0, 446_000.0, 2.5));
    anchor.crs = Some("EPSG:28992".into());
    let mut tree = Skeleton::new(anchor, 0.2);
    let a = tree.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.5), 0.15);
    for (x, y) in [(0.6, 0.0), (-0.3, 0.5), (-0.3, -0.5)] {
        let b = tree.add_child(a, Vec3::new(x, y, 2.2), 0.06);
        tree.add_child(b, Vec3::new(x * 1.5, y * 1.5, 2.9), 0.03);
    }
    let tip = tree.add_child(a, Vec3::new(0.0, 0.0, 1.5), 0.1);
    tree.add_child(tip, Vec3::new(0.0, 0.1, 2.5), 0.05);
    tree
}

/// A Weber–Penn birch without its laterals thinner than `threshold_m`: a
/// real tree's irregular geometry in a few dozen internodes.
fn pruned_birch(seed: u64, threshold_m: f32) -> Skeleton {
    let anchor = Anchor::at(DVec3::new(120_000.0, 480_000.0, 1.0));
    let tree = generate(&TreeParams::preset(Species::Birch), seed, anchor);
    chaincode::prune_like_lod(&tree, threshold_m)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(dir).expect("corpus directory");
    std::fs::write(dir.join(name), bytes).expect("seed file");
}

fn main() {
    let root = PathBuf::from(std::env::args().nth(1).unwrap_or("fuzz/corpus".into()));
    let trees = [
        ("fork", fork()),
        ("trifurcation", trifurcation()),
        ("birch", pruned_birch(1, 0.06)),
        ("birch-dense", pruned_birch(2, 0.03)),
    ];
    for (name, tree) in &trees {
        let code = chaincode::encode(tree, &ChainOptions::default()).expect("encodable");
        let plain = code.to_bytes();
        let split = code.compress_split().expect("the encoder's move order");
        let split_v1 = code.compress_split_v1().expect("the encoder's move order");
        let single = code.compress_single_string();
        let lod = chaincode::reduce_lod(&code, 0.1).to_bytes();
        write(&root.join("chaincode"), &format!("{name}.bin"), &plain);
        write(&root.join("chaincode"), &format!("{name}-lod.bin"), &lod);
        write(
            &root.join("chaincode_stream"),
            &format!("{name}.k2"),
            &split_v1,
        );
        write(
            &root.join("chaincode_stream"),
            &format!("{name}.k3"),
            &split,
        );
        write(
            &root.join("chaincode_stream"),
            &format!("{name}.k1"),
            &single,
        );
        for layout in chaincode::RadiusLayout::ALL {
            let bytes = code
                .compress_split_with(layout)
                .expect("the encoder's move order");
            let name = format!("{name}-radii{}.k3", layout.byte());
            write(&root.join("chaincode_stream"), &name, &bytes);
        }
        // Every step prediction weight, in the plain and the compressed form.
        for prediction in Prediction::ALL {
            let o = ChainOptions {
                prediction: Some(prediction),
                ..ChainOptions::default()
            };
            let code = chaincode::encode(tree, &o).expect("encodable");
            let w = prediction.quarters();
            write(
                &root.join("chaincode"),
                &format!("{name}-w{w}.bin"),
                &code.to_bytes(),
            );
            let name = format!("{name}-w{w}.k3");
            write(&root.join("chaincode_stream"), &name, &code.compress());
        }

        let ls = lsystem::encode(tree, &LsOptions::default()).to_json();
        let rules = LsOptions {
            generalise_tips: Some(2),
            tolerance_m: 0.01,
            ..LsOptions::default()
        };
        let ls_rules = lsystem::encode(tree, &rules).to_json();
        write(&root.join("lsjson"), &format!("{name}.json"), ls.as_bytes());
        write(
            &root.join("lsjson"),
            &format!("{name}-rules.json"),
            ls_rules.as_bytes(),
        );

        let stored = root.join("decode_stored");
        write(&stored, &format!("{name}.cc"), &split);
        write(&stored, &format!("{name}.ls.json"), ls.as_bytes());
        write(
            &stored,
            &format!("{name}.skeleton.json"),
            tree.to_json().as_bytes(),
        );
        let ply = tree.to_ply();
        let adtree = adtree_ply(tree);
        write(&stored, &format!("{name}.ply"), &ply);
        write(&root.join("skeleton_ply"), &format!("{name}.ply"), &ply);
        write(
            &root.join("skeleton_ply"),
            &format!("{name}-adtree.ply"),
            adtree.as_bytes(),
        );
        let sizes = [plain.len(), split.len(), ls.len(), ls_rules.len()];
        println!(
            "{name}: {} nodes, plain/compressed/lsjson/lsjson-rules bytes {sizes:?}",
            tree.len()
        );
    }
    for (name, bytes) in scan_seeds() {
        write(&root.join("reconstruct"), &name, &bytes);
    }
    // The decoders must accept what they are seeded with.
    for (_, tree) in &trees {
        let code = chaincode::encode(tree, &ChainOptions::default()).expect("encodable");
        let back = ChainCode::decompress(&code.compress(), &chaincode::Limits::default());
        assert_eq!(back.as_ref(), Ok(&code));
        assert!(Skeleton::from_ply(&tree.to_ply()).is_ok());
        assert!(Skeleton::from_ply(adtree_ply(tree).as_bytes()).is_ok());
    }
}

/// `tree` as the augmented AdTree writes a skeleton (lsystem-from-adtree-
/// skeletons, Fig. 3.11): ascii, `float x y z`, an empty face element, no
/// radius, each edge child to parent.
fn adtree_ply(tree: &Skeleton) -> String {
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face 0\nproperty list uchar int vertex_index\n\
         element edge {}\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        tree.len(),
        tree.internode_count()
    );
    for id in tree.ids() {
        let p = tree.absolute_position(id);
        ply += &format!("{:.4} {:.4} {:.4}\n", p.x, p.y, p.z);
    }
    for (parent, child) in tree.internodes() {
        ply += &format!("{} {}\n", child.index(), parent.index());
    }
    ply
}

/// Synthetic scans as inputs of the `reconstruct` target: a byte for the
/// pipeline (0 auto, 1 dense, 2 airborne), then per point three
/// little-endian `i16` millimetres relative to the tree's anchor (every
/// `n`-th point, at most 3,000).
fn scan_seeds() -> Vec<(String, Vec<u8>)> {
    let tree = |species, seed| generate(&TreeParams::preset(species), seed, Anchor::default());
    let sparse_tls = TlsOptions {
        points_per_m2: 20.0,
        ..TlsOptions::default()
    };
    let scans = [
        (
            "birch-als",
            2u8,
            simulate_als(&tree(Species::Birch, 2), &AlsOptions::default(), 2),
        ),
        (
            "pine-als",
            0,
            simulate_als(&tree(Species::Pine, 4), &AlsOptions::default(), 4),
        ),
        (
            "poplar-tls",
            1,
            simulate_tls(&tree(Species::Poplar, 3), &sparse_tls, 3),
        ),
        (
            "oak-tls",
            0,
            simulate_tls(&tree(Species::Oak, 1), &sparse_tls, 1),
        ),
    ];
    scans
        .into_iter()
        .map(|(name, mode, cloud)| {
            let step = cloud.len().div_ceil(3_000).max(1);
            let mut bytes = vec![mode];
            for p in cloud.points.iter().step_by(step).take(3_000) {
                for v in [p.x, p.y, p.z] {
                    let mm = (v * 1000.0).round().clamp(-32_768.0, 32_767.0) as i16;
                    bytes.extend_from_slice(&mm.to_le_bytes());
                }
            }
            println!("{name}: {} points", (bytes.len() - 1) / 6);
            (format!("{name}.bin"), bytes)
        })
        .collect()
}
