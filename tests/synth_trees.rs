//! Synthetic trees and simulated scans: determinism, realistic sizes, radius
//! monotonicity, ground-truth round trip, TLS surface fidelity, ALS density.

use glam::{DVec3, Vec3};
use proptest::prelude::*;
use silva::spatial::PointIndex;
use silva::synth::{
    AlsOptions, LevelParams, ScannerPlacement, Species, TlsOptions, TreeParams, generate,
    simulate_als, simulate_tls,
};
use silva::{Anchor, NodeId, Skeleton};

fn tree(species: Species, seed: u64) -> Skeleton {
    generate(&TreeParams::preset(species), seed, Anchor::at(DVec3::ZERO))
}

/// Stem diameter at 1.3 m, interpolated along the trunk (branch order 0).
fn dbh_m(t: &Skeleton) -> f32 {
    let orders = t.branch_orders();
    let mut id = NodeId::ROOT;
    loop {
        let next = t
            .children(id)
            .iter()
            .copied()
            .find(|c| orders[c.index()] == 0);
        let Some(next) = next else {
            return 2.0 * t.radius(id);
        };
        let (z0, z1) = (t.position(id).z, t.position(next).z);
        if z1 >= 1.3 {
            let f = ((1.3 - z0) / (z1 - z0)).clamp(0.0, 1.0);
            return 2.0 * (t.radius(id) + f * (t.radius(next) - t.radius(id)));
        }
        id = next;
    }
}

fn height_m(t: &Skeleton) -> f32 {
    t.bounds().1.z
}

fn crown_radius_m(t: &Skeleton) -> f32 {
    t.nodes()
        .iter()
        .map(|n| n.position.truncate().length())
        .fold(0.0, f32::max)
}

#[test]
fn same_seed_gives_identical_trees_and_scans() {
    for species in Species::ALL {
        let a = tree(species, 11);
        let b = tree(species, 11);
        assert_eq!(a.to_json(), b.to_json(), "{species}");
        assert_ne!(a.to_json(), tree(species, 12).to_json(), "{species}");
    }
    let t = tree(Species::Birch, 3);
    assert_eq!(
        simulate_tls(&t, &TlsOptions::default(), 5),
        simulate_tls(&t, &TlsOptions::default(), 5)
    );
    assert_ne!(
        simulate_tls(&t, &TlsOptions::default(), 5).points,
        simulate_tls(&t, &TlsOptions::default(), 6).points
    );
    assert_eq!(
        simulate_als(&t, &AlsOptions::default(), 5),
        simulate_als(&t, &AlsOptions::default(), 5)
    );
}

#[test]
fn a_known_seed_gives_a_known_tree() {
    // Guards bit-identity across machines and releases: every generator
    // input (ChaCha8, libm, IEEE arithmetic) is portable, so this fingerprint
    // must not change unless the generator itself is changed on purpose.
    let t = tree(Species::Oak, 7);
    let checksum: f64 = t
        .nodes()
        .iter()
        .map(|n| f64::from(n.position.x + 2.0 * n.position.y + 3.0 * n.position.z + n.radius_m))
        .sum();
    let text = format!("{} {checksum:.3}", t.len());
    assert_eq!(text, include_str!("data/synth_oak_seed7.txt").trim());
}

