//! Inputs that made a fuzz target fail (see `docs/fuzzing.md`), replayed through the same
//! code path (`vgps_fuzz_bodies::<target>`) and checked directly on the library function.

/// Three detections along the rig's axes, from the rig's origin.
fn axis_detections() -> Vec<vgps::matcher::Detection> {
    use nalgebra::Vector3;
    [Vector3::x(), Vector3::y(), Vector3::z()]
        .iter()
        .map(|d| {
            vgps::matcher::Detection::new(
                vgps::geometry::Ray::try_new(Vector3::zeros(), *d).unwrap(),
            )
        })
        .collect()
}

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

/// `nmea` crash-8a0b0b0a: a GGA time field with multi-byte UTF-8 characters (invalid bytes
/// replaced by U+FFFD) made `time_of_day` slice inside a character and panic.
#[test]
fn nmea_time_with_multibyte_characters_is_an_invalid_field() {
    let data = hex(
        "244750524d432c3132303030302e30302c412c343830372e303338302c4e2c30313133312e3030302c343830372e303338302c4e2c30313133312e303030302c452c302e302c302e302c3233303339342c2c2c412a35300d0a2447504747412c3132303030302e30302c302c452c302e302c302e302c3233303339342c2c2c412a35300d0a2447504747412c3132303030302e30302c343830372e303330352c2c30392c31322c2c2c32342c2c2c2c2c322e352c312e332c322e352a33390d0a2447504747412c313230cbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcbcb3030322e30302c2c2c2c2c302c30302c2c2c4d2c2c4d2c2c2a34390d0a67617262616765206c696e650d0a2447504747412c3132303030332e30302c343830372e303339302c532c30313133312e303031302c572c322c31322c302e372c2d352e352c4d2c34362e392c4d2c2c2a30300d0a",
    );
    vgps_fuzz_bodies::nmea(&data);
    let (records, stats) = vgps::drive::nmea::read_nmea(&String::from_utf8_lossy(&data));
    assert!(stats.invalid + stats.bad_checksum >= 1, "{stats:?}");
    assert!(records.iter().all(|r| r.time_s.is_finite()));
    // The minimal form: a valid checksum, a time of 2-byte characters.
    let body = "GPGGA,1é2é3é.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,";
    let sum = vgps::drive::nmea::checksum(body);
    let (records, stats) = vgps::drive::nmea::read_nmea(&format!("${body}*{sum:02X}\n"));
    assert!(records.is_empty());
    // Refused whole: the sentence finder takes only ASCII bodies, so it counts as a bad
    // sentence (not as a field error of a sentence it parsed).
    assert_eq!(stats.invalid + stats.bad_checksum, 1, "{stats:?}");
}

/// `p3p_cosines` timeout-bf6b4835: a scene whose residual made the interval subdivision of
/// `p3p_cosines` recurse into an exponential tree (more than 10 s, the fuzzer's timeout).
/// Subdivision now has a budget per sampling interval (`MAX_SPLITS_PER_INTERVAL`): the
/// solve returns at once. No timing is asserted; before the fix this test did not finish.
#[test]
fn p3p_cosines_subdivision_is_bounded() {
    let data = hex(
        "7411001818181818181818181818181856000000000018181818000000001818181818186200000000000000181800000000000000000000001818181818181818000de5fe0000a8fc",
    );
    vgps_fuzz_bodies::p3p_law_of_cosines(&data);
    vgps_fuzz_bodies::p3p_lambda_twist(&data);
}

/// `nclt_table` crash-56586e1e (out of memory): a distortion-table header claiming a
/// table of about 4·10⁹ pixels made the reader allocate it before reading a single entry.
/// The reader now refuses sides above `MAX_IMAGE_SIDE_PX` and headers whose table the
/// file's lines cannot fill, before allocating.
#[test]
fn nclt_table_with_a_huge_header_is_refused_before_allocating() {
    let data = hex(
        "0ac95858585858585858585858585886005858585858585858363636366a36363636363636363636363636363636363636363636140000000000000036363636363658585858585858585858585858750b000000000000585858585858ce0a58ce0a3231",
    );
    vgps_fuzz_bodies::nclt_table(&data);
    let text = "4000 1000000\n0 0 0.5 0.5\n";
    let e = vgps::calibration::formats::nclt::table_from_str(
        text,
        std::path::Path::new("U2D_Cam0.txt"),
        None,
    )
    .unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains("U2D_Cam0.txt") && message.contains("line 1"),
        "{message}"
    );
}

