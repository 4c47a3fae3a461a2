//! Real receiver logs read by vgps against gpsd's own decoding of them (`.chk`, the
//! regression references of gpsd): every fix gpsd reports is a vgps fix at the same time
//! (within 1 ms), the same position (within 1 cm), the same ellipsoidal height (within 1 cm)
//! and the same fix quality. Data: `tests/data/gnss/` (BSD-2 gpsd, MIT gnss_lib_py).

use std::path::{Path, PathBuf};
use vgps_replay::drive::gnss::{GnssFormat, GnssLog, read_gnss_file};

/// Position tolerance, metres.
const POSITION_TOLERANCE_M: f64 = 0.01;
/// Height tolerance, metres.
const HEIGHT_TOLERANCE_M: f64 = 0.01;
/// Time tolerance, seconds.
const TIME_TOLERANCE_S: f64 = 1e-3;
/// Metres per degree of latitude (enough for a centimetre check).
const M_PER_DEG: f64 = 111_320.0;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/gnss")
        .join(name)
}

/// One gpsd TPV report with a fix.
#[derive(Debug)]
struct Tpv {
    time_s: f64,
    lat: f64,
    lon: f64,
    alt_hae: Option<f64>,
    mode: u64,
    status: u64,
}

/// `2020-03-18T13:28:19.600Z` → Unix seconds.
fn iso_time(text: &str) -> f64 {
    let (date, time) = text.trim_end_matches('Z').split_once('T').unwrap();
    let d: Vec<i64> = date.split('-').map(|x| x.parse().unwrap()).collect();
    let t: Vec<f64> = time.split(':').map(|x| x.parse().unwrap()).collect();
    // Days from civil (H. Hinnant's algorithm).
    let (y, m, day) = (d[0] - i64::from(d[1] <= 2), d[1], d[2]);
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * (m + if m > 2 { -3 } else { 9 }) + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    days as f64 * 86_400.0 + t[0] * 3600.0 + t[1] * 60.0 + t[2]
}

/// gpsd's fixes: the last TPV of each time with a 2-D or 3-D fix.
fn gpsd_fixes(chk: &str) -> Vec<Tpv> {
    let mut out: Vec<Tpv> = Vec::new();
    for line in chk.lines().filter(|l| l.starts_with('{')) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        if v["class"] != "TPV" {
            continue;
        }
        let (Some(time), Some(lat), Some(lon)) =
            (v["time"].as_str(), v["lat"].as_f64(), v["lon"].as_f64())
        else {
            continue;
        };
        let mode = v["mode"].as_u64().unwrap_or(0);
        if mode < 2 {
            continue;
        }
        let tpv = Tpv {
            time_s: iso_time(time),
            lat,
            lon,
            alt_hae: v["altHAE"].as_f64(),
            mode,
            // gpsd leaves `status` out for a plain GPS fix (STATUS_GPS = 1).
            status: v["status"].as_u64().unwrap_or(1),
        };
        match out.last_mut() {
            Some(last) if (last.time_s - tpv.time_s).abs() < 1e-6 => *last = tpv,
            _ => out.push(tpv),
        }
    }
    out
}

/// GGA quality → gpsd status (gpsd `gps.h`: 1 GPS, 2 DGPS, 3 RTK fixed, 4 RTK float, 5 DR).
fn gpsd_status(quality: u8) -> u64 {
    match quality {
        2 | 3 => 2,
        4 => 3,
        5 => 4,
        6 => 5,
        _ => 1,
    }
}

/// Compares every gpsd fix with vgps's; returns (gpsd fixes, matched, largest position and
/// height differences in metres).
fn compare(log: &GnssLog, chk: &str) -> (usize, usize, f64, f64) {
    compare_shifted(log, chk, 0.0)
}

/// [`compare`] with `shift_s` added to gpsd's times.
fn compare_shifted(log: &GnssLog, chk: &str, shift_s: f64) -> (usize, usize, f64, f64) {
    let mut reference = gpsd_fixes(chk);
    for r in &mut reference {
        r.time_s += shift_s;
    }
    let (mut matched, mut worst_pos, mut worst_h) = (0, 0.0_f64, 0.0_f64);
    for tpv in &reference {
        let Some(ours) = log
            .records
            .iter()
            .find(|r| (r.time_s - tpv.time_s).abs() <= TIME_TOLERANCE_S)
        else {
            panic!("{}: no vgps epoch at gpsd's {tpv:?}", log.path.display());
        };
        let fix = ours
            .fix
            .unwrap_or_else(|| panic!("vgps has no fix at gpsd's {tpv:?}"));
        let p = fix.position;
        let dn = (p.lat_deg - tpv.lat) * M_PER_DEG;
        let de = (p.lon_deg - tpv.lon) * M_PER_DEG * tpv.lat.to_radians().cos();
        let dpos = dn.hypot(de);
        assert!(dpos <= POSITION_TOLERANCE_M, "{dpos} m at {tpv:?}");
        worst_pos = worst_pos.max(dpos);
        if let (Some(h), 3) = (tpv.alt_hae, tpv.mode) {
            let dh = (p.alt_m - h).abs();
            assert!(dh <= HEIGHT_TOLERANCE_M, "height {} vs {tpv:?}", p.alt_m);
            worst_h = worst_h.max(dh);
        }
        assert_eq!(gpsd_status(fix.quality), tpv.status, "quality at {tpv:?}");
        matched += 1;
    }
    (reference.len(), matched, worst_pos, worst_h)
}