#[test]
fn species_have_realistic_sizes() {
    // (height range m, DBH range m, internode count range)
    let expect = [
        (Species::Oak, (15.0, 25.0), (0.4, 0.9), (300, 8_000)),
        (Species::Birch, (13.0, 24.0), (0.2, 0.45), (300, 8_000)),
        (Species::Poplar, (18.0, 33.0), (0.4, 0.9), (300, 8_000)),
        (Species::Pine, (14.0, 25.0), (0.3, 0.6), (300, 8_000)),
    ];
    for (species, (h_lo, h_hi), (d_lo, d_hi), (n_lo, n_hi)) in expect {
        for seed in 0..8 {
            let t = tree(species, seed);
            let (h, d, n) = (height_m(&t), dbh_m(&t), t.internode_count());
            let what = format!("{species} seed {seed}: height {h} DBH {d} internodes {n}");
            assert!((h_lo..=h_hi).contains(&h), "{what}");
            assert!((d_lo..=d_hi).contains(&d), "{what}");
            assert!((n_lo..=n_hi).contains(&n), "{what}");
            for id in t.ids().skip(1) {
                let l = t.internode_length(id);
                assert!((0.05..=0.6).contains(&l), "{what}: internode of {l} m");
            }
            assert_eq!(t.position(NodeId::ROOT), Vec3::ZERO);
        }
    }
}

#[test]
fn species_have_their_crown_forms() {
    for seed in 0..4 {
        let (oak, birch, poplar, pine) = (
            tree(Species::Oak, seed),
            tree(Species::Birch, seed),
            tree(Species::Poplar, seed),
            tree(Species::Pine, seed),
        );
        // Poplar: columnar, a crown far narrower than the tree is tall.
        assert!(crown_radius_m(&poplar) < 0.2 * height_m(&poplar));
        // Oak: broad, a crown about as wide as the tree is tall.
        assert!(2.0 * crown_radius_m(&oak) > 0.7 * height_m(&oak));
        // Birch: slender next to the oak.
        assert!(dbh_m(&birch) < 0.75 * dbh_m(&oak));
        // Pine: conical, wider in the lower crown than near the top.
        let h = height_m(&pine);
        let width_between = |lo: f32, hi: f32| {
            pine.nodes()
                .iter()
                .filter(|n| (lo * h..hi * h).contains(&n.position.z))
                .map(|n| n.position.truncate().length())
                .fold(0.0, f32::max)
        };
        assert!(width_between(0.3, 0.55) > 1.5 * width_between(0.8, 1.0));
        // Birch: drooping, many twig internodes point downward.
        let orders = birch.branch_orders();
        let twigs: Vec<NodeId> = birch.ids().filter(|id| orders[id.index()] >= 2).collect();
        let down = twigs
            .iter()
            .filter(|&&id| {
                let p = birch.parent(id).unwrap();
                birch.position(id).z < birch.position(p).z
            })
            .count();
        assert!(
            down * 3 > twigs.len(),
            "{down} of {} twig internodes droop",
            twigs.len()
        );
    }
}

#[test]
fn radius_never_increases_towards_the_tips() {
    for species in Species::ALL {
        for seed in 0..4 {
            let t = tree(species, seed);
            for (p, c) in t.internodes() {
                assert!(t.radius(c) <= t.radius(p), "{species} {seed}: {c:?}");
                assert!(t.radius(c) > 0.0);
            }
        }
    }
}

#[test]
fn children_come_main_extension_first() {
    let t = tree(Species::Oak, 5);
    let mut again = t.clone();
    again.order_main_extension_first();
    assert_eq!(again, t);
    assert!(t.ids().any(|id| t.is_fork(id)));
}

#[test]
fn truth_round_trips_with_a_national_grid_anchor() {
    let anchor = Anchor {
        origin: DVec3::new(85_000.0, 446_000.0, 0.0),
        crs: Some("EPSG:28992".into()),
    };
    let t = generate(&TreeParams::preset(Species::Oak), 7, anchor.clone());
    let back = Skeleton::from_json(&t.to_json()).unwrap();
    assert_eq!(back, t);
    for id in t.ids() {
        let d = back.absolute_position(id) - t.absolute_position(id);
        assert!(d.length() < 1e-3);
    }
    // The relative geometry does not depend on the anchor.
    let at_zero = tree(Species::Oak, 7);
    assert_eq!(at_zero.nodes(), t.nodes());
    // Scans keep the georeference: absolute point = anchor + relative point,
    // to the millimetre.
    let tls = simulate_tls(&t, &TlsOptions::default(), 7);
    assert_eq!(tls.offset, anchor.origin);
    let als = simulate_als(&t, &AlsOptions::default(), 7);
    assert_eq!(als.offset, anchor.origin);
    let p = als.absolute(0);
    assert!((p - (anchor.origin + als.points[0].as_dvec3())).length() < 1e-3);
    assert!((p.x - 85_000.0).abs() < 50.0 && (p.y - 446_000.0).abs() < 50.0);
}

