//! Where the bytes of a compressed DBF6 chain code go, per skeleton JSON file:
//! `cargo run --release --example chaincode_breakdown -- a.json b.json …`
//! (`CC_R=3` for another resolution, `CC_D=0.02` for a fixed voxel size in
//! metres, `CC_VOX=nearest|predictive|optimised` for a voxel choice).

use silva::Skeleton;
use silva::encode::chaincode::{self, ChainOptions, Resolution, Voxelisation};

fn entropy_bits(counts: &[usize]) -> f64 {
    let n: usize = counts.iter().sum();
    counts
        .iter()
        .filter(|&&c| c > 0)
        .map(|&c| {
            let p = c as f64 / n as f64;
            -(c as f64) * p.log2()
        })
        .sum()
}

/// Median of [`Skeleton::turning_angles_deg`] (NaN without any).
fn median_turn_deg(s: &Skeleton) -> f32 {
    let mut turns = s.turning_angles_deg();
    if turns.is_empty() {
        return f32::NAN;
    }
    let mid = turns.len() / 2;
    *turns.select_nth_unstable_by(mid, f32::total_cmp).1
}

fn main() {
    let r: f32 = std::env::var("CC_R")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5.0);
    for path in std::env::args().skip(1) {
        let text = std::fs::read_to_string(&path).expect("readable file");
        let s = Skeleton::from_json(&text).expect("skeleton JSON");
        let voxel = std::env::var("CC_D").ok().and_then(|v| v.parse().ok());
        let opts = ChainOptions {
            resolution: voxel.map_or(Resolution::PerInternode(r), Resolution::VoxelSize),
            voxelisation: match std::env::var("CC_VOX").as_deref() {
                Ok("nearest") => Voxelisation::Nearest,
                Ok("predictive") => Voxelisation::Predictive,
                Ok("optimised") => Voxelisation::Optimised,
                _ => ChainOptions::default().voxelisation,
            },
            ..ChainOptions::default()
        };
        let code = chaincode::encode(&s, &opts).expect("encodable");
        let sz = code.compressed_sizes();
        let n = s.internode_count().max(1) as f64;
        let mut counts = [0usize; 9];
        for &c in code.symbols() {
            counts[usize::from(c)] += 1;
        }
        let lens: Vec<f32> = s.ids().skip(1).map(|i| s.internode_length(i)).collect();
        let mean = lens.iter().sum::<f32>() / lens.len().max(1) as f32;
        let zero = lens.iter().filter(|&&l| l == 0.0).count();
        let cv = (lens.iter().map(|l| (l - mean).powi(2)).sum::<f32>() / lens.len().max(1) as f32)
            .sqrt()
            / mean;
        let forks = s.ids().filter(|&i| s.is_fork(i)).count();
        let tips = s.ids().filter(|&i| s.is_tip(i)).count();
        println!(
            "{path}: internodes {} forks {forks} tips {tips} zero-length {zero} mean len {mean:.3} m cv {cv:.2} median turn {:.0} deg",
            s.internode_count(),
            median_turn_deg(&s)
        );
        println!(
            "  kind {} total {} B = {:.3} B/in; header {} B ({:.3}), meta {} B ({:.3}), structure {} B ({:.3}), moves {} B ({:.3}), radii {} B ({:.3})",
            sz.kind,
            sz.total_bytes,
            sz.total_bytes as f64 / n,
            sz.header_bytes,
            sz.header_bytes as f64 / n,
            sz.metadata_bytes,
            sz.metadata_bytes as f64 / n,
            sz.structure_bits / 8,
            sz.structure_bits as f64 / 8.0 / n,
            sz.move_bits / 8,
            sz.move_bits as f64 / 8.0 / n,
            sz.radius_bits / 8,
            sz.radius_bits as f64 / 8.0 / n,
        );
        let layouts: Vec<String> = chaincode::RadiusLayout::ALL
            .into_iter()
            .filter_map(|l| {
                let bytes = code.compress_split_with(l)?;
                Some(format!(
                    "{l:?} {} B ({:.3})",
                    bytes.len(),
                    bytes.len() as f64 / n
                ))
            })
            .collect();
        if !layouts.is_empty() {
            println!(
                "  kind 3 by radius layout (written: {:?}): {}",
                sz.radius_layout,
                layouts.join(", ")
            );
        }
        if let Some(v1) = code.compress_split_v1() {
            println!(
                "  container version 1 split form (kind 2): {} B = {:.3} B/in",
                v1.len(),
                v1.len() as f64 / n
            );
        }
        println!(
            "  paper's single-string form (kind 1): {} B = {:.3} B/in",
            code.compress_single_string().len(),
            code.compress_single_string().len() as f64 / n
        );
        println!(
            "  symbols {} ({:.2}/in), counts {:?}, order-0 entropy {:.0} B",
            code.symbols().len(),
            code.symbols().len() as f64 / n,
            counts,
            entropy_bits(&counts) / 8.0
        );
        let mut rc = std::collections::HashMap::new();
        for &q in code.radii_q() {
            *rc.entry(q).or_insert(0usize) += 1;
        }
        let rcounts: Vec<usize> = rc.values().copied().collect();
        println!(
            "  radii distinct {} order-0 entropy {:.0} B, max q {}",
            rc.len(),
            entropy_bits(&rcounts) / 8.0,
            code.radii_q().iter().max().unwrap()
        );
    }
}
