//! The skeleton's PLY form (`Skeleton::to_ply`, `Skeleton::from_ply`):
//! silva's own files read back as the same tree, AdTree's classical skeleton
//! PLY (ascii, vertices and edges in any order, no radius) read as the tree
//! it describes, and malformed files refused with a typed error, never a
//! panic.

mod mesh_support;

use std::collections::HashMap;

use glam::DVec3;
use proptest::prelude::*;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use silva::skeleton::{MAX_PLY_NODES, SkeletonPlyError};
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, NodeId, Skeleton};

use mesh_support::{random_tree, split_ply};

/// A Weber–Penn pine whose root is its lowest node, as in a real tree.
fn pine() -> Skeleton {
    let anchor = Anchor {
        origin: DVec3::new(127_395.5, 401_149.75, 1.25),
        crs: Some("EPSG:28992".into()),
    };
    let tree = generate(&TreeParams::preset(Species::Pine), 3, anchor).canonical();
    let lowest = tree
        .ids()
        .map(|id| tree.position(id).z)
        .fold(f32::MAX, f32::min);
    assert_eq!(lowest, 0.0, "the test needs the root as the lowest node");
    tree
}

#[test]
fn the_ply_holds_nodes_radii_and_edges_parent_to_child() {
    let tree = random_tree(8, 200);
    let bytes = tree.to_ply();
    let (header, body) = split_ply(&bytes);
    assert!(header.contains(&format!("element vertex {}\n", tree.len())));
    assert!(header.contains("property float radius\n"));
    assert!(header.contains("comment crs EPSG:28992\n"));
    assert!(header.contains(&format!("element edge {}\n", tree.internode_count())));
    assert_eq!(body.len(), tree.len() * 28 + tree.internode_count() * 8);
    for id in tree.ids() {
        let at = id.index() * 28;
        let coordinate =
            |k: usize| f64::from_le_bytes(body[at + 8 * k..at + 8 * k + 8].try_into().unwrap());
        let r = f32::from_le_bytes(body[at + 24..at + 28].try_into().unwrap());
        let p = tree.absolute_position(id);
        assert_eq!(
            (coordinate(0), coordinate(1), coordinate(2)),
            (p.x, p.y, p.z)
        );
        assert_eq!(r, tree.radius(id));
    }
    let edges = &body[tree.len() * 28..];
    for (k, (p, c)) in tree.internodes().enumerate() {
        let read =
            |o: usize| i32::from_le_bytes(edges[k * 8 + o..k * 8 + o + 4].try_into().unwrap());
        assert_eq!((read(0), read(4)), (p.index() as i32, c.index() as i32));
    }
}

/// `back` is `tree` node for node: same parents, children order and radii,
/// absolute positions within `tolerance_m`.
fn assert_same_tree(tree: &Skeleton, back: &Skeleton, tolerance_m: f64) {
    assert_eq!(back.len(), tree.len());
    assert_eq!(back.anchor().crs, tree.anchor().crs);
    for (a, b) in tree.ids().zip(back.ids()) {
        assert_eq!(back.parent(b), tree.parent(a), "node {}", a.index());
        assert_eq!(back.children(b), tree.children(a), "node {}", a.index());
        assert_eq!(back.radius(b), tree.radius(a));
        let d = (back.absolute_position(b) - tree.absolute_position(a)).length();
        assert!(d <= tolerance_m, "node {} moved {d} m", a.index());
    }
}

#[test]
fn silva_skeleton_ply_reads_back_as_the_same_tree() {
    for seed in 0..8 {
        let tree = random_tree(seed, 400).canonical();
        let back = Skeleton::from_ply(&tree.to_ply()).unwrap();
        assert_same_tree(&tree, &back, 1e-6);
    }
    let tree = pine();
    assert_same_tree(&tree, &Skeleton::from_ply(&tree.to_ply()).unwrap(), 1e-6);
}

