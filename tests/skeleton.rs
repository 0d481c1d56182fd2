//! The central `Skeleton` type: invariants, pruning, JSON round trip.

use glam::{DVec3, Vec3};
use silva::skeleton::{Anchor, Node, NodeId, Skeleton, SkeletonError};

fn y_tree() -> (Skeleton, [NodeId; 4]) {
    let mut s = Skeleton::new(
        Anchor {
            origin: DVec3::new(155_000.123, 463_000.456, -2.5),
            crs: Some("EPSG:28992".into()),
        },
        0.3,
    );
    let a = s.add_child(NodeId::ROOT, Vec3::new(0.0, 0.0, 2.0), 0.25);
    let lateral = s.add_child(a, Vec3::new(1.5, 0.0, 3.0), 0.05);
    let mid = s.add_child(a, Vec3::new(0.0, 0.1, 4.0), 0.2);
    let top = s.add_child(mid, Vec3::new(0.0, 0.0, 7.0), 0.1);
    (s, [a, lateral, mid, top])
}

#[test]
fn main_extension_first_and_branch_orders() {
    let (mut s, [a, lateral, mid, _]) = y_tree();
    assert_eq!(s.children(a), &[lateral, mid]);
    s.order_main_extension_first();
    assert_eq!(s.children(a), &[mid, lateral]);
    assert_eq!(s.branch_orders()[lateral.index()], 1);
    assert_eq!(s.branch_orders()[mid.index()], 0);
}

#[test]
fn retain_reattaches_kept_descendants() {
    let (s, [a, _, mid, top]) = y_tree();
    let mut keep = vec![true; s.len()];
    keep[mid.index()] = false;
    let r = s.retain(&keep);
    assert_eq!(r.len(), 4);
    // `top` now hangs directly from `a`.
    let top_new = r
        .ids()
        .find(|&id| r.position(id) == s.position(top))
        .unwrap();
    assert_eq!(r.position(r.parent(top_new).unwrap()), s.position(a));
}

#[test]
fn json_round_trip_keeps_millimetres_far_from_origin() {
    let (mut s, _) = y_tree();
    s.order_main_extension_first();
    let back = Skeleton::from_json(&s.to_json()).unwrap();
    for (id, id2) in s.canonical().ids().zip(back.ids()) {
        let d = s.canonical().absolute_position(id) - back.absolute_position(id2);
        assert!(d.length() < 1e-3, "moved by {d:?}");
    }
    assert_eq!(back, s.canonical());
}

#[test]
fn invalid_nodes_are_rejected() {
    let node = |parent: Option<u32>, r: f32| Node {
        position: Vec3::ZERO,
        radius_m: r,
        parent: parent.map(|p| NodeId::from_index(p as usize)),
    };
    let anchor = Anchor::default();
    assert_eq!(
        Skeleton::from_nodes(anchor.clone(), vec![]),
        Err(SkeletonError::Empty)
    );
    assert_eq!(
        Skeleton::from_nodes(anchor.clone(), vec![node(None, 0.1), node(Some(1), 0.1)]),
        Err(SkeletonError::ParentOrder { node: 1, parent: 1 })
    );
    assert_eq!(
        Skeleton::from_nodes(anchor.clone(), vec![node(None, f32::NAN)]),
        Err(SkeletonError::NotFinite(0))
    );
    assert_eq!(
        Skeleton::from_nodes(anchor, vec![node(None, 0.1), node(None, 0.1)]),
        Err(SkeletonError::Root(1))
    );
}

#[test]
fn hostile_json_is_an_error_not_a_panic() {
    for text in [
        "",
        "{}",
        r#"{"format":"silva-skeleton","version":1,"anchor":{"origin":[0,0,0]},"nodes":[]}"#,
        r#"{"format":"silva-skeleton","version":1,"anchor":{"origin":[0,0,0]},"nodes":[[0,0,0,1,-1],[0,0,1,1,5]]}"#,
        r#"{"format":"silva-skeleton","version":9,"anchor":{"origin":[0,0,0]},"nodes":[[0,0,0,1,-1]]}"#,
        r#"{"format":"silva-skeleton","version":1,"anchor":{"origin":[0,0,0]},"nodes":[[0,0,0,-1,-1]]}"#,
    ] {
        assert!(Skeleton::from_json(text).is_err(), "accepted {text}");
    }
}
