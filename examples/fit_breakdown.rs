//! Where the points that the cylinders miss lie:
//! `cargo run --release --example fit_breakdown -- tree.xyz [out.csv]`.
//!
//! Reconstructs the cloud in dense mode, prints the cylinder fit
//! ([`silva::eval::fit::surface_fit`]) and sorts every point farther than
//! 5 cm from all cylinder surfaces by what lies near it:
//! - `fat`: inside a cylinder, more than 5 cm from its bark (radius too large);
//! - `thin`: beside a cylinder, within 3 × its radius + 10 cm of its axis
//!   (radius too small, or the axis off-centre);
//! - `end`: beyond the end of the nearest internode (tips and forks);
//! - `bare`: no cylinder axis within 3 × radius + 10 cm (a pruned or missed
//!   twig), split by whether the point has 5 or more neighbours within 5 cm;
//!
//! and prints the classes by height, and the fit the same skeleton would get
//! with every internode's radius set to the median distance of its nearest
//! points to its axis (what better radii alone could give). With a second
//! argument, writes `x,y,z,distance,class` per point.

use std::path::Path;

use glam::Vec3;
use silva::cloud::{ReadOptions, read_path};
use silva::eval::fit::surface_fit;
use silva::reconstruct::{Mode, Options, reconstruct};
use silva::skeleton::{NodeId, Skeleton};
use silva::spatial::PointIndex;

/// One internode: axis ends and radii.
struct Cone {
    a: Vec3,
    b: Vec3,
    ra: f32,
    rb: f32,
}

/// Where a point lies relative to one cone.
struct Near {
    /// Distance to the axis segment.
    axis: f32,
    /// Position along the axis, 0–1 (outside: beyond an end).
    t: f32,
    /// The cone's radius there (clamped to the ends).
    radius: f32,
}

impl Cone {
    fn near(&self, p: Vec3) -> Near {
        let ab = self.b - self.a;
        let len2 = ab.length_squared().max(1e-12);
        let t = (p - self.a).dot(ab) / len2;
        let tc = t.clamp(0.0, 1.0);
        Near {
            axis: p.distance(self.a + ab * tc),
            t,
            radius: self.ra + (self.rb - self.ra) * tc,
        }
    }

    fn surface(&self, p: Vec3) -> f32 {
        let n = self.near(p);
        if (0.0..=1.0).contains(&n.t) {
            (n.axis - n.radius).abs()
        } else {
            n.axis.max(0.0) // beyond an end: about the distance to the disc
        }
    }
}

fn cones(s: &Skeleton) -> Vec<(NodeId, Cone)> {
    s.internodes()
        .map(|(p, c)| {
            (
                c,
                Cone {
                    a: s.position(p),
                    b: s.position(c),
                    ra: s.radius(p),
                    rb: s.radius(c),
                },
            )
        })
        .collect()
}

