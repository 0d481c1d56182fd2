//! Branch meshes and LOD: geometry sanity on synthetic trees (no NaN, no
//! degenerate faces, surface on the skeleton's radii, closed outward tubes),
//! LOD selection semantics, and the OBJ, PLY and cylinder-table writers.

mod mesh_support;

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use mesh_support::{random_tree, split_ply};
use silva::mesh::{self, Lod, Mesh, MeshFormat};
use silva::synth::{Species, TreeParams, generate};
use silva::{Anchor, NodeId, Skeleton};

const SEEDS: [u64; 3] = [1, 7, 42];

/// Random pipe-model trees and the Weber–Penn presets of `silva::synth`.
fn trees() -> Vec<Skeleton> {
    let anchor = Anchor {
        origin: DVec3::new(155_000.0, 463_000.0, 0.0),
        crs: Some("EPSG:28992".into()),
    };
    let synth = Species::ALL
        .iter()
        .map(|&s| generate(&TreeParams::preset(s), 3, anchor.clone()));
    SEEDS
        .iter()
        .map(|&s| random_tree(s, 800))
        .chain(synth)
        .collect()
}

fn triangle_area(m: &Mesh, [a, b, c]: [u32; 3]) -> f32 {
    let p = |i: u32| m.positions[i as usize];
    (p(b) - p(a)).cross(p(c) - p(a)).length() / 2.0
}

#[test]
fn meshes_have_no_nan_and_no_degenerate_faces() {
    for tree in trees() {
        for lod in Lod::ALL {
            let m = mesh::build_mesh(&tree, lod);
            assert!(!m.is_empty(), "{lod}");
            assert_eq!(m.positions.len(), m.normals.len());
            assert!(m.positions.iter().all(|p| p.is_finite()));
            for n in &m.normals {
                assert!((n.length() - 1.0).abs() < 1e-4, "normal {n} not unit");
            }
            for t in m.triangles() {
                assert!(t.iter().all(|&i| (i as usize) < m.vertex_count()));
                assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
                assert!(triangle_area(&m, t) > 1e-9, "{lod}: degenerate {t:?}");
            }
        }
    }
}

/// Every directed edge appears exactly once and its reverse exactly once:
/// each tube is a closed 2-manifold with consistently oriented faces.
#[test]
fn tubes_are_closed_and_consistently_oriented() {
    for tree in trees() {
        let m = mesh::build_mesh(&tree, Lod::L3);
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for [a, b, c] in m.triangles() {
            for e in [(a, b), (b, c), (c, a)] {
                *edges.entry(e).or_default() += 1;
            }
        }
        for (&(a, b), &count) in &edges {
            assert_eq!(count, 1, "edge {a}-{b} used twice in one direction");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} is on a hole");
        }
    }
}

/// One closed tube per branch, each enclosing a positive volume (outward
/// winding), and vertex normals agreeing with the face normals.
#[test]
fn every_branch_is_a_tube_with_positive_volume() {
    for tree in trees() {
        for lod in Lod::ALL {
            let m = mesh::build_mesh(&tree, lod);
            let selected = mesh::select(&tree, lod);
            let branches = selected.ids().filter(|&id| selected.is_tip(id)).count();
            let component = components(&m);
            let count = component.iter().max().map_or(0, |&c| c + 1);
            assert_eq!(count, branches, "{lod}: tubes vs branches");
            let mut volume = vec![0.0f64; count];
            for t in m.triangles() {
                let [a, b, c] = t.map(|i| m.positions[i as usize].as_dvec3());
                volume[component[t[0] as usize]] += a.dot(b.cross(c)) / 6.0;
                let face = (b - a).cross(c - a).as_vec3();
                let vertex_normals: Vec3 = t.iter().map(|&i| m.normals[i as usize]).sum();
                assert!(
                    face.dot(vertex_normals) > 0.0,
                    "{lod}: normals disagree with winding"
                );
            }
            assert!(volume.iter().all(|&v| v > 0.0), "{lod}: inward tube");
        }
    }
}