/// `tree` in the augmented AdTree's layout (lsystem-from-adtree-skeletons,
/// Fig. 3.11): ascii, `float x y z`, an empty face element, no radius, the
/// vertices shuffled and each edge written in a random direction and order.
/// Coordinates are written in full, so that nodes can be matched by position.
fn adtree_ply(tree: &Skeleton, seed: u64) -> String {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut order: Vec<usize> = (0..tree.len()).collect();
    order.shuffle(&mut rng);
    let mut at = vec![0; tree.len()];
    for (line, &node) in order.iter().enumerate() {
        at[node] = line;
    }
    let mut edges: Vec<(usize, usize)> = tree
        .internodes()
        .map(|(p, c)| (at[p.index()], at[c.index()]))
        .map(|(p, c)| if rng.random_bool(0.5) { (p, c) } else { (c, p) })
        .collect();
    edges.shuffle(&mut rng);
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face 0\nproperty list uchar int vertex_index\n\
         element edge {}\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        tree.len(),
        edges.len()
    );
    for &node in &order {
        let p = tree.absolute_position(NodeId::from_index(node));
        ply += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    for (a, b) in edges {
        ply += &format!("{a} {b}\n");
    }
    ply
}

#[test]
fn an_adtree_skeleton_is_read_as_the_tree_it_describes() {
    let tree = pine();
    let back = Skeleton::from_ply(adtree_ply(&tree, 5).as_bytes()).unwrap();
    assert_eq!(back.len(), tree.len());
    assert!(back.anchor().origin.distance(tree.anchor().origin) < 1e-6);
    // Match nodes by position, then compare parents.
    let key = |p: DVec3| (p * 1e3).round().as_i64vec3().to_array();
    let original: HashMap<_, NodeId> = tree
        .ids()
        .map(|id| (key(tree.absolute_position(id)), id))
        .collect();
    assert_eq!(original.len(), tree.len(), "positions are distinct");
    let map: Vec<NodeId> = back
        .ids()
        .map(|id| original[&key(back.absolute_position(id))])
        .collect();
    for id in back.ids() {
        let parent = back.parent(id).map(|p| map[p.index()]);
        assert_eq!(parent, tree.parent(map[id.index()]));
        assert_eq!(back.radius(id), 0.0);
    }
    // Children are ordered main extension first, as the generator ordered them.
    for id in back.ids() {
        let children: Vec<NodeId> = back.children(id).iter().map(|c| map[c.index()]).collect();
        assert_eq!(children, tree.children(map[id.index()]));
    }
}

fn ascii(vertex_props: &str, vertices: &[&str], edges: &[&str]) -> String {
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\n{vertex_props}element edge {}\n\
         property int vertex1\nproperty int vertex2\nend_header\n",
        vertices.len(),
        edges.len()
    );
    for line in vertices.iter().chain(edges) {
        ply += line;
        ply += "\n";
    }
    ply
}

const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";
const XYZR: &str = "property float x\nproperty float y\nproperty float z\nproperty float radius\n";

/// Whether an error is the one a case expects.
type Expected = fn(&SkeletonPlyError) -> bool;

