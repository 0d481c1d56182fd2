//! Readers and writers on small committed samples (tests/data) and on
//! broken inputs: every failure must name the format and the place.

use std::io::Cursor;
use std::path::PathBuf;

mod cli_support;

use cli_support::{Run, silva};
use glam::{DVec3, Vec3};
use silva::cloud::{
    CloudError, Format, Location, PointCloud, ReadOptions, detect, read_as, read_bytes, read_path,
    read_path_with_details, to_laz_bytes, write_path,
};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(data(name)).unwrap()
}

fn read_ok(name: &str) -> (PointCloud, Format) {
    read_path(&data(name), &ReadOptions::default()).unwrap()
}

fn read_err(name: &str) -> CloudError {
    read_path(&data(name), &ReadOptions::default()).unwrap_err()
}

/// Asserts a `Malformed` error with this format and location.
fn assert_malformed(err: CloudError, format: Format, location: Location) -> String {
    match err {
        CloudError::Malformed {
            format: f,
            location: l,
            reason,
        } => {
            assert_eq!((f, l), (format, location), "reason: {reason}");
            reason
        }
        other => panic!("expected Malformed {format} at {location}, got {other}"),
    }
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).abs().max_element() < 1e-3
}

#[test]
fn xyz_with_comments_commas_tabs_and_no_final_newline() {
    let (cloud, format) = read_ok("tiny.xyz");
    assert_eq!(format, Format::Xyz);
    assert_eq!(cloud.len(), 5);
    assert!(close(
        cloud.absolute(0),
        DVec3::new(85000.125, 446000.5, 0.25)
    ));
    assert!(close(cloud.absolute(2), DVec3::new(85001.0, 446001.0, 1.0)));
    assert!(close(cloud.absolute(4), DVec3::new(85002.0, 446002.0, 2.5)));
    assert!(cloud.intensity.is_none());
}

#[test]
fn ply_ascii_binary_le_float_and_be_double_agree() {
    let (ascii, f1) = read_ok("ascii.ply");
    let (be, f2) = read_ok("binary_be_double.ply");
    let (le, f3) = read_ok("binary_le_float.ply");
    assert_eq!((f1, f2, f3), (Format::Ply, Format::Ply, Format::Ply));
    assert_eq!((ascii.len(), be.len(), le.len()), (6, 6, 6));
    let grid = DVec3::new(155_000.0, 463_000.0, 0.0);
    for i in 0..6 {
        assert!(close(ascii.absolute(i), be.absolute(i)));
        assert!(close(ascii.absolute(i), le.absolute(i) + grid));
    }
    assert_eq!(le.intensity, Some(vec![0, 10, 20, 30, 40, 50]));
}

#[test]
fn las_and_laz_twins_agree_and_keep_attributes() {
    let (las, f1) = read_ok("tiny.las");
    let (laz, f2) = read_ok("tiny.laz");
    assert_eq!((f1, f2), (Format::Las, Format::Laz));
    assert_eq!(las, laz);
    assert_eq!(las.len(), 40);
    let class = las.classification.as_ref().unwrap();
    assert_eq!(class[..6], [2, 2, 2, 2, 2, 5]);
    assert_eq!(las.return_number.as_ref().unwrap()[..4], [1, 2, 3, 1]);
    assert_eq!(las.intensity.as_ref().unwrap()[3], 300);
    let (_, details) = read_path_with_details(&data("tiny.laz"), &ReadOptions::default()).unwrap();
    let las_details = details.las.unwrap();
    assert_eq!(
        (las_details.version.as_str(), las_details.point_format),
        ("1.4", 6)
    );
}

#[test]
fn laz_1_2_point_format_1() {
    let (cloud, format) = read_ok("v12_format1.laz");
    assert_eq!((format, cloud.len()), (Format::Laz, 25));
    assert!(close(
        cloud.absolute(24),
        DVec3::new(129.424, 35.592, 5.072)
    ));
    assert_eq!(cloud.classification.as_ref().unwrap()[0], 5);
}

#[test]
fn detection_ignores_the_file_name() {
    let laz = bytes("tiny.laz");
    assert_eq!(detect(&laz), Some(Format::Laz));
    assert_eq!(detect(&bytes("tiny.las")), Some(Format::Las));
    assert_eq!(detect(&bytes("ascii.ply")), Some(Format::Ply));
    assert_eq!(detect(&bytes("binary_le_float.ply")), Some(Format::Ply));
    assert_eq!(detect(&bytes("tiny.xyz")), Some(Format::Xyz));
    let (cloud, format) = read_bytes(&laz, &ReadOptions::default()).unwrap();
    assert_eq!((format, cloud.len()), (Format::Laz, 40));
}