fn check(name: &str, format: GnssFormat, min_fixes: usize) -> GnssLog {
    let log = read_gnss_file(&data(name), None, 0.0).unwrap();
    assert_eq!(log.stats.format, format, "{name}");
    let chk = std::fs::read_to_string(data(&format!("{name}.chk"))).unwrap();
    let (n, matched, pos, h) = compare(&log, &chk);
    eprintln!(
        "{name}: {matched}/{n} gpsd fixes matched, vgps epochs {} (fixes {}), worst position {pos:.2e} m, height {h:.2e} m",
        log.records.len(),
        log.stats.fixes
    );
    assert!(n >= min_fixes, "{name}: only {n} gpsd fixes");
    log
}

#[test]
fn ublox8_nmea_in_a_car_matches_gpsd() {
    let log = check("gpsd_nl2008u.log", GnssFormat::Nmea, 9);
    assert_eq!(log.stats.fixes, 9);
}

#[test]
fn trimble_rtk_nmea_matches_gpsd() {
    let log = check("gpsd_nmea-rtk.log", GnssFormat::Nmea, 100);
    // DGPS then RTK fixed: both qualities are there.
    let qualities: std::collections::BTreeSet<u8> = log
        .records
        .iter()
        .filter_map(|r| r.fix.map(|f| f.quality))
        .collect();
    assert!(
        qualities.contains(&2) && qualities.contains(&4),
        "{qualities:?}"
    );
}

#[test]
fn zed_f9p_ubx_matches_gpsd() {
    // The log is UBX only (NAV-PVT, NAV-POSLLH, NAV-VELNED, NAV-SAT, …; the NMEA of its
    // .chk is gpsd's output): 10 NAV-PVT epochs, the 9 gpsd reports (it reports an epoch at
    // the next one's start) equal.
    let log = check("gpsd_ublox-zed-f9p-rtk.log", GnssFormat::Ubx, 9);
    assert_eq!(log.stats.fixes, 10);
    assert!(
        log.records
            .iter()
            .all(|r| r.fix.is_some_and(|f| f.quality == 5))
    );
}

#[test]
fn sirf_binary_matches_gpsd() {
    // SiRF-II (BU-303, walking, 2005-06-09): 12 MID 2 (ECEF, GPS week/time) and 11 MID 41
    // whose UTC fields are all zero (SiRF-II firmware), so the epochs come from MID 2.
    // gpsd cannot know this receiver's leap seconds and applies its build's 18 s; 13 s were
    // in force in June 2005, so vgps's UTC is gpsd's plus 5 s (docs/drive-format.md).
    let log = read_gnss_file(&data("gpsd_bu303-moving.log"), None, 0.0).unwrap();
    assert_eq!(log.stats.format, GnssFormat::Sirf);
    let chk = std::fs::read_to_string(data("gpsd_bu303-moving.log.chk")).unwrap();
    let (n, matched, pos, h) = compare_shifted(&log, &chk, 18.0 - 13.0);
    eprintln!(
        "gpsd_bu303-moving.log: {matched}/{n} gpsd fixes matched, worst position {pos:.2e} m, height {h:.2e} m"
    );
    assert_eq!((n, matched, log.stats.fixes), (12, 12, 12));
    assert_eq!(log.stats.skipped(), 0, "{:?}", log.stats);
}

#[test]
fn android_gnsslogger_nmea_is_read() {
    let log = read_gnss_file(&data("pixel6.nmea"), None, 0.0).unwrap();
    let nmea = log.nmea.as_ref().unwrap();
    assert_eq!((log.stats.fixes, nmea.noisy, nmea.used), (48, 96, 96));
    // First line: NMEA,$GPGGA,234257.00,3725.590397,N,12210.422534,W,1,24,0.4,51.9,M,-28.4,…
    // on 7 Nov 2023 (its RMC).
    let first = &log.records[0];
    assert_eq!(first.time_s, iso_time("2023-11-07T23:42:57Z"));
    let p = first.fix.unwrap().position;
    assert!((p.lat_deg - (37.0 + 25.590397 / 60.0)).abs() < 1e-12);
    assert!((p.lon_deg + (122.0 + 10.422534 / 60.0)).abs() < 1e-12);
    assert!((p.alt_m - (51.9 - 28.4)).abs() < 1e-9);
}
