//! Property tests: random and mutated bytes into every reader give `Ok` or a
//! typed error, never a panic (the CI stand-in for `cargo fuzz`); clean-up
//! passes keep their invariants on random clouds.

use std::io::Cursor;

use glam::{DVec3, Vec3};
use proptest::prelude::*;
use silva::cloud::clean::{
    IsolatedGroups, occupied_voxels, remove_isolated_groups, remove_near_duplicates,
    remove_statistical_outliers, voxel_downsample,
};
use silva::cloud::{CloudError, Format, PointCloud, ReadOptions, read_as, read_bytes};

const SAMPLES: [&str; 7] = [
    "tiny.xyz",
    "ascii.ply",
    "binary_le_float.ply",
    "binary_be_double.ply",
    "tiny.las",
    "tiny.laz",
    "v12_format1.laz",
];

fn sample(i: usize) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(SAMPLES[i % SAMPLES.len()]);
    std::fs::read(path).unwrap()
}

fn opts() -> ReadOptions {
    ReadOptions { max_points: 10_000 }
}

/// Whatever the reader returns, a cloud it accepts is finite and non-empty.
fn check(result: Result<PointCloud, CloudError>) {
    if let Ok(cloud) = result {
        assert!(!cloud.is_empty());
        assert!(cloud.points.iter().all(|p| p.is_finite()));
        assert!(cloud.offset.is_finite());
    }
}

/// A mutation of a valid file: overwrite, truncate, or insert bytes.
#[derive(Debug, Clone)]
enum Mutation {
    Set(usize, u8),
    Truncate(usize),
    Insert(usize, Vec<u8>),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Set(i, b)),
        1 => any::<usize>().prop_map(Mutation::Truncate),
        1 => (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
    ]
}