#[test]
fn nan_coordinate_names_the_line() {
    let reason = assert_malformed(read_err("broken_nan.xyz"), Format::Xyz, Location::Line(3));
    assert!(reason.contains("non-finite"), "{reason}");
}

#[test]
fn missing_column_names_the_line() {
    assert_malformed(
        read_err("broken_columns.xyz"),
        Format::Xyz,
        Location::Line(2),
    );
}

#[test]
fn empty_file_is_an_empty_cloud_error() {
    // Zero bytes: no format can be detected from content, and none is guessed.
    let err = read_err("broken_empty.xyz");
    assert!(
        matches!(&err, CloudError::UnknownFormat(m) if m.contains("empty (0 bytes)")),
        "{err}"
    );
    let err = read_as(Cursor::new(b""), Format::Xyz, &ReadOptions::default()).unwrap_err();
    assert!(matches!(err, CloudError::Empty(Format::Xyz)));
    let comments_only = read_bytes(b"# nothing here\n\n", &ReadOptions::default());
    assert!(matches!(comments_only, Err(CloudError::Empty(Format::Xyz))));
}

#[test]
fn garbage_is_an_unknown_format() {
    let err = read_err("broken_garbage.bin");
    assert!(
        matches!(&err, CloudError::UnknownFormat(m) if m.contains("0x009fff13")),
        "{err}"
    );
}

/// An XYZ file that a Windows editor saved with a UTF-8 byte-order mark
/// reads as without it; a mark anywhere else is still not a number.
#[test]
fn a_byte_order_mark_at_the_start_of_xyz_is_skipped() {
    let (cloud, format) = read_bytes(
        b"\xef\xbb\xbf155000.5 463000 1\n155001 463000 2\n",
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!((format, cloud.len()), (Format::Xyz, 2));
    assert_eq!(cloud.absolute(0).x, 155000.5);
    let err = read_bytes(b"1 2 3\n\xef\xbb\xbf4 5 6\n", &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("line 2: not a number"), "{err}");
}

/// A stray return first in the file (99 km east of the tree) does not
/// become the offset: relative `f32` coordinates 99 km from the tree would
/// keep 8 mm, and the tree's points 0.1 mm apart would merge. The offset
/// is the median of the first points; clouds whose first point lies with
/// the rest keep it as their offset. The 99 km span check still holds.
#[test]
fn a_stray_first_point_is_not_the_offset() {
    let tree: Vec<String> = (0..40)
        .map(|i| format!("155000.{i:04} 463000.{i:04} {}.5", i % 7))
        .collect();
    let file = format!("254000 463000 2\n{}\n", tree.join("\n"));
    let (cloud, _) = read_bytes(file.as_bytes(), &ReadOptions::default()).unwrap();
    assert_eq!(cloud.len(), 41);
    assert!(
        (cloud.offset.x - 155_000.0).abs() <= 1.0,
        "{}",
        cloud.offset
    );
    assert_eq!(cloud.absolute(0).x, 254_000.0);
    for i in 0..40 {
        let p = cloud.absolute(i + 1);
        let expected = 155_000.0 + i as f64 * 1e-4;
        assert!((p.x - expected).abs() < 1e-5, "point {i}: {}", p.x);
    }
    let (plain, _) = read_bytes(tree.join("\n").as_bytes(), &ReadOptions::default()).unwrap();
    assert_eq!(plain.offset, DVec3::new(155_000.0, 463_000.0, 1.0));
    let far = format!("{}\n254000 463000 2\n354001 463000 2\n", tree.join("\n"));
    let err = read_bytes(far.as_bytes(), &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("more than 100 km"), "{err}");
}

/// A skeleton, LsJSON or CityJSON document sent where a cloud belongs is
/// named as JSON, not read as XYZ lines that are too long or not numbers.
#[test]
fn json_is_named_as_json_not_read_as_xyz() {
    for json in [
        &b"{\"lsjson_version\": 1, \"axiom\": \"F(1)\"}"[..],
        b"\xef\xbb\xbf\n  [1.0, 2.0, 3.0]\n",
        b"\r\n{}",
    ] {
        let err = read_bytes(json, &ReadOptions::default()).unwrap_err();
        assert!(
            matches!(&err, CloudError::UnknownFormat(m) if m.contains("is JSON")),
            "{err}"
        );
    }
    let xyz = read_bytes(b"# {not json}\n1 2 3\n", &ReadOptions::default());
    assert_eq!(xyz.map(|(cloud, _)| cloud.len()).ok(), Some(1));
}

#[test]
fn garbage_after_las_signature_is_a_header_error() {
    let reason = assert_malformed(
        read_err("broken_garbage.las"),
        Format::Las,
        Location::Header,
    );
    assert!(reason.contains("truncated"), "{reason}");
}

#[test]
fn las_header_promising_more_points_than_present() {
    let len = bytes("broken_short.las").len() as u64;
    let reason = assert_malformed(
        read_err("broken_short.las"),
        Format::Las,
        Location::Byte(len),
    );
    assert!(reason.contains("promises 40 points"), "{reason}");
}

#[test]
fn las_header_claiming_billions_of_points_allocates_nothing() {
    let mut las = bytes("tiny.las");
    las[107..111].copy_from_slice(&u32::MAX.to_le_bytes()); // legacy point count
    let err = read_bytes(&las, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            CloudError::TooManyPoints {
                format: Format::Las,
                ..
            }
        ),
        "{err}"
    );
    let unlimited = ReadOptions {
        max_points: usize::MAX,
    };
    let err = read_bytes(&las, &unlimited).unwrap_err();
    assert_malformed(err, Format::Las, Location::Byte(las.len() as u64));
}