/// `p3p_cosines` timeout-6f9208b2: a second scene with an exponential subdivision tree (see
/// `p3p_cosines_subdivision_is_bounded`).
#[test]
fn p3p_cosines_second_timeout_is_bounded() {
    let data = hex(
        "7411001818181818181818181818181800000000000018181818181818180818181818181818b601040100010000181818ffffffffffffff00000004ff1818181818181800000000181818181818183b000000000000000000e5fe0000a8fc",
    );
    vgps_fuzz_bodies::p3p_law_of_cosines(&data);
}

/// `attitude` crash-24861c7b: directions with components near 1e-160 (their squares
/// underflow) were "normalised" to a length of 1.005, and TRIAD returned a matrix 1 % off
/// a rotation. `geometry::try_unit` now rescales such vectors first.
#[test]
fn triad_of_tiny_directions_is_a_rotation() {
    let data = hex(
        "3d000000e2e2e2e2e20064861e2413e9d7a8d22e5e010101010101ffff0101010101010101010101010101ffff010101010101ffffff01e2010101015959ca2f1fd18059ca2f59fe6142ff21af241ed2e92e5e015b0000000000000001010101010101010101010101010101010127010101010101f94ea12969fcc1",
    );
    vgps_fuzz_bodies::attitude(&data);
    let tiny = nalgebra::Vector3::new(1e-160, 1e-160, -1e-160);
    let u = vgps::geometry::try_unit(&tiny).expect("a direction");
    assert!((u.norm() - 1.0).abs() < 1e-15, "|u| = {}", u.norm());
    let huge = nalgebra::Vector3::new(1e300, -1e300, 1e300);
    let u = vgps::geometry::try_unit(&huge).expect("a direction");
    assert!((u.norm() - 1.0).abs() < 1e-15, "|u| = {}", u.norm());
}

/// `matcher` timeout-73ce5f50: 7 landmarks, 5 detections, a visibility range of 2·10⁶⁴ m and
/// 1 m cells over a 100 m box: about 10⁶ cells, each solving P3P for every landmark triple
/// of every detection triple (2.9 s in a release build, over the fuzzer's 10 s with its
/// sanitizers). `max_hypotheses` counted only the poses scored, not the solves that gave
/// none; it now bounds the P3P solves (0.3 s). No timing is asserted.
#[test]
fn matcher_solves_are_bounded_by_max_hypotheses() {
    let data = hex(
        "cdcb13ee013f0000000900004d4d4d4d4d3f4d4d4d4d4d4d4d4d4d4d4d41000000000000004d4d4d4d4d4d4d4d4d4d4d444d4d4d4d4d4d4d4d0500000000000000e0e0e0e0e04d4d4d4d4d4d4d4d4d4d4d0100f7004d4d4d4d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d1100000075000000004d4d4a4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4dfeffffffffffffff4d4d4d4d5b4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0000f948b68d36bfd3b4533de6f7f502621170ac00000008e0ad06294d4d4d4d0100f7004d4db74d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d11000000000000004d4d4a4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d090909090909090909ae09090909090909090909094d4d4dffffffffffffff054d4d4d090909090109090909ae0909090909090909099e094d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d63ffffff69ffffffffffffffffffffff63636363636363636363",
    );
    vgps_fuzz_bodies::matcher(&data);
}