/// Connected components of the mesh, as a component index per vertex.
fn components(m: &Mesh) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..m.vertex_count()).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for [a, b, c] in m.triangles() {
        for (x, y) in [(a, b), (b, c)] {
            let (rx, ry) = (find(&mut parent, x as usize), find(&mut parent, y as usize));
            parent[rx] = ry;
        }
    }
    let mut label = HashMap::new();
    (0..m.vertex_count())
        .map(|i| {
            let root = find(&mut parent, i);
            let next = label.len();
            *label.entry(root).or_insert(next)
        })
        .collect()
}

/// Distance from `p` to segment `a`–`b` and the segment parameter there.
fn to_segment(p: Vec3, a: Vec3, b: Vec3) -> (f32, f32) {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    (p.distance(a + ab * t), t)
}

/// An internode as a tapered cylinder, with how far a smooth axis may leave
/// it: `(start, end, start radius, end radius, sag allowance in metres)`.
type Frustum = (Vec3, Vec3, f32, f32, f32);

/// The internodes of a selected skeleton as the sweep sees them: a lateral's
/// first internode starts no wider than its parent. The sag allowance is the
/// departure of a cubic Hermite curve from its chord when its end tangents
/// bisect the kinks at both ends, `L (α₀ + α₁) / 16` for turns α, with a
/// 1.5 margin because the largest departure need not be at mid-segment.
fn frusta(s: &Skeleton) -> Vec<Frustum> {
    let dir = |c: NodeId| {
        let p = s.parent(c).unwrap();
        (s.position(c) - s.position(p)).normalize_or_zero()
    };
    s.internodes()
        .map(|(p, c)| {
            let r_c = s.radius(c).max(mesh::MIN_RADIUS_M);
            let r_p = s.radius(p).max(mesh::MIN_RADIUS_M);
            let main = s.children(p)[0] == c;
            let r_start = if main { r_p } else { r_c.min(r_p) };
            let turn_in = if main && p != NodeId::ROOT {
                dir(p).angle_between(dir(c))
            } else {
                0.0
            };
            let turn_out = s
                .children(c)
                .first()
                .map_or(0.0, |&n| dir(c).angle_between(dir(n)));
            let length = s.position(p).distance(s.position(c));
            let sag = 1.5 * length * (turn_in + turn_out) / 16.0;
            (s.position(p), s.position(c), r_start, r_c, sag)
        })
        .collect()
}

/// Ring vertices lie on the tapered surface of some internode: their
/// distance to the internode's axis is its interpolated radius times the
/// ring's [`mesh::ring_radius_scale`], within 10 % plus 2 mm plus the sag the smoothed axis needs to round the kinks of the
/// polyline ([`frusta`]). Only the two cap vertices of each tube (base
/// centre and tip apex) lie near an axis instead.
#[test]
fn surface_follows_the_skeleton_radii() {
    for tree in trees() {
        for lod in [Lod::L1, Lod::L3] {
            let selected = mesh::select(&tree, lod);
            let m = mesh::build_mesh(&tree, lod);
            let frusta = frusta(&selected);
            // Ring vertices lie out by the polygon's perimeter factor, the
            // largest for the level's fewest segments.
            let widest = mesh::ring_radius_scale(lod.resolution().min_segments);
            let mut on_axis = 0;
            for &v in &m.positions {
                let mut on_surface = false;
                let mut near_axis = false;
                for &(a, b, ra, rb, sag) in &frusta {
                    let (d, t) = to_segment(v, a, b);
                    let r = ra + (rb - ra) * t;
                    let slack = 0.002 + sag;
                    on_surface |= d >= 0.9 * r - slack && d <= 1.1 * widest * r + slack;
                    near_axis |= d < 0.6 * r;
                }
                if !on_surface {
                    assert!(near_axis, "{lod}: vertex {v} is off the surface");
                    on_axis += 1;
                }
            }
            let tips = selected.ids().filter(|&id| selected.is_tip(id)).count();
            assert!(
                on_axis <= 2 * tips,
                "{lod}: {on_axis} vertices off the surface"
            );
        }
    }
}