#[test]
fn las_extended_vlr_longer_than_the_file() {
    // LAS 1.4: point the header at an EVLR that claims 2^62 bytes.
    let mut las = bytes("tiny.las");
    let at = las.len() as u64;
    las[235..243].copy_from_slice(&at.to_le_bytes()); // start of first EVLR
    las[243..247].copy_from_slice(&1u32.to_le_bytes()); // number of EVLRs
    let mut evlr = vec![0u8; 60];
    evlr[20..28].copy_from_slice(&(1u64 << 62).to_le_bytes());
    las.extend_from_slice(&evlr);
    let err = read_bytes(&las, &ReadOptions::default()).unwrap_err();
    let reason = assert_malformed(err, Format::Las, Location::Byte(at));
    assert!(reason.contains("extended VLR"), "{reason}");
}

#[test]
fn truncated_laz_names_the_chunk_table_offset() {
    let reason = assert_malformed(
        read_err("broken_truncated.laz"),
        Format::Laz,
        Location::Byte(874),
    );
    assert!(reason.contains("truncated"), "{reason}");
    assert_malformed(
        read_err("broken_truncated_v12.laz"),
        Format::Laz,
        Location::Byte(440),
    );
}

/// Cuts the compressed points of a single-chunk LAZ in half, keeping the
/// chunk table readable (moved up and re-pointed).
fn cut_laz_points(laz: &[u8]) -> Vec<u8> {
    let data_start = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize;
    let table_start =
        i64::from_le_bytes(laz[data_start..data_start + 8].try_into().unwrap()) as usize;
    let cut = data_start + 8 + (table_start - data_start - 8) / 2;
    let mut broken = laz[..cut].to_vec();
    broken.extend_from_slice(&laz[table_start..]);
    broken[data_start..data_start + 8].copy_from_slice(&(cut as i64).to_le_bytes());
    broken
}

fn laz_error_point(laz: &[u8]) -> u64 {
    match read_bytes(laz, &ReadOptions::default()).unwrap_err() {
        CloudError::Malformed {
            format: Format::Laz,
            location: Location::Point(i),
            ..
        } => i,
        other => panic!("expected a LAZ point error, got {other}"),
    }
}