fn env(name: &str) -> Option<f32> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn options() -> Options {
    let mut o = Options {
        mode: Mode::Dense,
        ..Options::default()
    };
    if let Some(v) = env("MIN_BRANCH_BINS") {
        o.dense.min_branch_bins = v;
    }
    if let Some(v) = env("SIMPLIFY_BINS") {
        o.dense.simplify_bins = v;
    }
    if let Some(v) = env("SIMPLIFY_SPREADS") {
        o.dense.simplify_spreads = v;
    }
    if let Some(v) = env("BIN_SPACINGS") {
        o.dense.bin_spacings = v;
    }
    if let Some(v) = env("RING_WINDOW") {
        o.dense.ring_window_bins = v as u32;
    }
    if let Some(v) = env("BROKEN_PIECES") {
        o.dense.broken_ring_pieces = v as u32;
    }
    if let Some(v) = env("MERGE_ARCS") {
        o.dense.merge_overlapping_arcs = v > 0.0;
    }
    if let Some(v) = env("NEIGHBOURS") {
        o.dense.neighbours = v as usize;
    }
    if let Some(v) = env("MEASURED") {
        o.radii.measured_radii = v > 0.0;
    }
    o
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (cloud, _) = read_path(Path::new(&args[0]), &ReadOptions::default()).expect("cloud");
    let rec = reconstruct(&cloud, &options()).expect("reconstruction");
    let s = &rec.skeleton;
    let fit = surface_fit(s, &cloud);
    println!(
        "{}: {} nodes, {} points, <2cm {:.1}%, <5cm {:.1}%, mean {:.1} cm, supp {:.1}%, area {:.2} m²",
        args[0],
        s.len(),
        cloud.len(),
        100.0 * fit.within_2cm,
        100.0 * fit.within_5cm,
        100.0 * fit.mean_distance_m,
        100.0 * fit.supported_share,
        fit.surface_area_m2
    );
    let pts = cloud.rebased(s.anchor().origin).points;
    let cs = cones(s);
    let index = PointIndex::new(&pts);
    let mut classes: Vec<(&str, f32)> = Vec::with_capacity(pts.len());
    // Per internode, the distances of its nearest points to its axis.
    let mut axis_d: Vec<Vec<f32>> = vec![Vec::new(); s.len()];
    for &p in &pts {
        let d = cs
            .iter()
            .map(|(_, c)| c.surface(p))
            .fold(f32::INFINITY, f32::min);
        let (ka, near) = cs
            .iter()
            .enumerate()
            .map(|(k, (_, c))| (k, c.near(p)))
            .min_by(|x, y| x.1.axis.total_cmp(&y.1.axis))
            .unwrap();
        axis_d[cs[ka].0.index()].push(near.axis);
        let class = if d <= 0.05 {
            "ok"
        } else if near.axis > 3.0 * near.radius + 0.10 {
            if index.within(p, 0.05).len() > 5 {
                "bare"
            } else {
                "bare-sparse"
            }
        } else if !(0.0..=1.0).contains(&near.t) {
            "end"
        } else if near.axis < near.radius {
            "fat"
        } else {
            "thin"
        };
        classes.push((class, d));
    }
    let names = ["ok", "fat", "thin", "end", "bare", "bare-sparse"];
    let count = |c: &str| classes.iter().filter(|x| x.0 == c).count();
    for c in names {
        println!(
            "  {c:12} {:6} ({:.1}%)",
            count(c),
            100.0 * count(c) as f32 / pts.len() as f32
        );
    }
    // By height.
    let top = pts.iter().map(|p| p.z).fold(0.0, f32::max);
    println!("  height band: points, then misses per class");
    for band in 0..10 {
        let (lo, hi) = (top * band as f32 / 10.0, top * (band + 1) as f32 / 10.0);
        let inside: Vec<usize> = (0..pts.len())
            .filter(|&i| pts[i].z >= lo && (pts[i].z < hi || band == 9))
            .collect();
        let per: Vec<String> = names[1..]
            .iter()
            .map(|c| {
                format!(
                    "{c}={}",
                    inside.iter().filter(|&&i| classes[i].0 == *c).count()
                )
            })
            .collect();
        println!(
            "  {lo:5.2}-{hi:5.2} m {:5}  {}",
            inside.len(),
            per.join(" ")
        );
    }
    // Radii: thin-class misses by the radius of their cylinder.
    let mut ideal = s.clone();
    for id in s.ids().skip(1) {
        let d = &mut axis_d[id.index()];
        if d.len() >= 3 {
            let mid = d.len() / 2;
            let m = *d.select_nth_unstable_by(mid, f32::total_cmp).1;
            ideal.set_radius(id, m);
        }
    }
    let f = surface_fit(&ideal, &cloud);
    println!(
        "  with median-distance radii: <2cm {:.1}%, <5cm {:.1}%, supp {:.1}%",
        100.0 * f.within_2cm,
        100.0 * f.within_5cm,
        100.0 * f.supported_share
    );
    if let Some(out) = args.get(1) {
        let mut text = String::from("x,y,z,distance,class\n");
        for (p, (c, d)) in pts.iter().zip(&classes) {
            text.push_str(&format!("{},{},{},{d},{c}\n", p.x, p.y, p.z));
        }
        std::fs::write(out, text).expect("writable");
    }
}
