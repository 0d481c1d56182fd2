//! CityJSON 2.0 and CityJSONSeq: every document and stream validates with
//! zero errors (and zero warnings) with cjval, and carries what issue 5 asks.

mod mesh_support;

use cjval::CJValidator;
use glam::{DVec3, Vec3};
use mesh_support::random_tree;
use serde_json::{Map, Value, json};
use silva::cityjson::{self, CityJsonError, TreeInfo};
use silva::mesh::{self, Lod};
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, NodeId, Skeleton};

/// Every check's failures, errors and warnings alike, as readable lines.
fn problems(validator: &CJValidator) -> Vec<String> {
    validator
        .validate()
        .iter()
        .filter(|(_, summary)| summary.has_errors())
        .map(|(check, summary)| {
            let kind = if summary.is_warning() {
                "warning"
            } else {
                "error"
            };
            let first: Vec<_> = summary.get_errors().iter().take(3).collect();
            format!("{kind} {check}: {first:?}")
        })
        .collect()
}

fn assert_valid(document: &str) {
    let validator = CJValidator::from_str(document);
    assert!(validator.is_valid(), "{:?}", problems(&validator));
    assert_eq!(problems(&validator), Vec::<String>::new());
}

/// Validates a CityJSONSeq the way `cjval` does: header first, then each
/// feature against it.
fn assert_valid_seq(lines: &[String]) {
    let mut validator = CJValidator::from_str(&lines[0]);
    assert!(validator.is_cityjson() && validator.is_empty_cityjson());
    assert_eq!(problems(&validator), Vec::<String>::new(), "header");
    for (k, line) in lines[1..].iter().enumerate() {
        validator.from_str_cjfeature(line).unwrap();
        assert!(
            validator.is_valid(),
            "feature {k}: {:?}",
            problems(&validator)
        );
        assert_eq!(problems(&validator), Vec::<String>::new(), "feature {k}");
    }
}

fn metrics() -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("height".into(), json!(14.25));
    m.insert("silva:internodes".into(), json!(800));
    m.insert("silva:pointCoverage".into(), json!(0.93));
    m
}

#[test]
fn single_tree_documents_validate_at_every_lod() {
    for seed in [1, 4] {
        let tree = random_tree(seed, 800);
        let mut info = TreeInfo::new(format!("tree-{seed}"), &tree);
        info.species = Some("Tilia × europaea".into());
        info.attributes = metrics();
        for lods in [&Lod::ALL[..], &[Lod::L2], &[]] {
            let doc = cityjson::city_json(&info, lods);
            assert_valid(&doc.to_string());
        }
    }
}

#[test]
fn weber_penn_trees_validate() {
    let anchor = Anchor {
        origin: DVec3::new(155_000.0, 463_000.0, 0.0),
        crs: Some("EPSG:28992".into()),
    };
    for species in [Species::Birch, Species::Pine] {
        let tree = generate(&TreeParams::preset(species), 1, anchor.clone());
        let mut info = TreeInfo::new(species.name(), &tree);
        info.species = Some(species.name().into());
        assert_valid(&cityjson::city_json(&info, &[Lod::L0, Lod::L3]).to_string());
    }
}