/// Truncated compressed points. Point-wise LAZ (LAS 1.2, format 1) is
/// decoded point by point and fails at the first point it cannot decode.
/// Layered LAZ (LAS 1.4, format 6, what silva writes) declares each chunk's
/// layer sizes up front, so the cut is found before decoding, at the chunk.
#[test]
fn laz_truncated_inside_the_point_data_names_the_point() {
    let xyz = |i: usize| {
        DVec3::new(
            (i % 50) as f64 * 0.07,
            (i / 50) as f64 * 0.05,
            (i % 7) as f64,
        )
    };
    let pts: Vec<Vec3> = (0..3000).map(|i| xyz(i).as_vec3()).collect();
    let layered = to_laz_bytes(&PointCloud::from_points(DVec3::ZERO, pts)).unwrap();
    let data_start = u32::from_le_bytes(layered[96..100].try_into().unwrap()) as u64;
    let err = read_bytes(&cut_laz_points(&layered), &ReadOptions::default()).unwrap_err();
    let reason = assert_malformed(err, Format::Laz, Location::Byte(data_start + 8));
    assert!(reason.contains("chunk 0"), "{reason}");

    let mut builder = las::Builder::from((1, 2));
    builder.point_format = las::point::Format::new(1).unwrap();
    builder.point_format.is_compressed = true;
    let header = builder.into_header().unwrap();
    let mut writer = las::Writer::new(Cursor::new(Vec::new()), header).unwrap();
    for i in 0..3000 {
        let p = xyz(i);
        let point = las::Point {
            x: p.x,
            y: p.y,
            z: p.z,
            gps_time: Some(0.0),
            ..Default::default()
        };
        writer.write_point(point).unwrap();
    }
    let pointwise = writer.into_inner().unwrap().into_inner();
    let i = laz_error_point(&cut_laz_points(&pointwise));
    assert!((1000..3000).contains(&i), "failed at point {i}");
}