#[test]
fn lod_levels_prune_as_defined() {
    let tree = random_tree(3, 1500);
    let orders = tree.branch_orders();
    assert!(orders.iter().any(|&o| o >= 2), "test tree needs depth");
    let l0 = mesh::select(&tree, Lod::L0);
    assert!(l0.branch_orders().iter().all(|&o| o <= 1));
    // LOD 0 is LOD 1's scaffold cut to orders 0 and 1, so the levels nest.
    let l1 = mesh::select(&tree, Lod::L1);
    let l1_orders = l1.branch_orders();
    assert_eq!(l0.len(), l1_orders.iter().filter(|&&o| o <= 1).count());
    assert!(l0.len() <= l1.len());
    assert_eq!(mesh::select(&tree, Lod::L3), tree.canonical());
    let sizes: Vec<usize> = [Lod::L1, Lod::L2, Lod::L3]
        .iter()
        .map(|&l| mesh::select(&tree, l).len())
        .collect();
    assert!(sizes[0] < sizes[1] && sizes[1] < sizes[2], "{sizes:?}");
    // Thresholds: every kept lateral starts at least at T.
    for lod in [Lod::L1, Lod::L2] {
        let t = lod.radius_threshold_m(&tree).unwrap();
        let s = mesh::select(&tree, lod);
        let laterals: Vec<f32> = s
            .ids()
            .flat_map(|id| s.children(id).iter().skip(1).map(|&l| s.radius(l)))
            .collect();
        assert!(!laterals.is_empty(), "{lod:?} keeps laterals");
        assert!(
            laterals.iter().all(|&r| r >= t),
            "{lod:?}: a lateral under {t}"
        );
    }
    let triangles: Vec<usize> = Lod::ALL
        .iter()
        .map(|&l| mesh::build_mesh(&tree, l).triangle_count())
        .collect();
    assert!(
        triangles[0] <= triangles[1] && triangles[1] < triangles[2] && triangles[2] < triangles[3],
        "{triangles:?}"
    );
}

fn y_tree() -> (Skeleton, [NodeId; 5]) {
    let anchor = Anchor {
        origin: DVec3::new(155_000.0, 463_000.0, 1.0),
        crs: Some("EPSG:28992".into()),
    };
    let mut s = Skeleton::new(anchor, 0.3);
    let fork = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 3.0), 0.25);
    let top = s.add_child(fork, Vec3::new(0.0, 0.0, 6.0), 0.02);
    let thick = s.add_child(fork, Vec3::new(1.0, 0.0, 4.0), 0.12);
    let twig = s.add_child(thick, Vec3::new(1.5, 0.5, 4.5), 0.01);
    let thin = s.add_child(fork, Vec3::new(-1.0, 0.0, 4.0), 0.02);
    (s, [fork, top, thick, twig, thin])
}

#[test]
fn pruning_keeps_main_extensions_and_drops_thin_laterals_with_their_subtrees() {
    let (s, _) = y_tree();
    // 0.1 m: the thin lateral goes; the thick one stays with its twig, which
    // is its main extension; the thin trunk top stays (never foreshortened).
    let pruned = mesh::prune_thin_branches(&s, 0.1);
    assert_eq!(pruned.len(), 5);
    assert!(pruned.nodes().iter().all(|n| n.position.x > -0.5));
    let none = mesh::prune_thin_branches(&s, 0.0);
    assert_eq!(none, s.canonical());
    let trunk_only = mesh::prune_thin_branches(&s, 1.0);
    assert_eq!(trunk_only.len(), 3);
    assert_eq!(Lod::L1.radius_threshold_m(&s), Some(0.3 * 0.3));
    assert_eq!(Lod::L0.radius_threshold_m(&s), None);
    assert_eq!(mesh::trunk_radius_m(&s), 0.3);
}