#[test]
fn malformed_skeleton_plys_get_a_typed_error() {
    use SkeletonPlyError as E;
    let v4 = ["0 0 0", "0 0 1", "0 0 2", "1 0 2"];
    let cases: Vec<(&str, String, Expected)> = vec![
        (
            "a point cloud",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
             property float z\nend_header\n0 0 0\n1 1 1\n"
                .into(),
            |e| matches!(e, E::Layout(m) if m.contains("silva reconstruct")),
        ),
        (
            "no z",
            ascii(
                "property float x\nproperty float y\n",
                &["0 0", "0 1"],
                &["0 1"],
            ),
            |e| matches!(e, E::Layout(m) if m.contains("z")),
        ),
        ("no vertices", ascii(XYZ, &[], &[]), |e| {
            matches!(e, E::Layout(_))
        }),
        (
            "too few edges",
            ascii(XYZ, &v4, &["0 1", "1 2"]),
            |e| matches!(e, E::NotATree(m) if m.contains("4 vertices need 3 edges")),
        ),
        ("a cycle", ascii(XYZ, &v4, &["0 1", "1 2", "2 0"]), |e| {
            matches!(e, E::NotATree(_))
        }),
        (
            "a repeated edge",
            ascii(XYZ, &v4, &["0 1", "1 2", "2 1"]),
            |e| matches!(e, E::NotATree(_)),
        ),
        (
            "an unknown vertex",
            ascii(XYZ, &v4, &["0 1", "1 2", "2 7"]),
            |e| matches!(e, E::Edge { edge: 2, .. }),
        ),
        (
            "a negative vertex",
            ascii(XYZ, &v4, &["0 1", "-1 2", "2 3"]),
            |e| matches!(e, E::Edge { edge: 1, .. }),
        ),
        ("a loop", ascii(XYZ, &v4, &["0 1", "1 1", "2 3"]), |e| {
            matches!(e, E::Edge { edge: 1, .. })
        }),
        (
            "a NaN coordinate",
            ascii(XYZ, &["0 0 0", "nan 0 1"], &["0 1"]),
            |e| matches!(e, E::Vertex { vertex: 1, .. }),
        ),
        (
            "a negative radius",
            ascii(XYZR, &["0 0 0 0.1", "0 0 1 -0.1"], &["0 1"]),
            |e| matches!(e, E::Vertex { vertex: 1, .. }),
        ),
        (
            "a word for a number",
            ascii(XYZ, &["0 0 0", "0 x 1"], &["0 1"]),
            |e| matches!(e, E::Ply(_)),
        ),
        (
            "a missing edge line",
            ascii(XYZ, &v4, &["0 1", "1 2"]).replace("edge 2", "edge 3"),
            |e| matches!(e, E::Ply(_)),
        ),
        (
            "a binary header promising four million vertices",
            format!(
                "ply\nformat binary_little_endian 1.0\nelement vertex {}\n{XYZ}end_header\n\0\0\0\0",
                MAX_PLY_NODES
            ),
            |e| matches!(e, E::Ply(_)),
        ),
        (
            "more vertices than a skeleton may have",
            format!(
                "ply\nformat ascii 1.0\nelement vertex {}\n{XYZ}end_header\n0 0 0\n",
                MAX_PLY_NODES + 1
            ),
            |e| matches!(e, E::Ply(c) if c.to_string().contains("limit")),
        ),
    ];
    for (what, ply, expected) in cases {
        match Skeleton::from_ply(ply.as_bytes()) {
            Ok(_) => panic!("{what}: read"),
            Err(e) => {
                assert!(expected(&e), "{what}: unexpected error {e}");
                assert!(e.to_string().starts_with("skeleton PLY: "), "{what}: {e}");
            }
        }
    }
}

#[test]
fn silva_files_keep_their_root_and_others_root_at_the_lowest_vertex() {
    // A tree on a slope: a limb hangs 0.5 m below the trunk base.
    let mut tree = Skeleton::new(Anchor::at(DVec3::new(85_000.0, 446_000.0, 2.0)), 0.3);
    let fork = tree.add_child(NodeId::ROOT, glam::Vec3::new(0.0, 0.0, 2.0), 0.2);
    tree.add_child(fork, glam::Vec3::new(0.0, 0.0, 6.0), 0.1);
    let limb = tree.add_child(fork, glam::Vec3::new(2.0, 0.0, 1.0), 0.05);
    tree.add_child(limb, glam::Vec3::new(3.0, 0.0, -0.5), 0.02);
    let ply = tree.to_ply();
    let back = Skeleton::from_ply(&ply).unwrap();
    assert_eq!(back.anchor().origin, DVec3::new(85_000.0, 446_000.0, 2.0));
    // The same bytes without silva's comment: a foreign file, rooted at
    // its lowest vertex, the limb's tip.
    let mark = b"comment silva tree";
    let at = ply.windows(mark.len()).position(|w| w == mark).unwrap();
    let mut foreign = ply.clone();
    foreign[at..at + mark.len()].copy_from_slice(b"comment other tree");
    let back = Skeleton::from_ply(&foreign).unwrap();
    assert_eq!(back.anchor().origin, DVec3::new(85_003.0, 446_000.0, 1.5));
    assert_eq!(back.len(), 5);
}

