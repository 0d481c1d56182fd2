//! `silva synth`: a synthetic tree, its true skeleton, and a simulated scan.
//!
//! ```text
//! silva synth --species oak --seed 7 --scan als --density 20 -o cloud.laz --truth skeleton.json
//! ```
//!
//! The tree and the scan are those of [`silva::synth`]; the cloud goes
//! through [`silva::cloud::write_path`] with the anchor as its offset, so
//! georeference and CRS coordinates survive. Prints a one-line JSON summary
//! (tree size, points, density, time) on stdout.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use glam::DVec3;
use silva::synth::{
    AlsOptions, Foliage, Leaves, Species, TlsGround, TlsOptions, TreeParams, generate,
    simulate_als, simulate_tls,
};
use silva::{Anchor, PointCloud, Skeleton};

/// Which scanner to simulate (`silva synth` and `silva eval`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Scan {
    /// Terrestrial: bark surfaces, millimetre noise, self-occlusion.
    Tls,
    /// Airborne: an AHN3-like clip with crown, few trunk and ground returns.
    Als,
}

/// Scan settings shared by `silva synth` and `silva eval`; unset values take
/// the simulators' defaults.
#[derive(Debug, Clone, clap::Args)]
pub struct ScanArgs {
    /// Point density in points/m²: of clip area for ALS (default 20), of bark
    /// surface for TLS (default 150).
    #[arg(long)]
    density: Option<f32>,
    /// Gaussian noise standard deviation in metres (default 0.05 ALS, 0.003 TLS).
    #[arg(long)]
    noise: Option<f32>,
    /// TLS: keep points that no scanner could see (a clean, complete scan).
    #[arg(long)]
    no_occlusion: bool,
    /// TLS: also scan the ground, as a plot scan holds it: a disc of this
    /// radius in metres around the trunk base (default: no ground, a tree
    /// already cut out of its plot).
    #[arg(long)]
    ground_radius: Option<f32>,
    /// Slope of the ground in degrees, rising along +x through the trunk
    /// base (ALS clips and TLS ground; default 0, level).
    #[arg(long)]
    ground_slope: Option<f32>,
    /// ALS: leaf state of deciduous crowns; conifers keep their needles.
    /// `off` (bare twigs) as AHN, flown in winter and early spring.
    #[arg(long, value_enum, default_value_t = Leaves::Off)]
    pub leaves: Leaves,
    /// Scan with another draw of the scanner's randomness (0: the draw of
    /// the seed alone; see `silva::synth::scan_seed`). The tree stays the
    /// same, so draws 0, 1, 2… show how much a figure owes to which returns
    /// a scan happened to record.
    #[arg(long, default_value_t = 0)]
    pub scan_draw: u64,
}

impl ScanArgs {
    /// Refuses densities and noise levels no simulator should be asked for.
    pub fn validate(&self) -> anyhow::Result<()> {
        if let Some(d) = self.density {
            if !(d.is_finite() && d > 0.0 && d <= 10_000.0) {
                bail!("--density must be a number of points/m² in (0, 10000], got {d}");
            }
        }
        if let Some(n) = self.noise {
            if !(n.is_finite() && (0.0..=1.0).contains(&n)) {
                bail!("--noise must be a standard deviation in metres in [0, 1], got {n}");
            }
        }
        if let Some(r) = self.ground_radius {
            if !(r.is_finite() && (0.0..=50.0).contains(&r)) {
                bail!("--ground-radius must be a radius in metres in [0, 50], got {r}");
            }
        }
        if let Some(s) = self.ground_slope {
            if !(s.is_finite() && (0.0..=60.0).contains(&s)) {
                bail!("--ground-slope must be an angle in degrees in [0, 60], got {s}");
            }
        }
        Ok(())
    }

    /// The ground's rise per metre along x and y.
    fn slope(&self) -> glam::Vec2 {
        let degrees = self.ground_slope.unwrap_or(0.0);
        glam::Vec2::new(degrees.to_radians().tan(), 0.0)
    }

    /// The terrestrial simulator's options.
    pub fn tls(&self) -> TlsOptions {
        let defaults = TlsOptions::default();
        TlsOptions {
            points_per_m2: self.density.unwrap_or(defaults.points_per_m2),
            noise_sd_m: self.noise.unwrap_or(defaults.noise_sd_m),
            occlusion: !self.no_occlusion,
            ground: self.ground_radius.map(|radius_m| TlsGround {
                radius_m,
                slope: self.slope(),
            }),
            ..defaults
        }
    }

    /// The airborne simulator's options for a tree of `species`.
    pub fn als(&self, species: Species) -> AlsOptions {
        let defaults = AlsOptions::default();
        AlsOptions {
            density_pts_per_m2: self.density.unwrap_or(defaults.density_pts_per_m2),
            noise_sd_m: self.noise.unwrap_or(defaults.noise_sd_m),
            foliage: Foliage::for_species(species, self.leaves),
            ground_slope: self.slope(),
            ..defaults
        }
    }
}