#[test]
fn degenerate_skeletons_give_empty_or_valid_meshes() {
    let anchor = Anchor::at(DVec3::ZERO);
    let root_only = Skeleton::new(anchor.clone(), 0.1);
    assert!(mesh::build_mesh(&root_only, Lod::L3).is_empty());
    // Coincident nodes and zero radii must not produce NaN or zero-area faces.
    let mut s = Skeleton::new(anchor, 0.0);
    let a = s.add_child(NodeId::ROOT, Vec3::ZERO, 0.0);
    let b = s.add_child(a, Vec3::new(0.0, 0.0, 1.0), 0.0);
    s.add_child(b, Vec3::new(0.0, 0.0, 1.0), 0.0);
    s.add_child(b, Vec3::new(0.0, 0.0, 1.0), 0.0);
    let m = mesh::build_mesh(&s, Lod::L3);
    assert!(!m.is_empty());
    assert!(m.positions.iter().all(|p| p.is_finite()));
    assert!(m.triangles().all(|t| triangle_area(&m, t) > 1e-9));
    let glb = MeshFormat::Glb.encode(&m, s.anchor(), DVec3::ZERO);
    assert_eq!(&glb[..4], b"glTF");
}

#[test]
fn obj_lists_every_vertex_normal_and_face() {
    let tree = random_tree(5, 300);
    let m = mesh::build_mesh(&tree, Lod::L2);
    let text = mesh::obj(&m, tree.anchor(), DVec3::ZERO);
    let count = |prefix: &str| text.lines().filter(|l| l.starts_with(prefix)).count();
    assert_eq!(count("v "), m.vertex_count());
    assert_eq!(count("vn "), m.vertex_count());
    assert_eq!(count("f "), m.triangle_count());
    assert!(text.contains("# crs EPSG:28992"));
    // Absolute coordinates: the first vertex sits near the anchor.
    let first: Vec<f64> = text
        .lines()
        .find(|l| l.starts_with("v "))
        .unwrap()
        .split_whitespace()
        .skip(1)
        .map(|x| x.parse().unwrap())
        .collect();
    let expected = tree.anchor().origin + m.positions[0].as_dvec3();
    assert!((first[0] - expected.x).abs() < 1e-3 && (first[1] - expected.y).abs() < 1e-3);
}

/// The mesh PLY is binary little-endian, and its body holds exactly the
/// vertices and faces its header declares.
#[test]
fn mesh_ply_is_binary_with_declared_sizes() {
    let tree = random_tree(6, 300);
    let m = mesh::build_mesh(&tree, Lod::L3);
    let bytes = mesh::mesh_ply(&m, tree.anchor(), tree.anchor().origin);
    let (header, body) = split_ply(&bytes);
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    assert!(header.contains(&format!("element vertex {}\n", m.vertex_count())));
    assert!(header.contains(&format!("element face {}\n", m.triangle_count())));
    assert_eq!(body.len(), m.vertex_count() * 36 + m.triangle_count() * 13);
    let x = f64::from_le_bytes(body[..8].try_into().unwrap());
    assert!((x - f64::from(m.positions[0].x)).abs() < 1e-9);
}

#[test]
fn cylinder_table_has_one_row_per_internode() {
    let tree = random_tree(9, 200);
    let csv = mesh::cylinder_table_csv(&tree);
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(mesh::CYLINDER_TABLE_HEADER));
    let orders = tree.branch_orders();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), tree.internode_count());
    for (row, (p, c)) in rows.iter().zip(tree.internodes()) {
        assert_eq!(row.len(), 11);
        assert_eq!((row[0] as usize, row[1] as usize), (c.index(), p.index()));
        assert_eq!(row[2] as u32, orders[c.index()]);
        let start = tree.absolute_position(p);
        assert!((row[3] - start.x).abs() < 1e-3 && (row[5] - start.z).abs() < 1e-3);
        let axis = glam::DVec3::new(row[6], row[7], row[8]);
        assert!((axis.length() - 1.0).abs() < 1e-4);
        let end = start + axis * row[9];
        assert!(end.distance(tree.absolute_position(c)) < 2e-3);
        assert!((row[10] as f32 - tree.radius(c)).abs() < 1e-4);
    }
}

#[test]
fn mesh_formats_by_extension() {
    assert_eq!(MeshFormat::from_extension("GLB"), Some(MeshFormat::Glb));
    assert_eq!(MeshFormat::from_extension("obj"), Some(MeshFormat::Obj));
    assert_eq!(MeshFormat::from_extension("ply"), Some(MeshFormat::Ply));
    assert_eq!(MeshFormat::from_extension("stl"), None);
}