/// `matcher` timeout-5b924912: two landmarks and a 34 km × 9 km area of 28 m cells (377,000
/// cells, within `MAX_CELLS`): every cell was sorted by distance (two norms per comparison)
/// and queried in the R*-tree before finding that no cell has three candidates (69 ms in a
/// release build, over the fuzzer's 10 s with its sanitizers). The search now asks the
/// R*-tree once whether three landmarks are within reach of the whole area (9.8 ms, the
/// rest is generating the cells). The status must be `no_landmarks_in_range`.
#[test]
fn matcher_with_no_landmarks_within_reach_returns_at_once() {
    let data = hex(
        "cdcb13ee010000000081916eb84b7b00004d4d4d4d4d4d4d4d4d4d4d4d41000000000000004d4d4d4d4d4d4d4d4d4d4d444d4d00000000000000040000e0e00000e0e0e0e0e04d4d4d4d4d4d4d4d4d4d4d010000004d4d4d4d4d4d4d4d4d4a4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4dd3d3d3d3d3d3d3d3d3d3d3d3d3d3d3d3d3d3060606060606280100001c1c1c1c1c1b1c1c1cc0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0c0e0c0c0c0c0c0c0c0c0c4c0c0c0c0c0c0c0c0c0c0c01c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1ce4e3e3e3e3e3e3e31c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c1c00000000060606060606ae0606060606060000064d4d4d4d",
    );
    vgps_fuzz_bodies::matcher(&data);
    use nalgebra::Vector3;
    use vgps::matcher::{MatchOptions, MatchStatus, SearchArea};
    use vgps::synthetic::matcher::landmark_db;
    let db = landmark_db(&[
        Vector3::new(0.0, 0.0, 6.0),
        Vector3::new(30.0, 0.0, 6.0),
        Vector3::new(0.0, 30.0, 6.0),
    ])
    .unwrap();
    let detections = axis_detections();
    // A large area 20 km away: no landmark within its reach.
    let area = SearchArea::try_new(
        Vector3::new(20_000.0, 0.0, 0.0),
        Vector3::new(30_000.0, 9_000.0, 10.0),
    )
    .unwrap();
    let options = MatchOptions {
        cell_size_m: 28.0,
        ..MatchOptions::default()
    };
    let r = vgps::matcher::match_detections(&db, &detections, &area, &options).unwrap();
    assert_eq!(r.status, MatchStatus::NoLandmarksInRange);
    assert_eq!(r.cells, 0);
}

/// `matcher` timeout-40a26b25: 7 landmarks, a visibility range of 2·10⁶⁴ m and 0.53 m cells:
/// every one of the (then allowed) 10⁶ cells had all 7 landmarks as candidates and built its
/// angle and pair tables (2.1 s in a release build). `MAX_CELLS` is now 250,000 (a cold
/// start over 4 km² at 10 m); larger areas are `MatchError::AreaTooLarge`.
#[test]
fn matcher_area_of_a_million_cells_is_refused() {
    let data = hex(
        "cdcb25ee0100000000ffffff060900004d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d41000000000000004d4d4d4d4d4d4d4d4d4d4d444d4d4d4d4d4d4d4d0500000000000000e0e0e0e0e04d4d4d4d4d4d4d4d4d4d4d0100f7004d4d4d4d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4db3b2b2ba4d4d4d4d4d4d004d4d4d4d5d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d5d4d0d4d1100000075000000004d4d4a4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4dfeffffffffffffff4d4d4d4d5b4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d41000000000000004d4d4d4d4d4d4d4d4d4d4d444d4d4d4d4d4d4d4d000008e0ad06294d4d4d4d0100f7004d4d4d4d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4daa4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d1100000000004d4d00004a4d234d4d4d4d4d4d494d4d4d4d4d4d4d4d4d090909090909090909ae09090909090909090909094d4d4dffffffffffffff054d4d4d0909d9d94d4d0909e0e0e03f4d4d4d4d4d4d4d4d4d4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c4c09090909ffffffffffffffffff63636363636363636363",
    );
    vgps_fuzz_bodies::matcher(&data);
    use nalgebra::Vector3;
    use vgps::matcher::{MatchError, MatchOptions, SearchArea};
    use vgps::synthetic::matcher::landmark_db;
    let points: Vec<Vector3<f64>> = (0..7)
        .map(|k| Vector3::new(10.0 * k as f64, 5.0 * (k % 3) as f64, 6.0))
        .collect();
    let db = landmark_db(&points).unwrap();
    let detections = axis_detections();
    let area = SearchArea::around(&Vector3::zeros(), 50.0, 50.0).unwrap();
    let options = MatchOptions {
        cell_size_m: 1.0,
        ..MatchOptions::default()
    };
    // A box of 10⁶ cells; the cylinder within it stops counting its rings past the limit.
    let square = SearchArea {
        horizontal_radius_m: None,
        ..area
    };
    assert_eq!(
        vgps::matcher::match_detections(&db, &detections, &square, &options),
        Err(MatchError::AreaTooLarge(1_000_000))
    );
    assert!(matches!(
        vgps::matcher::match_detections(&db, &detections, &area, &options),
        Err(MatchError::AreaTooLarge(n)) if n > vgps::matcher::MAX_CELLS
    ));
}