#[test]
fn a_lone_root_needs_no_edges() {
    let ply = "ply\nformat ascii 1.0\ncomment crs EPSG:28992\nelement vertex 1\n\
               property double x\nproperty double y\nproperty double z\nproperty float radius\n\
               end_header\n85000.5 446000.25 -1.5 0.3\n";
    let tree = Skeleton::from_ply(ply.as_bytes()).unwrap();
    assert_eq!(tree.len(), 1);
    assert_eq!(tree.anchor().origin, DVec3::new(85_000.5, 446_000.25, -1.5));
    assert_eq!(tree.anchor().crs.as_deref(), Some("EPSG:28992"));
    assert_eq!(tree.radius(NodeId::ROOT), 0.3);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any tree of silva's survives the round trip.
    #[test]
    fn random_trees_round_trip(seed in 0u64..10_000, internodes in 1usize..300) {
        let tree = random_tree(seed, internodes).canonical();
        let back = Skeleton::from_ply(&tree.to_ply()).unwrap();
        assert_same_tree(&tree, &back, 1e-6);
    }

    /// Bytes changed or cut anywhere give a skeleton or a typed error,
    /// never a panic.
    #[test]
    fn damaged_files_never_panic(
        seed in 0u64..1_000,
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        as_ascii in any::<bool>(),
    ) {
        let tree = random_tree(seed, 30).canonical();
        let mut bytes = if as_ascii {
            adtree_ply(&tree, seed).into_bytes()
        } else {
            tree.to_ply()
        };
        for (at, byte) in flips {
            let i = at.index(bytes.len());
            bytes[i] = byte;
        }
        bytes.truncate(cut.index(bytes.len() + 1));
        // What is read is a usable skeleton: finite, radii not negative.
        if let Ok(back) = Skeleton::from_ply(&bytes) {
            prop_assert!(back.anchor().origin.is_finite());
            for node in back.nodes() {
                prop_assert!(node.position.is_finite());
                prop_assert!(node.radius_m.is_finite() && node.radius_m >= 0.0);
            }
        }
    }
}

/// An AdTree skeleton has no radii; `estimate_radii` gives it those of an
/// unseen trunk. On Weber–Penn truths stripped of their radii, the radii are
/// positive and never grow towards the tips, and the estimated DBH of the
/// broad crowns is within 0.8–1.3 of the true one (0.88–1.24 when this test
/// was written). The poplars' columnar crowns get 0.36–0.42 of it: the
/// allometry from height × crown diameter reads a narrow crown as a thin
/// stem (the limitation `estimate_radii` documents).
#[test]
fn a_skeleton_without_radii_gets_pipe_model_radii_near_the_true_dbh() {
    use silva::eval::run::trunk_radius_at;
    use silva::reconstruct::radii::{DbhMethod, Params, estimate_radii};
    for species in Species::ALL {
        for seed in 1..=3 {
            let truth = generate(&TreeParams::preset(species), seed, Anchor::default());
            let mut bare = truth.clone();
            for id in bare.ids() {
                bare.set_radius(id, 0.0);
            }
            let trunk = estimate_radii(&mut bare, &Params::default());
            let true_dbh = 2.0 * trunk_radius_at(&truth, 1.3);
            let ratio = trunk.dbh_m() / true_dbh;
            eprintln!(
                "{species:?} {seed}: DBH {:.3} m, true {true_dbh:.3} m, ratio {ratio:.2}",
                trunk.dbh_m()
            );
            assert_eq!(trunk.method, DbhMethod::Estimated);
            // The poplars' band pins the documented limitation: if it ever
            // closes, the docs must say so.
            let band = if species == Species::Poplar {
                0.3..0.5
            } else {
                0.8..1.3
            };
            assert!(band.contains(&ratio), "{species:?} {seed}: ratio {ratio}");
            for id in bare.ids().skip(1) {
                let parent = bare.parent(id).unwrap();
                assert!(bare.radius(id) > 0.0);
                assert!(
                    bare.radius(id) <= bare.radius(parent) + 1e-6,
                    "{species:?} {seed}"
                );
            }
        }
    }
}