#[test]
fn document_has_attributes_geometries_transform_and_metadata() {
    let tree = random_tree(2, 600);
    let mut info = TreeInfo::new("tree-2", &tree);
    info.species = Some("Quercus robur".into());
    info.attributes = metrics();
    let doc = cityjson::city_json(&info, &[Lod::L3, Lod::L0, Lod::L1, Lod::L1]);
    let object = &doc["CityObjects"]["tree-2"];
    assert_eq!(object["type"], "SolitaryVegetationObject");
    let attributes = &object["attributes"];
    assert_eq!(attributes["species"], "Quercus robur");
    // The caller's measured height wins over the skeleton's estimate.
    assert_eq!(attributes["height"], 14.25);
    assert_eq!(attributes["silva:internodes"], 800);
    let dbh = attributes["trunkDiameter"].as_f64().unwrap();
    assert!(dbh > 0.0 && dbh <= 2.0 * f64::from(tree.radius(NodeId::ROOT)) + 1e-3);
    assert!(attributes["crownDiameter"].as_f64().unwrap() > 1.0);

    let geometry = object["geometry"].as_array().unwrap();
    let kinds: Vec<(&str, &str)> = geometry
        .iter()
        .map(|g| (g["type"].as_str().unwrap(), g["lod"].as_str().unwrap()))
        .collect();
    assert_eq!(
        kinds,
        [
            ("MultiSurface", "0"),
            ("MultiSurface", "1"),
            ("MultiSurface", "3"),
            ("MultiLineString", "3")
        ]
    );
    // Close to the mesh's triangle count: only triangles that collapse at
    // 1 mm may be dropped.
    let triangles = geometry[2]["boundaries"].as_array().unwrap().len();
    let full = mesh::build_mesh(&tree, Lod::L3).triangle_count();
    assert!(
        triangles <= full && triangles * 100 >= full * 99,
        "{triangles} of {full}"
    );
    let branches = tree.ids().filter(|&id| tree.is_tip(id)).count();
    assert_eq!(
        geometry[3]["boundaries"].as_array().unwrap().len(),
        branches
    );

    assert_eq!(doc["transform"]["scale"], json!([0.001, 0.001, 0.001]));
    assert_eq!(
        doc["metadata"]["referenceSystem"],
        "https://www.opengis.net/def/crs/EPSG/0/28992"
    );
    // The extent holds every vertex, which are integers near the anchor.
    let translate: Vec<f64> =
        serde_json::from_value(doc["transform"]["translate"].clone()).unwrap();
    let extent: Vec<f64> =
        serde_json::from_value(doc["metadata"]["geographicalExtent"].clone()).unwrap();
    let origin = tree.anchor().origin;
    assert!((translate[0] - origin.x).abs() < 1e-3 && (translate[2] - origin.z).abs() < 1e-3);
    for v in doc["vertices"].as_array().unwrap() {
        for k in 0..3 {
            let x = translate[k] + v[k].as_i64().unwrap() as f64 * 0.001;
            assert!(x >= extent[k] - 1e-6 && x <= extent[k + 3] + 1e-6);
        }
    }
    let height = tree.bounds().1.z as f64;
    assert!(
        (extent[5] - origin.z - height).abs() < 0.05,
        "top of extent"
    );
}

#[test]
fn seq_streams_validate_and_share_the_header_transform() {
    let trees: Vec<Skeleton> = (0..4).map(|s| random_tree(s, 300)).collect();
    let infos: Vec<TreeInfo> = trees
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let mut info = TreeInfo::new(format!("t{k}"), t);
            info.attributes = metrics();
            info
        })
        .collect();
    let lines: Vec<String> = cityjson::city_json_seq(&infos, &[Lod::L1, Lod::L3])
        .unwrap()
        .collect();
    assert_eq!(lines.len(), 1 + trees.len());
    assert!(lines.iter().all(|l| !l.contains('\n')));
    assert_valid_seq(&lines);
    let header: Value = serde_json::from_str(&lines[0]).unwrap();
    let extent: Vec<f64> =
        serde_json::from_value(header["metadata"]["geographicalExtent"].clone()).unwrap();
    let translate: Vec<f64> =
        serde_json::from_value(header["transform"]["translate"].clone()).unwrap();
    // Every feature's vertices, decoded with the header transform, lie in
    // the header extent: far-apart trees share one transform.
    for line in &lines[1..] {
        let feature: Value = serde_json::from_str(line).unwrap();
        assert_eq!(feature["type"], "CityJSONFeature");
        let id = feature["id"].as_str().unwrap();
        assert!(feature["CityObjects"][id].is_object());
        for v in feature["vertices"].as_array().unwrap() {
            for k in 0..3 {
                let x = translate[k] + v[k].as_i64().unwrap() as f64 * 0.001;
                assert!(
                    x >= extent[k] && x <= extent[k + 3],
                    "outside the header extent"
                );
            }
        }
    }
}

