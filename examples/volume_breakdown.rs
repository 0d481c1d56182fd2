//! Where a synthetic tree's reconstructed wood volume differs from the truth:
//! `cargo run --release --example volume_breakdown -- [trees] [clean|default|als] [seed]`.
//!
//! Generates the trees `silva eval --synthetic N` makes (species in turn,
//! seed `seed + i`), scans them (`clean`: TLS at 1000 pts/m² without
//! occlusion; `default`: the default occluded TLS scan; `als`: the default
//! airborne scan), reconstructs them and samples both skeletons every 2 cm
//! along their internodes, each sample carrying the volume of its slice
//! (π r² ds, r interpolated as in
//! [`silva::reconstruct::metrics::wood_volume_m3`]). Each reconstructed
//! sample is matched to the nearest true sample when it lies within 10 cm
//! plus the true radius there; unmatched samples are skeleton length with
//! no truth nearby.
//!
//! Prints per tree and for all trees together, by the true radius class and
//! by height: the true volume, the part of it recalled (a reconstructed
//! sample within the tolerance), the reconstructed volume matched to that
//! class, the length ratio (matched reconstructed over recalled true
//! length: > 1 means duplicated skeleton) and the RMS-radius ratio
//! (√(mean r²) of the matched reconstruction over that of the recalled
//! truth), the volume change from the radii (`dV_radius`: reconstructed
//! minus true radius at the matched samples) and from the length
//! (`dV_length`), and the volume of reconstructed samples thinner than half
//! their match (`V_thin`, `Vt_thin` with the true radius: a lateral's base
//! or a spur inside a thicker branch). Then the trunk (the root's chain of
//! main extensions) alone, and the tip counts.

use glam::{DVec3, Vec3};
use silva::eval::run::SyntheticTree;
use silva::reconstruct::metrics::wood_volume_m3;
use silva::reconstruct::{Options, reconstruct};
use silva::skeleton::{NodeId, Skeleton};
use silva::spatial::PointIndex;
use silva::synth::{AlsOptions, Foliage, Leaves, TlsOptions, simulate_als, simulate_tls};

/// Sample spacing along internodes, in metres.
const STEP_M: f32 = 0.02;
/// Matching tolerance beyond the true radius, in metres.
const TOLERANCE_M: f32 = 0.10;
/// Upper bounds of the true radius classes, in metres.
const RADIUS_CLASSES: [f32; 6] = [0.01, 0.02, 0.05, 0.10, 0.20, f32::INFINITY];
/// Upper bounds of the height classes above the true base, in metres.
const HEIGHT_CLASSES: [f32; 5] = [2.0, 5.0, 10.0, 15.0, f32::INFINITY];

/// One slice of an internode.
#[derive(Clone, Copy)]
struct Sample {
    at: Vec3,
    radius: f32,
    length: f32,
}

impl Sample {
    fn volume(&self) -> f64 {
        f64::from(std::f32::consts::PI * self.radius * self.radius * self.length)
    }
}

/// Samples every internode of `s` relative to `origin`; a lateral's first
/// internode is a cylinder of the child's radius, as in the volume.
fn samples(s: &Skeleton, origin: DVec3) -> Vec<Sample> {
    let at = |id| (s.absolute_position(id) - origin).as_vec3();
    let mut out = Vec::new();
    for (p, c) in s.internodes() {
        let main = s.children(p).first() == Some(&c);
        let (r1, r2) = (if main { s.radius(p) } else { s.radius(c) }, s.radius(c));
        let (a, b) = (at(p), at(c));
        let n = ((a.distance(b) / STEP_M).ceil() as usize).max(1);
        let length = a.distance(b) / n as f32;
        out.extend((0..n).map(|k| {
            let t = (k as f32 + 0.5) / n as f32;
            Sample {
                at: a.lerp(b, t),
                radius: r1 + (r2 - r1) * t,
                length,
            }
        }));
    }
    out
}

/// Sums of one class.
#[derive(Default, Clone, Copy)]
struct Tally {
    true_volume: f64,
    recalled_volume: f64,
    recalled_length: f64,
    recalled_r2_length: f64,
    rec_volume: f64,
    rec_length: f64,
    rec_r2_length: f64,
    /// Σ π r_true² ds over the matched reconstructed samples.
    rec_true_volume: f64,
    /// Reconstructed volume of samples much thinner than their match.
    thin_volume: f64,
    /// Same, with the matched truth's radius.
    thin_true_volume: f64,
}

