//! `silva encode`, `decode` and `export` end to end on a synthetic tree:
//! every stored form decodes back within its stated bound, outputs are
//! written in the requested formats, a skeleton PLY (silva's or AdTree's)
//! is read like the skeleton JSON, and hostile inputs fail with one line.

mod cli_support;

use glam::DVec3;
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, Skeleton};

use cli_support::{Run, silva};

fn truth() -> Skeleton {
    let anchor = Anchor {
        origin: DVec3::new(155_000.25, 463_000.5, 2.0),
        crs: Some("EPSG:28992".into()),
    };
    generate(&TreeParams::preset(Species::Pine), 11, anchor)
}

fn max_error_m(a: &Skeleton, b: &Skeleton) -> f64 {
    assert_eq!(a.len(), b.len());
    a.ids()
        .zip(b.ids())
        .map(|(x, y)| (a.absolute_position(x) - b.absolute_position(y)).length())
        .fold(0.0, f64::max)
}

/// `silva decode INPUT --skeleton INPUT.json` in `dir`, read back.
fn decoded(dir: &std::path::Path, input: &str) -> Skeleton {
    let out = format!("{input}.json");
    silva()
        .current_dir(dir)
        .args(["decode", input, "--skeleton", &out])
        .succeeds();
    Skeleton::from_json(&std::fs::read_to_string(dir.join(out)).unwrap()).unwrap()
}

#[test]
fn encode_decode_export_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tree = truth().canonical();
    std::fs::write(d.join("s.json"), tree.to_json()).unwrap();
    silva()
        .current_dir(d)
        .args([
            "encode",
            "s.json",
            "--lsystem",
            "l.json",
            "--chaincode",
            "c.bin",
        ])
        .succeeds();

    let from_ls = decoded(d, "l.json");
    assert!(max_error_m(&tree, &from_ls) <= 0.001 + 1e-5);

    // The chain code at its default r = 5: every node within √3·d/2 of the
    // original, d being the mean internode length over 5 (Eq. 2).
    let full_cc = decoded(d, "c.bin");
    let lengths: Vec<f64> = tree
        .internodes()
        .map(|(p, c)| f64::from(tree.position(p).distance(tree.position(c))))
        .filter(|&l| l > 0.0)
        .collect();
    let voxel_m = lengths.iter().sum::<f64>() / lengths.len() as f64 / 5.0;
    let bound_m = 3f64.sqrt() / 2.0 * voxel_m;
    assert!(max_error_m(&tree, &full_cc.canonical()) <= bound_m + 1e-5);

    silva()
        .current_dir(d)
        .args([
            "decode",
            "c.bin",
            "--skeleton",
            "from_cc.json",
            "--mesh",
            "m.glb",
            "--lod",
            "1",
        ])
        .succeeds();
    let from_cc =
        Skeleton::from_json(&std::fs::read_to_string(d.join("from_cc.json")).unwrap()).unwrap();
    assert!(from_cc.internode_count() > 0);
    assert_eq!(&std::fs::read(d.join("m.glb")).unwrap()[..4], b"glTF");

    silva()
        .current_dir(d)
        .args([
            "export",
            "l.json",
            "--mesh",
            "m.obj",
            "--cityjson",
            "t.city.json",
            "--cylinders",
            "t.csv",
            "--skeleton",
            "t.ply",
        ])
        .succeeds();
    let city: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("t.city.json")).unwrap()).unwrap();
    assert_eq!(city["type"], "CityJSON");
    let csv = std::fs::read_to_string(d.join("t.csv")).unwrap();
    assert_eq!(csv.lines().count(), tree.internode_count() + 1);
    let ply = Skeleton::from_ply(&std::fs::read(d.join("t.ply")).unwrap()).unwrap();
    assert!(max_error_m(&from_ls, &ply.canonical()) <= 1e-5);
    assert!(
        std::fs::read_to_string(d.join("m.obj"))
            .unwrap()
            .contains("\nvn ")
    );
}

#[test]
fn hostile_inputs_fail_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: [(&str, &[u8]); 5] = [
        ("garbage.json", b"not json at all"),
        (
            "points.ply",
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
              property float z\nend_header\n0 0 0\n1 1 1\n",
        ),
        ("trunc.bin", b"SLVC\x01\x01\xff\xff"),
        (
            "bomb.json",
            br#"{"recursions":1000000,"axiom":"A","rules":{"A":"AA"}}"#,
        ),
        ("binary.bin", &[0xff, 0xfe, 0x00, 0x13]),
    ];
    for (name, bytes) in cases {
        std::fs::write(d.join(name), bytes).unwrap();
        silva()
            .current_dir(d)
            .args(["decode", name, "--skeleton", "x.json"])
            .fails_with_one_line();
    }
}

#[test]
fn a_skeleton_ply_encodes_as_its_json_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.json"), truth().canonical().to_json()).unwrap();
    silva()
        .current_dir(d)
        .args(["export", "s.json", "--skeleton", "s.ply"])
        .succeeds();
    for input in ["s.json", "s.ply"] {
        silva()
            .current_dir(d)
            .args(["encode", input, "--lsystem"])
            .arg(format!("{input}.ls.json"))
            .arg("--chaincode")
            .arg(format!("{input}.bin"))
            .succeeds();
    }
    let read = |name: &str| std::fs::read(d.join(name)).unwrap();
    assert_eq!(read("s.ply.ls.json"), read("s.json.ls.json"));
    assert_eq!(read("s.ply.bin"), read("s.json.bin"));
}

#[test]
fn an_adtree_skeleton_ply_is_encoded_with_estimated_radii_and_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // lsystem-from-adtree-skeletons, Fig. 3.11: ascii, no radius, edges
    // child to parent.
    let adtree = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                  property float y\nproperty float z\nelement face 0\n\
                  property list uchar int vertex_index\nelement edge 2\n\
                  property int vertex1\nproperty int vertex2\nend_header\n\
                  127395.5 401149.75 16.5\n127395.5 401149.75 13.0\n\
                  127396.0 401149.75 14.5\n0 2\n2 1\n";
    std::fs::write(d.join("adtree.ply"), adtree).unwrap();
    let out = silva()
        .current_dir(d)
        .args(["encode", "adtree.ply", "--lsystem", "l.json"])
        .succeeds();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("every radius is 0"), "{stderr}");
    assert!(
        stderr.contains("the radii follow the pipe model"),
        "{stderr}"
    );
    silva()
        .current_dir(d)
        .args(["decode", "l.json", "--skeleton", "back.json"])
        .succeeds();
    let back = Skeleton::from_json(&std::fs::read_to_string(d.join("back.json")).unwrap()).unwrap();
    assert_eq!(back.len(), 3);
    // The estimated radii survive the L-system: positive, never thicker
    // upwards.
    let (root, tip) = (
        back.radius(silva::NodeId::ROOT),
        back.radius(back.ids().last().unwrap()),
    );
    assert!(root >= tip && tip > 0.0, "root {root}, tip {tip}");
    let base = back.absolute_position(silva::NodeId::ROOT);
    assert!((base - DVec3::new(127_395.5, 401_149.75, 13.0)).length() < 1e-3);
}
