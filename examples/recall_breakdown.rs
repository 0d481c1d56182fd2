//! Where the truth that a reconstruction misses lies:
//! `cargo run --release --example recall_breakdown -- SPECIES SEED [out.csv]`.
//!
//! Makes the tree and scan of `silva eval --synthetic N --scan tls
//! --density 1000 --no-occlusion` (species and seed as there; with
//! `DEFAULT_TLS=1`, the occluded 150 pts/m² scan of `--scan tls`; with
//! `SCAN=als`, the leaf-off scan of `--scan als`), reconstructs it, samples
//! the truth every 5 cm and sorts each sample farther than the tolerance
//! (0.1 m; 0.5 m for ALS, where truth thinner than 5 cm does not count)
//! from the reconstruction by its internode's branch order and radius, and by
//! whether scan points lie on its bark (within the radius + 2 cm of its
//! axis). With a third argument, writes `x,y,z,distance,order,radius,points,
//! from_start,axis_len,node` per missed sample (`from_start`: arc length from
//! the start of its branch; `axis_len`: that branch's length); with `DUMP=1`
//! also the truth's and the reconstruction's internodes (`OUT.truth`,
//! `OUT.recon`: both ends, radius, node) and the points (`OUT.points`), all
//! relative to the truth's base. The tree stands at the origin, where `silva
//! eval` anchors it in EPSG:28992, so figures can differ from the report's
//! in the third decimal.
//!
//! What it showed (2026-12-02, on the clean TLS poplars 3, 7 and 11, whose
//! recall is 0.970–0.981): 72–80 % of the missed length lies within 3 cm of
//! the bark of truth wood thicker than 8 cm (the stem), and 54–72 % overlaps
//! it: twigs of the Weber–Penn poplars that bend back onto the stem, and
//! the first decimetres of steep laterals leaving it, both inside the stem's
//! returns. The rest is under 3.5 m per tree. On the airborne oaks that miss
//! recall 0.9 (seeds 5, 21, 29), the trunk and the limbs' first metres are
//! missed where the trunk base is placed 0.4–1.1 m off: birch and oak
//! trunks placed by Eq. 4 (no stem returns under the crown) give 24 of the
//! 32 base misses over seeds 1–600, and 20 of the 40 recall misses (23 of 74
//! before bare crowns stopped being contracted). On the oaks whose base was
//! right, the first 0–2.5 m of the limbs lay 0.5–0.8 m from the
//! reconstruction; that is what leaving a bare crown's candidates on the
//! returns (`airborne::Params::bare_crown_linearity`) mended.
//!
//! On the occluded default scans (`DEFAULT_TLS=1`, 2026-12-04, the ten
//! trees of `silva eval --synthetic 10 --scan tls`, recall 0.753–0.941):
//! 91.8–99.7 % of the missed length has no scan point on its bark (twigs
//! under 1 cm that the scanners did not hit), and the truth that has points
//! on its bark is recalled at 0.992–0.996, the poplars at 0.956–0.957 (the
//! twigs along the stem, as above).
//!
//! Its last line splits the reconstruction's length off the truth
//! (precision). On the same occluded scans (oak 1, birch 2, poplar 3, pine
//! 4: precision 0.832–0.898) most of it lies either by twigs under 1 cm
//! (birch 100 of 112 m, pine 99 of 174 m: straight internodes across
//! sparsely hit, drooping twigs) or by wood 5 cm and thicker (oak 285 of
//! 406 m, poplar 60 of 125 m), and there much of it runs along the bark
//! of wood 10 cm or thicker, on scan points (oak 146 m, poplar 24 m, pine
//! 33 m): thin branches made of a one-sided stem's own bark. The clean
//! scans of oak 1 and poplar 3 (precision 0.992 and 0.993) have 12.3 and
//! 0.6 m of it.
//!
//! A closer look (`DUMP=1`, plotted; 2026-12-04): on oak 1 the thick part
//! is the trunk itself. At 150 pts/m² the point spacing is 4.3 cm and a bin
//! 3 cm, so a 0.42 m trunk's bins fall into pieces of bark that the 1-bin
//! ring window does not join: the trunk's chain zigzags up to 0.4 m off the
//! axis between ring centres and bark pieces, and the pieces sprout spurs.
//! The `dense::Params` that bear on it, set one at a time on the ten
//! trees (reconstructed in `Mode::Dense`, compared at 0.1 m; median recall
//! / precision 0.861 / 0.859 occluded, 0.997 / 0.995 clean):
//! `ring_window_bins` 3 straightens the trunk (occluded 0.853 / 0.932, clean
//! 0.996 / 0.994) but the poplars lose 4–6 points of recall (twigs along the
//! stem join its ring) and `silva eval --data` falls on tree1 from 82.4 to
//! 75.7 % of points within 2 cm, on tree13 from 69.5 to 62.5 % (2 bins:
//! 79.3, 66.0); `bin_spacings` 1.0 gives 0.852 / 0.917; `stem_stub_spreads`
//! 2 gives 0.848 / 0.872; a second, 3-bin window for sections spreading 0.3
//! m or more raises the oaks' and poplars' precision by 1–3 points at no
//! recall, but tree13 loses 1.1 points; `detour_max_nodes` 4 or
//! `detour_thin_share` 0.8 move nothing by 0.2 points. So none went in.
//! The twig tips' part (birch 2: 74 of its 112 m off the truth lies on thin
//! tip internodes) is mostly internodes of about 0.6 m whose two ends lie
//! on different truth twigs (the path along the truth between them at
//! least 3 times longer); dropping tips whose line passes more than 0.25 m
//! from every scan point would remove 42 m off the truth and 44 m on it.
//! Those hops come from the graph: a sparsely hit twig's nearest neighbours
//! lie on the next twig. Cutting its links at 10 point spacings instead of
//! 20 (`dense::Params::max_edge_spacings`, the pieces joined again by one
//! bridge each) took birch 2 to precision 0.937 and recall 0.765, and the
//! 20 default scans of `silva eval --synthetic 20` to a median precision
//! of 0.919 (0.860 before) at a recall of 0.853 (0.862).