impl Tally {
    fn add(&mut self, o: &Tally) {
        self.true_volume += o.true_volume;
        self.recalled_volume += o.recalled_volume;
        self.recalled_length += o.recalled_length;
        self.recalled_r2_length += o.recalled_r2_length;
        self.rec_volume += o.rec_volume;
        self.rec_length += o.rec_length;
        self.rec_r2_length += o.rec_r2_length;
        self.rec_true_volume += o.rec_true_volume;
        self.thin_volume += o.thin_volume;
        self.thin_true_volume += o.thin_true_volume;
    }

    fn row(&self, label: &str, total_true: f64) -> String {
        let rms = |r2l: f64, l: f64| if l > 0.0 { (r2l / l).sqrt() } else { 0.0 };
        let r_true = rms(self.recalled_r2_length, self.recalled_length);
        let r_rec = rms(self.rec_r2_length, self.rec_length);
        format!(
            "{label:>9} {:>8.4} {:>8.4} {:>8.4} {:>+8.4} {:>+6.1}% {:>6.2} {:>6.2} {:>7.4} {:>7.4} {:>+8.4} {:>+8.4} {:>8.4} {:>8.4}",
            self.true_volume,
            self.recalled_volume,
            self.rec_volume,
            self.rec_volume - self.true_volume,
            100.0 * (self.rec_volume - self.true_volume) / total_true,
            self.rec_length / self.recalled_length.max(1e-9),
            r_rec / r_true.max(1e-9),
            r_true,
            r_rec,
            self.rec_volume - self.rec_true_volume,
            self.rec_true_volume - self.true_volume,
            self.thin_volume,
            self.thin_true_volume,
        )
    }
}

const HEADER: &str = "    class   V_true  V_recld    V_rec    dV   dV/Vt  L_rat  r_rat  r_true   r_rec dV_radius dV_length  V_thin Vt_thin";

fn class_of(bounds: &[f32], v: f32) -> usize {
    bounds
        .iter()
        .position(|&b| v < b)
        .unwrap_or(bounds.len() - 1)
}

fn labels(bounds: &[f32], unit: f32, suffix: &str) -> Vec<String> {
    let mut lo = 0.0;
    bounds
        .iter()
        .map(|&b| {
            let l = if b.is_finite() {
                format!("{}-{}{suffix}", lo * unit, b * unit)
            } else {
                format!(">{}{suffix}", lo * unit)
            };
            lo = b;
            l
        })
        .collect()
}

/// Tallies by radius class and by height class, and the unmatched volume
/// and length.
struct Breakdown {
    radius: Vec<Tally>,
    height: Vec<Tally>,
    unmatched_volume: f64,
    unmatched_length: f64,
}

fn breakdown(truth: &Skeleton, rec: &Skeleton) -> Breakdown {
    let origin = truth.anchor().origin;
    let t = samples(truth, origin);
    let r = samples(rec, origin);
    let base_z = truth.position(NodeId::ROOT).z;
    let mut out = Breakdown {
        radius: vec![Tally::default(); RADIUS_CLASSES.len()],
        height: vec![Tally::default(); HEIGHT_CLASSES.len()],
        unmatched_volume: 0.0,
        unmatched_length: 0.0,
    };
    let rec_index = PointIndex::new(&r.iter().map(|s| s.at).collect::<Vec<_>>());
    for s in &t {
        let classes = [
            &mut out.radius[class_of(&RADIUS_CLASSES, s.radius)],
            &mut out.height[class_of(&HEIGHT_CLASSES, s.at.z - base_z)],
        ];
        let recalled = rec_index
            .nearest(s.at)
            .is_some_and(|n| n.distance_sq.sqrt() <= TOLERANCE_M + s.radius);
        for c in classes {
            c.true_volume += s.volume();
            if recalled {
                c.recalled_volume += s.volume();
                c.recalled_length += f64::from(s.length);
                c.recalled_r2_length += f64::from(s.radius * s.radius * s.length);
            }
        }
    }
    let truth_index = PointIndex::new(&t.iter().map(|s| s.at).collect::<Vec<_>>());
    for s in &r {
        let near = truth_index
            .nearest(s.at)
            .filter(|n| n.distance_sq.sqrt() <= TOLERANCE_M + t[n.index].radius);
        let Some(n) = near else {
            out.unmatched_volume += s.volume();
            out.unmatched_length += f64::from(s.length);
            continue;
        };
        let m = t[n.index];
        for c in [
            &mut out.radius[class_of(&RADIUS_CLASSES, m.radius)],
            &mut out.height[class_of(&HEIGHT_CLASSES, m.at.z - base_z)],
        ] {
            c.rec_volume += s.volume();
            c.rec_length += f64::from(s.length);
            c.rec_r2_length += f64::from(s.radius * s.radius * s.length);
            let as_true = Sample {
                radius: m.radius,
                ..*s
            };
            c.rec_true_volume += as_true.volume();
            if s.radius < 0.5 * m.radius {
                c.thin_volume += s.volume();
                c.thin_true_volume += as_true.volume();
            }
        }
    }
    out
}