/// `matcher` timeout-5b5ed533: the input of timeout-73ce5f50 again, now with 250,000 cells
/// (`MAX_CELLS`), each with all 7 landmarks as candidates: 0.27 s in a release build, a
/// bounded search, but over the fuzzer's 10 s with its sanitizers. The target now skips
/// areas of more than `MATCHER_MAX_FUZZ_CELLS` cells (the library bounds the rest by
/// `MAX_CELLS`). Replayed through the target.
#[test]
fn matcher_target_skips_areas_of_many_cells() {
    let data = hex(
        "cdcb13ee013f0000000900004d4d4d4d4d3f4d4d4d4d4d4d4d4d4d4d4d41000000000000004d4d4d4d4d4d4d4d4d4d4d444d4d4d4d4d4d4d4d0500000000000000e0e0e0e0e04d4d4d4d4d4d4d4d4d4d4d0100f7004d4d4d4d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d1100000075000000004d4d4a4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4dfeffffffffffffff4d4d4d4d5b4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0000f948b68d36bfd3b4533de6f7f502621170ac00000008e0ad06294d4d4d4d0100f7004d4db74d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d11000000000000004d4d4a4d4d4d4d4d4d4d4d4d4d4d0d4d4d4d4d4d4d090909090909090909ae09090909090909090909094d4d4dffffffffffffff054d4d4d090909090109090909ae0909090909090909099e094d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d1100000075000000004d4d4a4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4dfeffffffffffffff4d4d4d4d5b4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0000f948b68d36bfd3b4533de6f7f502621170ac00000008e0ad06294d4d4d4d0100f7004d4db74d4d4d4d4d4d4a4d4d4d4d4d4d4d4dcd4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d4d0d4d110000000000004d4d63ffffff69ffffffffffffffffffffff63636363636363636363",
    );
    vgps_fuzz_bodies::matcher(&data);
    const { assert!(vgps_fuzz_bodies::MATCHER_MAX_FUZZ_CELLS < vgps::matcher::MAX_CELLS as f64) };
}

/// `mcap_read` crash-c65b0e06 (2026-11-27): an attachment record of 32 bytes (its header
/// and data length, no room for its CRC) made the `mcap` crate (0.26) slice
/// `body[32..body.len() - 4]` and panic. vgps now parses only the records it uses
/// (schema, channel, message, chunk), and refuses a chunk holding anything else.
#[test]
fn mcap_short_attachment_is_skipped() {
    let mut data = b"\x89MCAP0\r\n".to_vec();
    data.push(0x09);
    data.extend_from_slice(&32u64.to_le_bytes());
    data.extend_from_slice(&[0u8; 32]);
    vgps_fuzz_bodies::mcap_read(&data);
}

/// `nmea` crash-718cf595 (2026-11-27), a bug of the fuzz body, not of the reader: the body
/// asserted at most one sentence used per line, but a line may hold several sentences
/// (`$GPGGA…*hh$GPRMC…*hh`), each read. The body now bounds the sentences by the `$` count.
#[test]
fn nmea_two_sentences_on_one_line_are_both_used() {
    use vgps::drive::nmea::{checksum, read_nmea};
    let rmc = "GPRMC,120000.00,A,4807.038,N,01131.000,E,0.0,0.0,230394,,,A";
    let gga = "GPGGA,120000.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,";
    let line = format!("${rmc}*{:02X}${gga}*{:02X}\n", checksum(rmc), checksum(gga));
    let (records, stats) = read_nmea(&line);
    assert_eq!(
        (stats.lines, stats.used, records.len()),
        (1, 2, 1),
        "{stats:?}"
    );
    vgps_fuzz_bodies::nmea(line.as_bytes());
}

/// `import_tables` crash-bd1ae883 (2026-11-27, 19 executions into the target's first run): a
/// file name with a multi-byte character just before its time (`é1352589620.jpg`) made
/// `time_ns_of_name` slice inside the character (`rfind` + 1); `camera_of_topic` had the
/// same slice (`/caméra2`). Both now take the run's start from `trim_end_matches`.
#[test]
fn names_with_multibyte_characters_before_the_number() {
    use vgps_import::{folders::time_ns_of_name, mcap_import::camera_of_topic};
    assert_eq!(
        time_ns_of_name("é1352589620.jpg"),
        Some(1_352_589_620_000_000_000)
    );
    assert_eq!(
        time_ns_of_name("\u{fffd}1.5\u{fffd}.png"),
        Some(1_500_000_000)
    );
    assert_eq!(camera_of_topic("/caméra2"), Some(2));
    assert_eq!(camera_of_topic("€7"), Some(7));
    vgps_fuzz_bodies::import_tables("a\u{fffd}12.txt\n".as_bytes());
}
