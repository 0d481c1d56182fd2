//! GLB output: container layout and accessors checked here, and every file
//! validated by the Khronos glTF validator through tests/gltf/validate.mjs.
//!
//! The validator needs Node.js and `npm ci` in tests/gltf. When either is
//! missing the validator test fails if the `CI` environment variable is set,
//! and otherwise prints a loud SKIP warning.

mod mesh_support;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DVec3, Vec3};
use mesh_support::random_tree;
use serde_json::Value;
use silva::mesh::{self, Lod};
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, NodeId, Skeleton};

/// The GLB's JSON document and binary chunk, checking the container.
fn parse_glb(bytes: &[u8]) -> (Value, Vec<u8>) {
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(word(4), 2);
    assert_eq!(word(8), bytes.len());
    assert_eq!(bytes.len() % 4, 0);
    let json_len = word(12);
    assert_eq!(json_len % 4, 0);
    assert_eq!(&bytes[16..20], b"JSON");
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    if bin_at == bytes.len() {
        return (json, Vec::new());
    }
    let bin_len = word(bin_at);
    assert_eq!(bin_len % 4, 0);
    assert_eq!(&bytes[bin_at + 4..bin_at + 8], b"BIN\0");
    assert_eq!(bin_at + 8 + bin_len, bytes.len());
    (json, bytes[bin_at + 8..].to_vec())
}

#[test]
fn glb_accessors_match_the_mesh() {
    let tree = random_tree(11, 600);
    let m = mesh::build_mesh(&tree, Lod::L3);
    let local = DVec3::new(84_000.0, 447_000.0, 0.0);
    let (json, bin) = parse_glb(&mesh::glb(&m, tree.anchor(), local));
    let acc = &json["accessors"];
    assert_eq!(acc[0]["count"], m.vertex_count());
    assert_eq!(acc[2]["count"], m.indices.len());
    // Fewer than 65,536 vertices: 16-bit indices.
    assert!(m.vertex_count() < 65_536);
    assert_eq!(acc[2]["componentType"], 5123);
    for view in json["bufferViews"].as_array().unwrap() {
        assert_eq!(view["byteOffset"].as_u64().unwrap() % 4, 0);
    }
    // min/max are the y-up bounds of exactly the stored f32 positions.
    let (lo, hi) = m.bounds();
    let y_up = |v: Vec3| [v.x, v.z, -v.y];
    let (lo, hi) = (y_up(lo), y_up(hi));
    let (min, max) = (&acc[0]["min"], &acc[0]["max"]);
    for k in 0..3 {
        assert_eq!(min[k].as_f64().unwrap() as f32, lo[k].min(hi[k]));
        assert_eq!(max[k].as_f64().unwrap() as f32, lo[k].max(hi[k]));
    }
    // The first position in the buffer is the first mesh vertex, y-up.
    let x = f32::from_le_bytes(bin[..4].try_into().unwrap());
    let y = f32::from_le_bytes(bin[4..8].try_into().unwrap());
    assert_eq!((x, y), (m.positions[0].x, m.positions[0].z));
    // Georeference: translation = anchor - local origin, in y-up axes.
    let t = &json["nodes"][0]["translation"];
    let shift = tree.anchor().origin - local;
    assert!((t[0].as_f64().unwrap() - shift.x).abs() < 1e-9);
    assert!((t[1].as_f64().unwrap() - shift.z).abs() < 1e-9);
    assert!((t[2].as_f64().unwrap() + shift.y).abs() < 1e-9);
    assert_eq!(json["nodes"][0]["extras"]["crs"], "EPSG:28992");
}

#[test]
fn large_meshes_use_32_bit_indices() {
    let tree = random_tree(12, 12_000);
    let m = mesh::build_mesh(&tree, Lod::L3);
    assert!(
        m.vertex_count() > 65_535,
        "need a big mesh: {}",
        m.vertex_count()
    );
    let (json, _) = parse_glb(&mesh::glb(&m, tree.anchor(), tree.anchor().origin));
    assert_eq!(json["accessors"][2]["componentType"], 5125);
}