fn apply(mut bytes: Vec<u8>, mutations: &[Mutation]) -> Vec<u8> {
    for m in mutations {
        let n = bytes.len().max(1);
        match m {
            Mutation::Set(i, b) => {
                if let Some(x) = bytes.get_mut(i % n) {
                    *x = *b;
                }
            }
            Mutation::Truncate(i) => bytes.truncate(i % n),
            Mutation::Insert(i, b) => {
                let at = (i % n).min(bytes.len());
                bytes.splice(at..at, b.iter().copied());
            }
        }
    }
    bytes
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_never_panic(data in prop::collection::vec(any::<u8>(), 0..2048)) {
        for format in [Format::Xyz, Format::Ply, Format::Las] {
            check(read_as(Cursor::new(&data), format, &opts()));
        }
        check(read_bytes(&data, &opts()).map(|(c, _)| c));
    }

    #[test]
    fn mutated_samples_never_panic(
        which in 0..SAMPLES.len(),
        mutations in prop::collection::vec(mutation(), 1..6),
    ) {
        let data = apply(sample(which), &mutations);
        check(read_bytes(&data, &opts()).map(|(c, _)| c));
    }

    #[test]
    fn random_text_lines_never_panic(text in "([-+0-9.eEnaif, \t#]{0,40}\r?\n){0,20}") {
        check(read_as(Cursor::new(text.as_bytes()), Format::Xyz, &opts()));
    }

    #[test]
    fn clean_up_passes_keep_invariants(
        raw in prop::collection::vec((-5i32..5, -5i32..5, -5i32..5), 0..300),
        voxel_m in 0.05f32..3.0,
    ) {
        // Coarse integer grid: many exact duplicates, the hard case.
        let pts: Vec<Vec3> = raw.iter().map(|&(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) * 0.1).collect();
        let mut cloud = PointCloud::from_points(DVec3::new(1000.0, 2000.0, 0.0), pts);
        // Tag each point with its index to check that attributes travel along.
        cloud.intensity = Some((0..cloud.len()).map(|i| i as u16).collect());

        let dedup = remove_near_duplicates(&cloud, 0.001);
        let mut unique = cloud.points.clone();
        unique.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
        unique.dedup();
        prop_assert_eq!(dedup.len(), unique.len());

        let down = voxel_downsample(&cloud, voxel_m);
        prop_assert!(down.len() <= dedup.len());
        prop_assert_eq!(occupied_voxels(&cloud.points, voxel_m), down.len());
        let outliers = remove_statistical_outliers(&cloud, 4, 2.0);
        prop_assert!(outliers.len() <= cloud.len());
        for out in [&dedup, &down, &outliers] {
            // Survivors are original points, in input order, with their attributes.
            let tags = out.intensity.as_ref().unwrap();
            prop_assert_eq!(tags.len(), out.len());
            prop_assert!(tags.windows(2).all(|w| w[0] < w[1]));
            for (p, &tag) in out.points.iter().zip(tags) {
                prop_assert_eq!(*p, cloud.points[usize::from(tag)]);
            }
        }
    }

    /// A block of returns with a few strays more than the gap above it:
    /// the strays go, all of them and nothing else (the random clouds
    /// below often drop nothing, or everything, and so check nothing).
    #[test]
    fn strays_above_a_block_are_dropped(
        side in 5usize..10,
        raw in prop::collection::vec((-8i32..8, -8i32..8, 0i32..40), 1..=8),
        gap_m in 0.5f32..6.0,
    ) {
        let step = 0.25;
        let mut pts: Vec<Vec3> = (0..side * side * side)
            .map(|k| Vec3::new((k % side) as f32, (k / side % side) as f32, (k / side / side) as f32) * step)
            .collect();
        let block = pts.len();
        let top = (side - 1) as f32 * step;
        pts.extend(raw.iter().map(|&(x, y, z)| Vec3::new(x as f32, y as f32, top + gap_m + 0.01 + z as f32 * 0.1)));
        let cloud = PointCloud::from_points(DVec3::new(1000.0, 2000.0, 0.0), pts);
        let rule = IsolatedGroups { min_gap_m: gap_m, gap_spacings: 0.0, max_group: 8, max_share: 0.01 };
        let (kept, strays) = remove_isolated_groups(&cloud, &rule).expect("strays to drop");
        prop_assert_eq!((strays.above, strays.below, strays.beside), (raw.len(), 0, 0));
        prop_assert_eq!(&kept.points[..], &cloud.points[..block]);
    }

    /// Whatever the cloud, a dropped return has no kept return within the
    /// gap, the survivors are original points in input order, and no more
    /// than the share (or one group) goes.
    #[test]
    fn isolated_groups_lie_apart_from_what_is_kept(
        raw in prop::collection::vec((-40i32..40, -40i32..40, -40i32..40), 1..200),
        gap_m in 0.5f32..6.0,
        max_group in 1usize..10,
        share in 0.0f32..0.5,
    ) {
        let pts: Vec<Vec3> = raw.iter().map(|&(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) * 0.25).collect();
        let mut cloud = PointCloud::from_points(DVec3::new(1000.0, 2000.0, 0.0), pts);
        cloud.intensity = Some((0..cloud.len()).map(|i| i as u16).collect());
        let rule = IsolatedGroups { min_gap_m: gap_m, gap_spacings: 0.0, max_group, max_share: share };
        let Some((kept, strays)) = remove_isolated_groups(&cloud, &rule) else {
            return Ok(());
        };
        let dropped = cloud.len() - kept.len();
        prop_assert_eq!(strays.total(), dropped);
        prop_assert!(dropped >= 1 && dropped <= ((cloud.len() as f32 * share) as usize).max(max_group));
        let tags = kept.intensity.as_ref().unwrap();
        prop_assert!(tags.windows(2).all(|w| w[0] < w[1]));
        let is_kept = |i: usize| tags.contains(&(i as u16));
        let dropped_points = cloud.points.iter().enumerate().filter(|&(i, _)| !is_kept(i));
        for (_, p) in dropped_points {
            for q in &kept.points {
                prop_assert!(p.distance(*q) > gap_m, "dropped {} within {} of kept {}", p, gap_m, q);
            }
        }
    }
}
