//! `silva encode`, `decode` and `export` end to end on a synthetic tree:
//! every stored form decodes back within its stated bound, outputs are
//! written in the requested formats, and hostile inputs fail with one line.

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

    silva()
        .current_dir(d)
        .args(["decode", "l.json", "--skeleton", "from_ls.json"])
        .succeeds();
    let from_ls =
        Skeleton::from_json(&std::fs::read_to_string(d.join("from_ls.json")).unwrap()).unwrap();
    assert!(max_error_m(&tree, &from_ls) <= 0.001 + 1e-5);

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
    let cases: [(&str, &[u8]); 4] = [
        ("garbage.json", b"not json at all"),
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