#[test]
fn empty_mesh_is_a_node_without_geometry() {
    let root_only = Skeleton::new(Anchor::at(DVec3::ZERO), 0.1);
    let m = mesh::build_mesh(&root_only, Lod::L3);
    let (json, bin) = parse_glb(&mesh::glb(&m, root_only.anchor(), DVec3::ZERO));
    assert!(bin.is_empty());
    assert!(json.get("meshes").is_none());
    assert!(json["nodes"][0].get("mesh").is_none());
}

/// The GLB files the validator checks: several random trees at every LOD,
/// one with 32-bit indices, the Weber–Penn species presets, a tiny fork,
/// and a skeleton without internodes.
fn sample_glbs(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut write = |name: String, bytes: Vec<u8>| {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        files.push(path);
    };
    for (seed, size) in [(1, 400), (2, 1500), (3, 6000)] {
        let tree = random_tree(seed, size);
        for lod in Lod::ALL {
            let m = mesh::build_mesh(&tree, lod);
            let glb = mesh::glb(&m, tree.anchor(), tree.anchor().origin);
            write(format!("tree{seed}_lod{}.glb", lod.level()), glb);
        }
        // Absolute georeference in the node translation.
        let m = mesh::build_mesh(&tree, Lod::L1);
        write(
            format!("tree{seed}_absolute.glb"),
            mesh::glb(&m, tree.anchor(), DVec3::ZERO),
        );
    }
    for species in Species::ALL {
        let tree = generate(&TreeParams::preset(species), 2, Anchor::at(DVec3::ZERO));
        for lod in [Lod::L0, Lod::L3] {
            let m = mesh::build_mesh(&tree, lod);
            let glb = mesh::glb(&m, tree.anchor(), tree.anchor().origin);
            write(format!("{species}_lod{}.glb", lod.level()), glb);
        }
    }
    let mut fork = Skeleton::new(Anchor::at(DVec3::new(155_000.0, 463_000.0, 0.0)), 0.1);
    let a = fork.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 1.0), 0.08);
    fork.add_child(a, Vec3::new(0.0, 0.0, 2.0), 0.0);
    fork.add_child(a, Vec3::new(0.5, 0.0, 1.5), 0.0);
    let m = mesh::build_mesh(&fork, Lod::L3);
    write("fork.glb".into(), mesh::glb(&m, fork.anchor(), DVec3::ZERO));
    let root_only = Skeleton::new(Anchor::at(DVec3::ZERO), 0.1);
    let m = mesh::build_mesh(&root_only, Lod::L3);
    write(
        "empty.glb".into(),
        mesh::glb(&m, root_only.anchor(), DVec3::ZERO),
    );
    files
}

#[test]
fn khronos_validator_reports_no_errors() {
    let gltf_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf");
    let node_ok = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    let package_ok = gltf_dir
        .join("node_modules/gltf-validator/package.json")
        .exists();
    if !(node_ok && package_ok) {
        let why = format!(
            "glTF validator unavailable (node found: {node_ok}, gltf-validator installed: \
             {package_ok}); install with `cd tests/gltf && npm ci`"
        );
        if std::env::var_os("CI").is_some() {
            panic!("{why}");
        }
        // Past the harness's capture, which would hide an `eprintln!`.
        let _ = writeln!(std::io::stderr().lock(), "\n*** SKIP: {why} ***\n");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let files = sample_glbs(dir.path());
    let out = Command::new("node")
        .arg(gltf_dir.join("validate.mjs"))
        .args(&files)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    eprintln!("{report}");
    assert!(
        out.status.success(),
        "glTF validator found errors:\n{report}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        report.matches(": 0 errors").count(),
        files.len(),
        "{report}"
    );
}