/// Arguments of `silva synth`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Species preset.
    #[arg(long, value_enum, default_value_t = Species::Oak)]
    species: Species,
    /// Random seed; the same seed gives the same tree and scan everywhere.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Scanner to simulate; needed with `-o`.
    #[arg(long, value_enum)]
    scan: Option<Scan>,
    #[command(flatten)]
    settings: ScanArgs,
    /// ALS: set class 2 on ground returns and 1 elsewhere (default: unclassified).
    #[arg(long)]
    classify_ground: bool,
    /// Trunk base position in the CRS, as `x,y,z` in metres.
    #[arg(long, value_parser = parse_anchor, default_value = "0,0,0")]
    anchor: DVec3,
    /// Coordinate reference system of the anchor, e.g. `EPSG:28992`.
    #[arg(long)]
    crs: Option<String>,
    /// Write the simulated cloud here; the format follows the extension
    /// (.xyz, .txt, .ply, .las, .laz).
    #[arg(short = 'o', long = "output")]
    output: Option<PathBuf>,
    /// Write the true skeleton as silva skeleton JSON to this file.
    #[arg(long)]
    truth: Option<PathBuf>,
}

/// Generates the tree, simulates the scan, writes the outputs and prints a
/// summary.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.truth.is_none() && args.scan.is_none() {
        bail!("nothing to do: give --truth FILE and/or --scan tls|als");
    }
    if let Some(path) = &args.output {
        if args.scan.is_none() {
            bail!(
                "-o {} needs a scan: add --scan tls or --scan als",
                path.display()
            );
        }
        if silva::cloud::format_for_path(path).is_none() {
            bail!(
                "cannot choose an output format for {}: use .xyz, .txt, .ply, .las or .laz",
                path.display()
            );
        }
    }
    let started = Instant::now();
    let anchor = Anchor {
        origin: args.anchor,
        crs: args.crs.clone(),
    };
    let tree = generate(&TreeParams::preset(args.species), args.seed, anchor);
    if let Some(path) = &args.truth {
        std::fs::write(path, tree.to_json())
            .with_context(|| format!("writing the true skeleton to {}", path.display()))?;
    }
    let scan = args
        .scan
        .map(|scan| simulate(&tree, scan, &args))
        .transpose()?;
    if let (Some(path), Some(scan)) = (&args.output, &scan) {
        silva::cloud::write_path(&scan.cloud, path)
            .with_context(|| format!("writing the simulated cloud to {}", path.display()))?;
    }
    let summary = summary(&tree, &args, scan.as_ref(), started);
    println!("{summary}");
    Ok(())
}

/// A simulated cloud with the clip area it covers (ALS only).
struct Simulated {
    cloud: PointCloud,
    clip_area_m2: Option<f32>,
}

fn simulate(tree: &Skeleton, scan: Scan, args: &Args) -> anyhow::Result<Simulated> {
    args.settings.validate()?;
    let scan_seed = silva::synth::scan_seed(args.seed, args.settings.scan_draw);
    Ok(match scan {
        Scan::Tls => Simulated {
            cloud: simulate_tls(tree, &args.settings.tls(), scan_seed),
            clip_area_m2: None,
        },
        Scan::Als => {
            let opts = AlsOptions {
                classify_ground: args.classify_ground,
                ..args.settings.als(args.species)
            };
            let half = opts.clip_half_width_m(tree);
            Simulated {
                cloud: simulate_als(tree, &opts, scan_seed),
                clip_area_m2: Some(4.0 * half * half),
            }
        }
    })
}

fn summary(
    tree: &Skeleton,
    args: &Args,
    scan: Option<&Simulated>,
    started: Instant,
) -> serde_json::Value {
    let (_, top) = tree.bounds();
    let mut out = serde_json::json!({
        "species": args.species.name(),
        "seed": args.seed,
        "internodes": tree.internode_count(),
        "height_m": top.z,
        "base_radius_m": tree.radius(silva::NodeId::ROOT),
    });
    if let Some(s) = scan {
        out["scan_draw"] = args.settings.scan_draw.into();
        out["points"] = s.cloud.len().into();
        if let Some(area) = s.clip_area_m2 {
            out["clip_area_m2"] = area.into();
            out["leaves"] = serde_json::to_value(args.settings.leaves).unwrap_or_default();
            out["density_pts_per_m2"] = (s.cloud.len() as f32 / area).into();
        }
    }
    out["elapsed_s"] = started.elapsed().as_secs_f64().into();
    out
}

/// Parses `x,y,z` into a finite point.
fn parse_anchor(text: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y, z] = parts[..] else {
        return Err(format!("expected x,y,z, got {text:?}"));
    };
    let num = |s: &str| {
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{s:?} is not a finite number"))
    };
    Ok(DVec3::new(num(x)?, num(y)?, num(z)?))
}