use glam::Vec3;
use silva::Anchor;
use silva::reconstruct::{Mode, Options, reconstruct};
use silva::skeleton::{NodeId, Skeleton};
use silva::spatial::PointIndex;
use silva::synth::{
    AlsOptions, Foliage, Leaves, Species, TlsOptions, TreeParams, generate, simulate_als,
    simulate_tls,
};

const STEP_M: f32 = 0.05;

/// A truth sample: where, on which internode (its child node).
struct Sample {
    at: Vec3,
    node: NodeId,
}

fn samples(s: &Skeleton, origin: glam::DVec3) -> Vec<Sample> {
    let shift = (s.anchor().origin - origin).as_vec3();
    let mut out = Vec::new();
    for (parent, child) in s.internodes() {
        let (a, b) = (s.position(parent) + shift, s.position(child) + shift);
        let n = ((a.distance(b) / STEP_M).ceil() as usize).max(1);
        for k in 0..n {
            let t = (k as f32 + 0.5) / n as f32;
            out.push(Sample {
                at: a.lerp(b, t),
                node: child,
            });
        }
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let species: Species = args.get(1).expect("SPECIES").parse().expect("species");
    let seed: u64 = args.get(2).expect("SEED").parse().expect("seed");
    let truth = generate(&TreeParams::preset(species), seed, Anchor::default());
    let airborne = std::env::var("SCAN").is_ok_and(|s| s == "als");
    let (cloud, mode, tolerance_m, min_radius_m) = if airborne {
        let als = AlsOptions {
            foliage: Foliage::for_species(species, Leaves::Off),
            ..AlsOptions::default()
        };
        (simulate_als(&truth, &als, seed), Mode::Airborne, 0.5, 0.05)
    } else {
        let tls = if std::env::var_os("DEFAULT_TLS").is_some() {
            TlsOptions::default()
        } else {
            TlsOptions::clean()
        };
        (simulate_tls(&truth, &tls, seed), Mode::Dense, 0.1, 0.0)
    };
    let opts = Options {
        mode,
        ..Options::default()
    };
    let rec = reconstruct(&cloud, &opts).expect("reconstructs");
    let origin = truth.anchor().origin;
    let t = samples(&truth, origin);
    let r = samples(&rec.skeleton, origin);
    let r_index = PointIndex::new(&r.iter().map(|s| s.at).collect::<Vec<_>>());
    let shift = (cloud.offset - origin).as_vec3();
    let pts: Vec<Vec3> = cloud.points.iter().map(|&p| p + shift).collect();
    let p_index = PointIndex::new(&pts);
    let orders = truth.branch_orders();
    let (from_start, axis_len) = branch_axes(&truth, &orders);

    // (order, radius class, covered) -> (missed m, total m)
    let mut table = std::collections::BTreeMap::<(u32, u8, bool), (f32, f32)>::new();
    let mut csv = String::from("x,y,z,distance,order,radius,points,from_start,axis_len,node\n");
    for s in &t {
        let d = r_index
            .nearest(s.at)
            .map_or(f32::INFINITY, |n| n.distance_sq.sqrt());
        // The eval's filter: the mean of the internode's end radii.
        let (base, tip) = truth.internode_radii(s.node);
        if (base + tip) * 0.5 < min_radius_m {
            continue;
        }
        let radius = truth.radius(s.node);
        let points = p_index
            .within(s.at, radius + silva::eval::compare::BARK_MARGIN_M)
            .len();
        let class = match radius {
            x if x < 0.01 => 0,
            x if x < 0.02 => 1,
            x if x < 0.05 => 2,
            _ => 3,
        };
        let order = orders[s.node.index()];
        let e = table.entry((order, class, points > 0)).or_default();
        e.1 += STEP_M;
        if d > tolerance_m {
            e.0 += STEP_M;
            csv.push_str(&format!(
                "{:.3},{:.3},{:.3},{d:.3},{order},{radius:.4},{points},{:.3},{:.3},{}\n",
                s.at.x,
                s.at.y,
                s.at.z,
                from_start[s.node.index()],
                axis_len[s.node.index()],
                s.node.index()
            ));
        }
    }
    let total: f32 = table.values().map(|v| v.1).sum();
    let missed: f32 = table.values().map(|v| v.0).sum();
    println!(
        "{species:?} seed {seed}: truth {total:.1} m, missed {missed:.2} m (recall {:.4}), {} points",
        1.0 - missed / total,
        cloud.points.len()
    );
    println!("order  radius     covered  missed_m  total_m  share_of_missed");
    let names = ["<1cm", "1-2cm", "2-5cm", ">=5cm"];
    for ((order, class, covered), (m, tot)) in &table {
        if *m > 0.0 {
            println!(
                "{order:>5}  {:>6}  {covered:>10}  {m:8.2}  {tot:7.1}  {:5.1}%",
                names[*class as usize],
                100.0 * m / missed
            );
        }
    }
    let (covered_missed, covered_total) = table
        .iter()
        .filter(|((_, _, covered), _)| *covered)
        .fold((0.0, 0.0), |(m, t), (_, v)| (m + v.0, t + v.1));
    println!(
        "truth with points on its bark: {covered_total:.1} m, recall {:.4}; {:.1} % of the \
         missed length has no point on its bark",
        1.0 - covered_missed / covered_total,
        100.0 * (missed - covered_missed) / missed
    );
    imprecision(&t, &r, &truth, &p_index, tolerance_m);
    if let Some(path) = args.get(3) {
        std::fs::write(path, csv).expect("write csv");
        if std::env::var_os("DUMP").is_some() {
            dump(&format!("{path}.truth"), &truth, origin);
            dump(&format!("{path}.recon"), &rec.skeleton, origin);
            let rows: String = pts
                .iter()
                .map(|p| format!("{},{},{}\n", p.x, p.y, p.z))
                .collect();
            std::fs::write(format!("{path}.points"), rows).expect("write points");
        }
    }
}

/// Where the reconstruction lies off the truth (precision): the length of
/// reconstruction samples farther than the tolerance from every truth
/// sample, by the radius of the nearest truth wood, and how much of it runs
/// along the bark of wood 10 cm or thicker (0.6–1.2 radii from its axis)
/// with a scan point within 5 cm: skeleton made of a thick stem's own bark.
fn imprecision(t: &[Sample], r: &[Sample], truth: &Skeleton, points: &PointIndex, tol: f32) {
    let t_index = PointIndex::new(&t.iter().map(|s| s.at).collect::<Vec<_>>());
    let (mut far, mut on_bark) = (0.0f32, 0.0f32);
    let mut by_radius = [0.0f32; 4];
    for s in r {
        let Some(n) = t_index.nearest(s.at) else {
            return;
        };
        let d = n.distance_sq.sqrt();
        if d <= tol {
            continue;
        }
        far += STEP_M;
        let radius = truth.radius(t[n.index].node);
        by_radius[[0.01, 0.02, 0.05].iter().filter(|&&x| radius >= x).count()] += STEP_M;
        let near_point = points
            .nearest(s.at)
            .is_some_and(|p| p.distance_sq.sqrt() < 0.05);
        if radius >= 0.1 && (0.6..1.2).contains(&(d / radius)) && near_point {
            on_bark += STEP_M;
        }
    }
    let total = r.len() as f32 * STEP_M;
    println!(
        "reconstruction {total:.1} m, off the truth {far:.1} m (precision {:.4}); near truth \
         wood <1 / 1-2 / 2-5 / >=5 cm: {:.1} / {:.1} / {:.1} / {:.1} m; along the bark of wood \
         >=10 cm: {on_bark:.1} m",
        1.0 - far / total,
        by_radius[0],
        by_radius[1],
        by_radius[2],
        by_radius[3]
    );
}

/// Per node: the arc length from its branch's first node (where the branch
/// order last changed) and the length of that branch's axis (main
/// extensions only).
fn branch_axes(s: &Skeleton, orders: &[u32]) -> (Vec<f32>, Vec<f32>) {
    let mut from_start = vec![0.0f32; s.len()];
    let mut start = vec![0usize; s.len()];
    for id in s.depth_first() {
        let i = id.index();
        start[i] = i;
        if let Some(p) = s.parent(id) {
            if orders[p.index()] == orders[i] {
                start[i] = start[p.index()];
                from_start[i] = from_start[p.index()] + s.internode_length(id);
            }
        }
    }
    let mut longest = vec![0.0f32; s.len()];
    for i in 0..s.len() {
        longest[start[i]] = longest[start[i]].max(from_start[i]);
    }
    let axis = (0..s.len()).map(|i| longest[start[i]]).collect();
    (from_start, axis)
}

fn dump(path: &str, s: &Skeleton, origin: glam::DVec3) {
    let shift = (s.anchor().origin - origin).as_vec3();
    let mut out = String::new();
    for (p, c) in s.internodes() {
        let (a, b) = (s.position(p) + shift, s.position(c) + shift);
        out.push_str(&format!(
            "{},{},{},{},{},{},{},{}\n",
            a.x,
            a.y,
            a.z,
            b.x,
            b.y,
            b.z,
            s.radius(c),
            c.index()
        ));
    }
    std::fs::write(path, out).expect("write edges");
}