fn print(b: &Breakdown, true_volume: f64) {
    println!("{HEADER}");
    for (t, l) in b.radius.iter().zip(labels(&RADIUS_CLASSES, 100.0, "cm")) {
        println!("{}", t.row(&l, true_volume));
    }
    for (t, l) in b.height.iter().zip(labels(&HEIGHT_CLASSES, 1.0, "m")) {
        println!("{}", t.row(&l, true_volume));
    }
    println!(
        "unmatched: V {:.4} m³ ({:+.1}% of V_true), L {:.1} m",
        b.unmatched_volume,
        100.0 * b.unmatched_volume / true_volume,
        b.unmatched_length
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let trees: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(8);
    let scan = args.get(2).map_or("clean", String::as_str).to_string();
    let first_seed: u64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1);
    let mut all = Breakdown {
        radius: vec![Tally::default(); RADIUS_CLASSES.len()],
        height: vec![Tally::default(); HEIGHT_CLASSES.len()],
        unmatched_volume: 0.0,
        unmatched_length: 0.0,
    };
    let mut all_true = 0.0;
    for i in 0..trees {
        let SyntheticTree {
            species,
            seed,
            truth,
        } = SyntheticTree::nth(i, first_seed);
        let cloud = match scan.as_str() {
            "clean" => simulate_tls(&truth, &TlsOptions::clean(), seed),
            "als" => {
                let o = AlsOptions {
                    foliage: Foliage::for_species(species, Leaves::default()),
                    ..AlsOptions::default()
                };
                simulate_als(&truth, &o, seed)
            }
            _ => simulate_tls(&truth, &TlsOptions::default(), seed),
        };
        let rec = match reconstruct(&cloud, &Options::default()) {
            Ok(r) => r,
            Err(e) => {
                println!("{}-s{seed}: failed: {e}", species.name());
                continue;
            }
        };
        let vt = f64::from(wood_volume_m3(&truth));
        let vr = f64::from(rec.metrics.wood_volume_m3);
        println!(
            "\n== {}-s{seed} {scan}: V_true {vt:.4} V_rec {vr:.4} ratio {:.3} ({:?})",
            species.name(),
            vr / vt,
            rec.mode
        );
        let b = breakdown(&truth, &rec.skeleton);
        let (tl, tv) = trunk(&truth);
        let (rl, rv) = trunk(&rec.skeleton);
        let tips = |s: &Skeleton| s.ids().filter(|&i| s.is_tip(i)).count();
        println!(
            "trunk chain: true L {tl:.2} V {tv:.4}, rec L {rl:.2} V {rv:.4} \
             (dV {:+.1}% of V_true); tips true {} rec {}",
            100.0 * (rv - tv) / vt,
            tips(&truth),
            tips(&rec.skeleton)
        );
        print(&b, vt);
        for (a, t) in all.radius.iter_mut().zip(&b.radius) {
            a.add(t);
        }
        for (a, t) in all.height.iter_mut().zip(&b.height) {
            a.add(t);
        }
        all.unmatched_volume += b.unmatched_volume;
        all.unmatched_length += b.unmatched_length;
        all_true += vt;
    }
    println!("\n== all trees ({scan}): V_true {all_true:.4}");
    print(&all, all_true);
}

/// Length and volume of the trunk: the root's chain of main extensions.
fn trunk(s: &Skeleton) -> (f64, f64) {
    let (mut l, mut v) = (0.0, 0.0);
    let mut node = NodeId::ROOT;
    while let Some(&c) = s.children(node).first() {
        let h = f64::from(s.internode_length(c));
        let (r1, r2) = (f64::from(s.radius(node)), f64::from(s.radius(c)));
        l += h;
        v += std::f64::consts::PI * h / 3.0 * (r1 * r1 + r1 * r2 + r2 * r2);
        node = c;
    }
    (l, v)
}
