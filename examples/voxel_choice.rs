//! What each chain-code voxel choice gives, per skeleton JSON file: the
//! compressed size, the mean and maximal node error and the encoding time
//! (median of 11), at r = 3, 5 and 10.
//! `cargo run --release --example voxel_choice -- a.json b.json …`

use std::time::Instant;

use silva::Skeleton;
use silva::encode::chaincode::{self, ChainOptions, Resolution, Voxelisation};

fn main() {
    for path in std::env::args().skip(1) {
        let text = std::fs::read_to_string(&path).expect("readable file");
        let s = Skeleton::from_json(&text).expect("skeleton JSON");
        let n = s.internode_count().max(1) as f64;
        println!("{path}: {} internodes", s.internode_count());
        for r in [3.0, 5.0, 10.0] {
            for voxelisation in [
                Voxelisation::Nearest,
                Voxelisation::Predictive,
                Voxelisation::Optimised,
            ] {
                let opts = ChainOptions {
                    resolution: Resolution::PerInternode(r),
                    voxelisation,
                    ..ChainOptions::default()
                };
                let mut times: Vec<f64> = (0..11)
                    .map(|_| {
                        let t = Instant::now();
                        std::hint::black_box(chaincode::encode(&s, &opts).expect("encodable"));
                        t.elapsed().as_secs_f64() * 1e3
                    })
                    .collect();
                times.sort_by(f64::total_cmp);
                let code = chaincode::encode(&s, &opts).expect("encodable");
                let decoded = chaincode::decode(&code).expect("decodable");
                let order = chaincode::encode_order(&s);
                let errors: Vec<f64> = order
                    .iter()
                    .enumerate()
                    .map(|(i, &id)| {
                        let back = decoded.position(silva::NodeId::from_index(i));
                        f64::from(back.distance(s.position(id)))
                    })
                    .collect();
                let mean = errors.iter().sum::<f64>() / errors.len() as f64;
                let max = errors.iter().copied().fold(0.0, f64::max);
                let bytes = code.compress().len();
                println!(
                    "  r {r:>4} {voxelisation:<10?} {bytes:>6} B {:.3} B/in  mean error {:.4} m  max {:.4} m (bound {:.4})  encode {:.2} ms",
                    bytes as f64 / n,
                    mean,
                    max,
                    code.error_bound_m(),
                    times[5]
                );
            }
        }
    }
}