#[test]
fn seq_rejects_mixed_crs_and_duplicate_ids() {
    let a = random_tree(1, 100);
    let mut b = random_tree(2, 100);
    let info = |id: &str, s| TreeInfo::new(id, s);
    let same = [info("x", &a), info("x", &a)];
    assert_eq!(
        cityjson::city_json_seq(&same, &[Lod::L0]).err(),
        Some(CityJsonError::DuplicateId("x".into()))
    );
    b.set_anchor(Anchor {
        origin: b.anchor().origin,
        crs: Some("EPSG:7415".into()),
    });
    let mixed = [info("a", &a), info("b", &b)];
    assert!(matches!(
        cityjson::city_json_seq(&mixed, &[Lod::L0]),
        Err(CityJsonError::MixedCrs { .. })
    ));
    let empty: [TreeInfo; 0] = [];
    let lines: Vec<String> = cityjson::city_json_seq(&empty, &[Lod::L0])
        .unwrap()
        .collect();
    assert_eq!(lines.len(), 1);
    assert_valid_seq(&lines);
}

#[test]
fn odd_trees_still_validate() {
    // No CRS, a root-only skeleton, and a fork of zero-radius twigs.
    let root_only = Skeleton::new(Anchor::at(DVec3::new(1.0, 2.0, 3.0)), 0.1);
    let doc = cityjson::city_json(&TreeInfo::new("stump", &root_only), &Lod::ALL);
    assert!(doc["metadata"].get("referenceSystem").is_none());
    assert!(doc["CityObjects"]["stump"].get("geometry").is_none());
    assert_valid(&doc.to_string());
    let mut fork = Skeleton::new(Anchor::at(DVec3::ZERO), 0.002);
    let a = fork.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 0.5), 0.0);
    fork.add_child(a, Vec3::new(0.0, 0.0, 1.0), 0.0);
    fork.add_child(a, Vec3::new(0.0005, 0.0, 0.5005), 0.0);
    let doc = cityjson::city_json(&TreeInfo::new("twig", &fork), &Lod::ALL);
    assert_valid(&doc.to_string());
}

#[test]
fn lod_figures_cover_every_level() {
    let tree = random_tree(5, 1000);
    let figures = cityjson::lod_figures(&tree);
    assert_eq!(figures.iter().map(|f| f.lod).collect::<Vec<_>>(), Lod::ALL);
    for f in &figures {
        assert_eq!(f.triangles, mesh::build_mesh(&tree, f.lod).triangle_count());
        assert!(f.glb_bytes > f.triangles * 6 && f.obj_bytes > f.glb_bytes);
        assert!(f.cityjson_bytes > 0);
    }
}

/// The validator harness catches what the writers must avoid, so the tests
/// above cannot pass vacuously.
#[test]
fn validator_rejects_broken_documents() {
    let tree = random_tree(3, 100);
    let doc = cityjson::city_json(&TreeInfo::new("t", &tree), &[Lod::L1]);
    let mut bad_lod = doc.clone();
    bad_lod["CityObjects"]["t"]["geometry"][0]["lod"] = json!("4");
    assert!(!CJValidator::from_str(&bad_lod.to_string()).is_valid());
    let mut missing_vertex = doc.clone();
    missing_vertex["vertices"].as_array_mut().unwrap().pop();
    assert!(!CJValidator::from_str(&missing_vertex.to_string()).is_valid());
    let mut duplicate = doc;
    let first = duplicate["vertices"][0].clone();
    duplicate["vertices"].as_array_mut().unwrap().push(first);
    assert!(!problems(&CJValidator::from_str(&duplicate.to_string())).is_empty());
}