/// Regression (found by `cargo fuzz run las`): a layered LAZ whose first
/// layer claims 4 GiB made the `laz` crate allocate it before reading.
#[test]
fn laz_layer_size_beyond_the_file() {
    let mut laz = bytes("tiny.laz");
    let chunk = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize + 8;
    let record_len = u16::from_le_bytes(laz[105..107].try_into().unwrap()) as usize;
    let first_layer = chunk + record_len + 4;
    laz[first_layer..first_layer + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = read_bytes(&laz, &ReadOptions::default()).unwrap_err();
    let reason = assert_malformed(err, Format::Laz, Location::Byte(chunk as u64));
    assert!(reason.contains("layers"), "{reason}");
}

/// Regression (found by `cargo fuzz run las`): corrupt entropy-coded bytes
/// make laz 0.12's arithmetic decoder index out of bounds; the panic is
/// contained and reported as an error at the point being decoded.
#[test]
fn laz_decoder_panic_becomes_an_error() {
    let reason = assert_malformed(
        read_err("broken_decoder_panic.laz"),
        Format::Laz,
        Location::Point(5),
    );
    assert!(reason.contains("corrupt"), "{reason}");
}

/// Regression (found by `cargo fuzz run las`): corrupt GPS time data made
/// laz 0.12's point-wise GPS decoder recurse until the stack overflowed,
/// which aborts the process. The depth limit turns it into an error.
#[test]
fn laz_gps_time_recursion_is_cut_off() {
    let reason = assert_malformed(
        read_err("broken_gps_recursion.laz"),
        Format::Laz,
        Location::Point(20),
    );
    assert!(reason.contains("recursed too deeply"), "{reason}");
}

/// Regression (found by `cargo fuzz run las`): layered items declared with
/// the point-wise compressor made laz read layer sizes 8 bytes early and
/// allocate a garbage 4 GiB layer.
#[test]
fn laz_compressor_must_match_item_versions() {
    let mut laz = bytes("tiny.laz");
    let header_size = u16::from_le_bytes(laz[94..96].try_into().unwrap()) as usize;
    let compressor = header_size + 54; // first VLR's data
    assert_eq!(laz[compressor..compressor + 2], 3u16.to_le_bytes());
    laz[compressor..compressor + 2].copy_from_slice(&1u16.to_le_bytes());
    let err = read_bytes(&laz, &ReadOptions::default()).unwrap_err();
    let reason = assert_malformed(err, Format::Laz, Location::Header);
    assert!(reason.contains("compressor 1"), "{reason}");
}

#[test]
fn laz_chunk_table_claiming_billions_of_chunks() {
    let mut laz = bytes("tiny.laz");
    let data_start = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize;
    let table = i64::from_le_bytes(laz[data_start..data_start + 8].try_into().unwrap()) as usize;
    laz[table + 4..table + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = read_bytes(&laz, &ReadOptions::default()).unwrap_err();
    let reason = assert_malformed(err, Format::Laz, Location::Byte(table as u64));
    assert!(reason.contains("chunks"), "{reason}");
}

#[test]
fn ply_binary_header_promising_more_vertices() {
    // The header is 148 bytes; 6 vertices of 13 bytes do not fit in 58.
    let reason = assert_malformed(
        read_err("broken_short.ply"),
        Format::Ply,
        Location::Byte(148),
    );
    assert!(reason.contains("promises 6 vertices"), "{reason}");
}

#[test]
fn ply_ascii_body_ending_early_names_the_line() {
    assert_malformed(
        read_err("broken_short_ascii.ply"),
        Format::Ply,
        Location::Line(17),
    );
}

#[test]
fn ply_infinite_coordinate_names_the_vertex_byte() {
    assert_malformed(read_err("broken_inf.ply"), Format::Ply, Location::Byte(127));
}

#[test]
fn ply_header_without_end_or_vertex() {
    let err = read_as(
        Cursor::new(b"ply\nformat ascii 1.0\n"),
        Format::Ply,
        &ReadOptions::default(),
    );
    assert_malformed(err.unwrap_err(), Format::Ply, Location::Byte(21));
    let no_vertex = b"ply\nformat ascii 1.0\nelement face 1\nproperty uchar a\nend_header\n1\n";
    let err = read_bytes(no_vertex, &ReadOptions::default()).unwrap_err();
    assert_malformed(err, Format::Ply, Location::Header);
}

#[test]
fn point_limit_is_enforced_while_streaming() {
    let opts = ReadOptions { max_points: 3 };
    for name in ["tiny.xyz", "ascii.ply", "tiny.laz"] {
        let err = read_path(&data(name), &opts).unwrap_err();
        assert!(
            matches!(err, CloudError::TooManyPoints { limit: 3, .. }),
            "{name}: {err}"
        );
    }
}

#[test]
fn overlong_xyz_line_is_rejected() {
    let line = vec![b'1'; 1 << 20];
    let err = read_bytes(&line, &ReadOptions::default()).unwrap_err();
    assert_malformed(err, Format::Xyz, Location::Line(1));
}

#[test]
fn writers_round_trip_through_every_format() {
    let (source, _) = read_ok("tiny.laz");
    let dir = tempfile::tempdir().unwrap();
    for (name, format) in [
        ("a.xyz", Format::Xyz),
        ("a.txt", Format::Xyz),
        ("a.ply", Format::Ply),
        ("a.las", Format::Las),
        ("a.LAZ", Format::Laz),
    ] {
        let path = dir.path().join(name);
        write_path(&source, &path).unwrap();
        let (back, got) = read_path(&path, &ReadOptions::default()).unwrap();
        assert_eq!(got, format, "{name}");
        assert_eq!(back.len(), source.len(), "{name}");
        for i in 0..source.len() {
            assert!(
                close(back.absolute(i), source.absolute(i)),
                "{name} point {i}"
            );
        }
        if format != Format::Xyz {
            assert_eq!(back.classification, source.classification, "{name}");
            assert_eq!(back.intensity, source.intensity, "{name}");
            assert_eq!(back.return_number, source.return_number, "{name}");
        }
    }
    let err = write_path(&source, &dir.path().join("a.e57")).unwrap_err();
    assert!(matches!(err, CloudError::UnknownFormat(_)));
}

#[test]
fn laz_bytes_are_smaller_than_las() {
    let (source, _) = read_ok("tiny.las");
    let laz = to_laz_bytes(&source).unwrap();
    assert!(laz.len() < bytes("tiny.las").len());
    assert_eq!(read_bytes(&laz, &ReadOptions::default()).unwrap().0, source);
}

#[test]
fn silva_info_prints_json() {
    let out = silva().arg("info").arg(data("tiny.laz")).succeeds();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["format"], "laz");
    assert_eq!(json["points"], 40);
    assert_eq!(json["las"]["version"], "1.4");
    assert_eq!(json["offset"], serde_json::json!([85000.0, 446000.0, 0.0]));
    let min = json["bounds"]["min"].as_array().unwrap();
    assert!((min[2].as_f64().unwrap() - 0.0).abs() < 1e-6);
}

#[test]
fn silva_info_on_broken_files_fails_with_one_line() {
    for name in [
        "broken_nan.xyz",
        "broken_empty.xyz",
        "broken_garbage.bin",
        "broken_garbage.las",
        "broken_short.las",
        "broken_truncated.laz",
        "broken_decoder_panic.laz",
        "broken_gps_recursion.laz",
        "broken_short.ply",
        "broken_inf.ply",
        "does_not_exist.xyz",
    ] {
        silva().arg("info").arg(data(name)).fails_with_one_line();
    }
}