/// Distance from `p` to the nearest internode surface.
fn surface_distance(t: &Skeleton, index: &PointIndex, ends: &[(NodeId, NodeId)], p: Vec3) -> f32 {
    index
        .within(p, 1.5)
        .iter()
        .map(|n| {
            let (a_id, b_id) = ends[n.index];
            let (a, b) = (t.position(a_id), t.position(b_id));
            let ab = b - a;
            let f = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            let r = t.radius(a_id) + f * (t.radius(b_id) - t.radius(a_id));
            ((p - (a + ab * f)).length() - r).abs()
        })
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn tls_points_lie_on_the_bark() {
    let t = tree(Species::Oak, 2);
    let sd = 0.004;
    let opts = TlsOptions {
        noise_sd_m: sd,
        ..TlsOptions::default()
    };
    let cloud = simulate_tls(&t, &opts, 2);
    assert!(
        (10_000..=100_000).contains(&cloud.len()),
        "{} points",
        cloud.len()
    );
    let ends: Vec<(NodeId, NodeId)> = t.internodes().collect();
    let mids: Vec<Vec3> = ends
        .iter()
        .map(|&(a, b)| 0.5 * (t.position(a) + t.position(b)))
        .collect();
    let index = PointIndex::new(&mids);
    let sample: Vec<Vec3> = cloud.points.iter().step_by(7).copied().collect();
    let dists: Vec<f32> = sample
        .iter()
        .map(|&p| surface_distance(&t, &index, &ends, p))
        .collect();
    let within_3sd = dists.iter().filter(|&&d| d <= 3.0 * sd).count();
    assert!(within_3sd as f32 >= 0.98 * dists.len() as f32);
    assert!(
        dists.iter().all(|&d| d <= 6.0 * sd),
        "max {:?}",
        dists.iter().cloned().fold(0.0, f32::max)
    );
}

#[test]
fn tls_occlusion_hides_the_far_side() {
    let t = tree(Species::Pine, 4);
    let open = TlsOptions {
        occlusion: false,
        ..TlsOptions::default()
    };
    let all = simulate_tls(&t, &open, 4);
    // One scanner east of the trunk: the west side of the trunk is unseen.
    let one = TlsOptions {
        scanners: ScannerPlacement::At(vec![Vec3::new(10.0, 0.0, 1.5)]),
        ..TlsOptions::default()
    };
    let seen = simulate_tls(&t, &one, 4);
    assert!(seen.len() < all.len() / 2 + all.len() / 4);
    let trunk_low = |c: &silva::PointCloud, west: bool| {
        c.points
            .iter()
            .filter(|p| p.z < 3.0 && p.truncate().length() < 0.6 && (p.x < 0.0) == west)
            .count()
    };
    assert!(trunk_low(&seen, false) > 100);
    assert_eq!(trunk_low(&seen, true), 0);
    assert!(trunk_low(&all, true) > 100);
}

#[test]
fn als_density_is_within_20_percent_at_20_per_m2() {
    let t = tree(Species::Oak, 7);
    for clip_radius_m in [None, Some(15.0)] {
        let opts = AlsOptions {
            density_pts_per_m2: 20.0,
            clip_radius_m,
            ..AlsOptions::default()
        };
        let cloud = simulate_als(&t, &opts, 7);
        let half = clip_radius_m.unwrap_or(crown_radius_m(&t) + 3.0);
        let area = 4.0 * half * half;
        let density = cloud.len() as f32 / area;
        assert!((16.0..=24.0).contains(&density), "{density} pts/m²");
        assert!(
            cloud
                .points
                .iter()
                .all(|p| p.x.abs() <= half && p.y.abs() <= half)
        );
    }
}

#[test]
fn als_sees_mostly_crown_and_ground_around_the_tree() {
    let t = tree(Species::Oak, 7);
    let unclassified = simulate_als(&t, &AlsOptions::default(), 1);
    assert!(unclassified.classification.is_none());
    let opts = AlsOptions {
        classify_ground: true,
        ..AlsOptions::default()
    };
    let cloud = simulate_als(&t, &opts, 1);
    let classes = cloud.classification.as_ref().unwrap();
    let ground: Vec<Vec3> = (0..cloud.len())
        .filter(|&i| classes[i] == 2)
        .map(|i| cloud.points[i])
        .collect();
    let above: Vec<Vec3> = (0..cloud.len())
        .filter(|&i| classes[i] == 1)
        .map(|i| cloud.points[i])
        .collect();
    assert_eq!(ground.len() + above.len(), cloud.len());
    assert!(
        ground.len() > cloud.len() / 5,
        "{} ground of {}",
        ground.len(),
        cloud.len()
    );
    assert!(ground.iter().all(|p| p.z.abs() < 0.3));
    // Crown: above the lowest branch. Trunk: near the axis below it.
    let crown_base = 0.2 * height_m(&t);
    let crown = above.iter().filter(|p| p.z > crown_base).count();
    let trunk = above
        .iter()
        .filter(|p| p.z <= crown_base && p.truncate().length() < 1.0)
        .count();
    assert!(
        crown as f32 > 0.9 * above.len() as f32,
        "{crown} of {}",
        above.len()
    );
    assert!(
        (trunk as f32) < 0.02 * above.len() as f32,
        "{trunk} trunk hits"
    );
    let returns = cloud.return_number.as_ref().unwrap();
    assert!(returns.iter().any(|&r| r > 1));
    assert!(returns.iter().all(|&r| (1..=4).contains(&r)));

    let no_ground = simulate_als(
        &t,
        &AlsOptions {
            ground: false,
            ..AlsOptions::default()
        },
        1,
    );
    assert_eq!(no_ground.len(), above.len());
}

#[test]
fn hostile_parameters_give_a_valid_tree_not_a_panic() {
    let mut params = TreeParams::preset(Species::Oak);
    params.scale_m = f32::NAN;
    params.ratio = f32::INFINITY;
    params.levels[1].branches = u32::MAX;
    params.levels[2].internode_m = 0.0;
    params.levels.push(LevelParams {
        branches: 1_000,
        ..params.levels[2].clone()
    });
    let t = generate(&params, 1, Anchor::default());
    assert!(t.len() <= silva::synth::MAX_NODES);
    assert!(Skeleton::from_json(&t.to_json()).is_ok());
    let empty = TreeParams {
        levels: Vec::new(),
        ..TreeParams::preset(Species::Pine)
    };
    assert!(generate(&empty, 1, Anchor::default()).internode_count() >= 1);

    let small = tree(Species::Birch, 1);
    let none = AlsOptions {
        density_pts_per_m2: f32::NAN,
        ..AlsOptions::default()
    };
    assert!(simulate_als(&small, &none, 1).is_empty());
    let no_tls = TlsOptions {
        points_per_m2: -3.0,
        ..TlsOptions::default()
    };
    assert!(simulate_tls(&small, &no_tls, 1).is_empty());
}

#[test]
fn species_names_parse_and_print() {
    for species in Species::ALL {
        assert_eq!(species.to_string().parse::<Species>().unwrap(), species);
    }
    assert_eq!(" Oak ".parse::<Species>().unwrap(), Species::Oak);
    let err = "maple".parse::<Species>().unwrap_err();
    assert!(err.to_string().contains("oak, birch, poplar, pine"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn any_seed_gives_a_valid_tree(seed in any::<u64>(), k in 0usize..4) {
        let t = tree(Species::ALL[k], seed);
        prop_assert!(Skeleton::from_json(&t.to_json()).is_ok());
        for (p, c) in t.internodes() {
            prop_assert!(t.radius(c) <= t.radius(p));
        }
        prop_assert!(t.nodes().iter().all(|n| n.position.z >= 0.0));
        prop_assert!((12.0..35.0).contains(&height_m(&t)));
    }
}

/// Share of the wood at least 5 cm thick (internode midpoints) with a return
/// within 0.5 m: what an airborne reconstruction can hope to recover.
fn wood_seen_share(t: &Skeleton, cloud: &silva::PointCloud) -> f32 {
    let index = PointIndex::new(&cloud.points);
    let thick: Vec<Vec3> = t
        .ids()
        .filter_map(|id| t.parent(id).map(|p| (p, id)))
        .filter(|&(p, id)| t.radius(p).min(t.radius(id)) >= 0.05)
        .map(|(p, id)| 0.5 * (t.position(p) + t.position(id)))
        .collect();
    let seen = thick
        .iter()
        .filter(|&&m| !index.within(m, 0.5).is_empty())
        .count();
    seen as f32 / thick.len().max(1) as f32
}

#[test]
fn leaf_off_scans_see_the_limbs_of_deciduous_trees_and_conifers_keep_needles() {
    use silva::synth::{Foliage, Leaves};
    let scan = |species: Species, seed: u64, leaves: Leaves| {
        let t = tree(species, seed);
        let opts = AlsOptions {
            foliage: Foliage::for_species(species, leaves),
            ..AlsOptions::default()
        };
        let cloud = simulate_als(&t, &opts, seed);
        wood_seen_share(&t, &cloud)
    };
    for (species, seed) in [
        (Species::Oak, 31),
        (Species::Birch, 32),
        (Species::Poplar, 33),
    ] {
        let (on, off) = (
            scan(species, seed, Leaves::On),
            scan(species, seed, Leaves::Off),
        );
        // Leaf-on, foliage hides most of the wood.
        assert!(
            off >= 0.4 && off > on + 0.3,
            "{species} {seed}: on {on}, off {off}"
        );
    }
    let (on, off) = (
        scan(Species::Pine, 34, Leaves::On),
        scan(Species::Pine, 34, Leaves::Off),
    );
    assert_eq!(on, off, "a pine keeps its needles");
}

#[test]
fn twigs_stop_at_the_bark_of_the_stem() {
    // No lateral passes into the trunk's wood from outside it (Weber & Penn's
    // productions would let a twig bent towards the trunk grow through it).
    for species in Species::ALL {
        for seed in 1..=4 {
            let t = tree(species, seed);
            let orders = t.branch_orders();
            let stem: Vec<(NodeId, NodeId)> = t
                .internodes()
                .filter(|&(_, c)| orders[c.index()] == 0)
                .collect();
            let in_stem = |id: NodeId| {
                let p = t.position(id);
                stem.iter().any(|&(a, b)| {
                    let (pa, pb) = (t.position(a), t.position(b));
                    let f = ((p - pa).dot(pb - pa) / pa.distance_squared(pb)).clamp(0.0, 1.0);
                    let r = t.radius(a) + f * (t.radius(b) - t.radius(a));
                    pa.lerp(pb, f).distance(p) < r
                })
            };
            for (parent, child) in t.internodes() {
                if orders[child.index()] > 0 && orders[parent.index()] > 0 {
                    assert!(
                        !in_stem(child) || in_stem(parent),
                        "{species} seed {seed}: node {child:?} enters the stem"
                    );
                }
            }
        }
    }
}
