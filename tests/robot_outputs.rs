//! The outputs for a robot stack, checked by their real consumers (issue #28):
//!
//! - gpsd (Debian's `gpsd` 3.22, `gpsfake`, `gpspipe -w`) reads `fixes.nmea` through
//!   gpsfake, and the live `--nmea-tcp` stream as a `tcp://` source: every 3-D fix it
//!   reports is at the position of `fixes.csv` within 1 mm, and its `epx`/`epy`/`epv` are
//!   the σ of `fixes.csv` within 5 %;
//! - the `--mcap` file read with the Python `mcap-ros2-support` decoder: one `NavSatFix`,
//!   one `PoseWithCovarianceStamped` and one `Imu` per fix, covariances equal to
//!   `fixes.csv`'s σ.
//!
//! The drive is the first 50 frames (3.3 s, 32 fixes) of the 120 m reference drive: its
//! fixes come early, and its later frames (no fix) would take most of a minute to replay.
//!
//! gpsd finds the end of an epoch from the sentences' times and the quiet gaps between
//! them; sentences sent faster than it reads them make it merge epochs and report fewer
//! fixes (by hand: 24 of 48 through gpsfake). So every fix gpsd reports must be a fix of
//! `fixes.csv`, within 1 mm and σ within 5 %, while only a share of the fixes must come
//! through ([`MIN_SHARE_REPORTED`]).
//!
//! Without gpsd or the Python reader a test prints why it is skipped and passes; `.ci/run`
//! installs `gpsd`, `gpsd-clients` and `tests/python/requirements.txt` when missing.

mod common;

use common::vgps;
use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Tolerance of a position reported by gpsd (metres).
const POSITION_TOLERANCE_M: f64 = 1e-3;
/// Relative tolerance of a σ reported by gpsd.
const SIGMA_TOLERANCE: f64 = 0.05;
/// The share of `fixes.csv`'s fixes that gpsd must report as 3-D fixes with σ (it merges
/// epochs that come in too fast; see the module docs).
const MIN_SHARE_REPORTED: f64 = 0.4;
/// The share for the live stream at the drive's own pace, which gpsd reads from its first
/// frame (`--nmea-wait-client`): 49 of 50 here, some slack for a loaded machine.
const MIN_SHARE_LIVE: f64 = 0.8;
/// The frames of the reference drive kept for these tests.
const FRAMES_KEPT: u64 = 50;
/// WGS84 equatorial radius (metres), for metre differences of nearby positions.
const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// One row of `fixes.csv` with a fix.
#[derive(Clone, Debug)]
struct CsvFix {
    time_s: f64,
    lat: f64,
    lon: f64,
    alt: f64,
    sigma_enu: [f64; 3],
}

/// A short simulated drive, replayed once (with `--mcap`) for every test of this file.
struct Replayed {
    _dir: tempfile::TempDir,
    drive: PathBuf,
    out: PathBuf,
    fixes: Vec<CsvFix>,
}

fn replayed() -> &'static Replayed {
    static ONCE: OnceLock<Replayed> = OnceLock::new();
    ONCE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let drive = dir.path().join("drive");
        let out = dir.path().join("replay");
        let o = vgps(&[
            "simulate",
            "--preset",
            "reference",
            "--length-m",
            "120",
            "--quiet",
            "--out",
            drive.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // Keep the first frames: the per-frame tables lose the rows of later frames.
        for table in [
            "frames.csv",
            "detections.csv",
            "truth.csv",
            "detections_truth.csv",
        ] {
            let path = drive.join(table);
            let text = std::fs::read_to_string(&path).unwrap();
            let kept: String = text
                .lines()
                .enumerate()
                .filter(|(k, line)| {
                    *k == 0
                        || line
                            .split(',')
                            .next()
                            .and_then(|f| f.parse::<u64>().ok())
                            .is_some_and(|f| f < FRAMES_KEPT)
                })
                .map(|(_, line)| format!("{line}\n"))
                .collect();
            std::fs::write(&path, kept).unwrap();
        }
        let mcap = out.join("fixes.mcap");
        let o = vgps(&[
            "replay",
            drive.to_str().unwrap(),
            "--quiet",
            "--out",
            out.to_str().unwrap(),
            "--mcap",
            mcap.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let fixes = read_fixes_csv(&out.join("fixes.csv"));
        assert!(fixes.len() >= 25, "{} fixes", fixes.len());
        Replayed {
            _dir: dir,
            drive,
            out,
            fixes,
        }
    })
}

fn read_fixes_csv(path: &Path) -> Vec<CsvFix> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let headers = reader.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (t, status, lat, lon, alt) = (
        col("time_s"),
        col("status"),
        col("lat"),
        col("lon"),
        col("alt"),
    );
    let sigma = [col("sigma_e_m"), col("sigma_n_m"), col("sigma_u_m")];
    reader
        .records()
        .map(Result::unwrap)
        .filter(|r| &r[status] == "ok")
        .map(|r| {
            let f = |k: usize| r[k].parse::<f64>().unwrap();
            CsvFix {
                time_s: f(t),
                lat: f(lat),
                lon: f(lon),
                alt: f(alt),
                sigma_enu: sigma.map(f),
            }
        })
        .collect()
}

/// Whether `program` can be run (prints why not).
fn have(program: &str, why: &str) -> bool {
    let found = Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        println!(
            "SKIPPED {why}: `{program}` is not installed (Debian: apt-get install gpsd gpsd-clients; .ci/run installs it)"
        );
    }
    found
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A child process killed when dropped.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Runs `gpspipe -w` against the gpsd on `port` (retrying until gpsd listens) until it
/// ends or `limit` passes; returns its JSON lines.
fn gpspipe(
    port: u16,
    limit: Duration,
    until_done: &mut dyn FnMut() -> bool,
) -> Vec<serde_json::Value> {
    let start = Instant::now();
    loop {
        let mut child = Guard(
            Command::new("gpspipe")
                .args(["-w", &format!("127.0.0.1:{port}")])
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        let stdout = child.0.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut lines = Vec::new();
        loop {
            match rx.recv_timeout(Duration::from_millis(200)) {
                Ok(line) => lines.push(line),
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    if until_done() || start.elapsed() > limit {
                        break;
                    }
                }
            }
        }
        if !lines.is_empty() || start.elapsed() > limit {
            return lines
                .iter()
                .filter_map(|l| serde_json::from_str(l).ok())
                .collect();
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Seconds of the UTC day of gpsd's `YYYY-MM-DDThh:mm:ss.sssZ`.
fn time_of_day(iso: &str) -> f64 {
    let clock = &iso[11..iso.len() - 1];
    let mut parts = clock.split(':').map(|p| p.parse::<f64>().unwrap());
    let (h, m, s) = (
        parts.next().unwrap(),
        parts.next().unwrap(),
        parts.next().unwrap(),
    );
    h * 3600.0 + m * 60.0 + s
}

/// Only one gpsd at a time: gpsd instances share a System V memory segment.
static GPSD: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Checks gpsd's TPV reports against `fixes.csv`; returns (fixes of `fixes.csv` reported as
/// 3-D fixes, of them with σ, worst position error m, worst relative σ error). gpsd may
/// report one epoch twice (at its GGA and at its end): a fix counts once.
fn check_tpv(reports: &[serde_json::Value], fixes: &[CsvFix]) -> (usize, usize, f64, f64) {
    let (mut worst_m, mut worst_sigma) = (0.0f64, 0.0f64);
    let mut matched = std::collections::BTreeSet::new();
    let mut with_sigma = std::collections::BTreeSet::new();
    for r in reports
        .iter()
        .filter(|r| r["class"] == "TPV" && r["mode"] == 3)
    {
        let Some(t) = r["time"].as_str().map(time_of_day) else {
            continue;
        };
        let (k, f) = fixes
            .iter()
            .enumerate()
            .find(|(_, f)| (f.time_s.rem_euclid(86_400.0) - t).abs() < 0.006)
            .unwrap_or_else(|| panic!("gpsd reports a fix at {t} that fixes.csv has not: {r}"));
        let lat = r["lat"].as_f64().unwrap();
        let lon = r["lon"].as_f64().unwrap();
        let alt = r["altHAE"].as_f64().unwrap();
        let dn = (lat - f.lat).to_radians() * EARTH_RADIUS_M;
        let de = (lon - f.lon).to_radians() * EARTH_RADIUS_M * f.lat.to_radians().cos();
        let error = (dn * dn + de * de + (alt - f.alt).powi(2)).sqrt();
        assert!(error <= POSITION_TOLERANCE_M, "{error} m at {t}: {r}");
        worst_m = worst_m.max(error);
        matched.insert(k);
        if let (Some(epx), Some(epy), Some(epv)) =
            (r["epx"].as_f64(), r["epy"].as_f64(), r["epv"].as_f64())
        {
            for (got, want) in [epx, epy, epv].into_iter().zip(f.sigma_enu) {
                let relative = (got - want).abs() / want;
                assert!(relative <= SIGMA_TOLERANCE, "σ {got} vs {want} at {t}: {r}");
                worst_sigma = worst_sigma.max(relative);
            }
            with_sigma.insert(k);
        }
    }
    (matched.len(), with_sigma.len(), worst_m, worst_sigma)
}

#[test]
fn gpsd_reads_fixes_nmea_through_gpsfake() {
    if !have("gpsd", "gpsfake test")
        || !have("gpsfake", "gpsfake test")
        || !have("gpspipe", "gpsfake test")
    {
        return;
    }
    let r = replayed();
    let _one_gpsd = GPSD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let port = free_port();
    // gpsfake waits for the first client before feeding; 10 ms between sentences keeps
    // most of gpsd's epochs apart (fed at once, gpsd merges them): about 2 s for the drive.
    let _fake = Guard(
        Command::new("gpsfake")
            .args(["-1", "-q", "-c", "0.01", "-P", &port.to_string()])
            .arg(r.out.join("fixes.nmea"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let reports = gpspipe(port, Duration::from_secs(20), &mut || false);
    let (matched, with_sigma, worst_m, worst_sigma) = check_tpv(&reports, &r.fixes);
    println!(
        "gpsfake: {matched} 3-D fixes of {} ({with_sigma} with σ), worst position {:.2} mm, worst σ {:.1} %",
        r.fixes.len(),
        worst_m * 1e3,
        worst_sigma * 100.0
    );
    assert_reported_enough(matched, with_sigma, r.fixes.len());
}

/// At least [`MIN_SHARE_REPORTED`] of the fixes reported as 3-D fixes, and with σ.
fn assert_reported_enough(matched: usize, with_sigma: usize, fixes: usize) {
    let least = (MIN_SHARE_REPORTED * fixes as f64).ceil() as usize;
    assert!(matched >= least, "{matched} 3-D fixes of {fixes}");
    assert!(with_sigma >= least, "{with_sigma} with σ of {fixes}");
}

#[test]
fn gpsd_reads_the_live_stream() {
    if !have("gpsd", "live gpsd test") || !have("gpspipe", "live gpsd test") {
        return;
    }
    let r = replayed();
    let _one_gpsd = GPSD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let gpsd_port = free_port();
    let out = r.out.parent().unwrap().join("live");
    // Port 0: vgps picks a free port and names it on stderr; it waits for gpsd to connect
    // before its first frame, so that no fix goes by before gpsd reads the stream.
    let mut replay = Guard(
        Command::new(env!("CARGO_BIN_EXE_vgps"))
            .args([
                "replay",
                r.drive.to_str().unwrap(),
                "--quiet",
                "--pace",
                "real",
                "--nmea-tcp",
                "127.0.0.1:0",
                "--nmea-wait-client",
                "20",
            ])
            .arg("--out")
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr_lines = BufReader::new(replay.0.stderr.take().unwrap());
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in stderr_lines.lines().map_while(Result::ok) {
            let _ = tx.send(line.clone());
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let serving = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("vgps names the address it serves on");
    let address = serving
        .split_whitespace()
        .find(|w| w.starts_with("127.0.0.1:"))
        .unwrap_or_else(|| panic!("no address in {serving:?}"))
        .to_string();
    let _gpsd = Guard(
        Command::new("gpsd")
            .args(["-N", "-n", "-b", "-S", &gpsd_port.to_string()])
            .arg(format!("tcp://{address}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut finished = None;
    let reports = gpspipe(gpsd_port, Duration::from_secs(40), &mut || {
        if finished.is_none() {
            finished = replay.0.try_wait().unwrap();
        }
        finished.is_some()
    });
    let status = replay.0.wait().unwrap();
    let stderr = reader.join().unwrap();
    assert!(status.success(), "{stderr}");
    assert!(stderr.contains("client 127.0.0.1:"), "{stderr}");
    assert!(
        !stderr.contains("no client after"),
        "gpsd connects within the wait: {stderr}"
    );
    assert!(
        out.join("fixes.csv").exists(),
        "the replay's files are written"
    );
    let (matched, with_sigma, worst_m, worst_sigma) = check_tpv(&reports, &r.fixes);
    println!(
        "live: {matched} 3-D fixes of {} ({with_sigma} with σ), worst position {:.2} mm, worst σ {:.1} %",
        r.fixes.len(),
        worst_m * 1e3,
        worst_sigma * 100.0
    );
    let least = (MIN_SHARE_LIVE * r.fixes.len() as f64).ceil() as usize;
    assert!(
        matched >= least && with_sigma >= least,
        "{matched} 3-D fixes ({with_sigma} with σ) of {}",
        r.fixes.len()
    );
}

#[test]
fn an_address_in_use_leaves_the_replay_and_its_files() {
    let r = replayed();
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = taken.local_addr().unwrap().to_string();
    let out = r.out.parent().unwrap().join("in-use");
    let o = vgps(&[
        "replay",
        r.drive.to_str().unwrap(),
        "--quiet",
        "--pace",
        "fast",
        "--nmea-tcp",
        &address,
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "vgps: warning: --nmea-tcp: cannot listen on {address}: "
        )),
        "{stderr}"
    );
    assert!(
        stderr.contains("the replay goes on without the live stream"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read(out.join("fixes.csv")).unwrap(),
        std::fs::read(r.out.join("fixes.csv")).unwrap()
    );
    // With nobody connecting, the replay says so and still writes its files.
    let out = r.out.parent().unwrap().join("nobody");
    let o = vgps(&[
        "replay",
        r.drive.to_str().unwrap(),
        "--quiet",
        "--pace",
        "fast",
        "--nmea-tcp",
        "127.0.0.1:0",
        "--nmea-wait-client",
        "0.2",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    // The wait for a client ends, says so, and the replay goes on.
    assert!(
        stderr.contains("waiting up to 0.2 s for a client")
            && stderr.contains("no client after 0.2 s; the replay goes on"),
        "{stderr}"
    );
    assert!(
        stderr.contains("no client connected during the replay"),
        "{stderr}"
    );
    assert!(out.join("fixes.nmea").exists());
    // A wait that is not a non-negative number, or a wait without a stream: usage errors.
    for bad in ["-1", "nan", "inf"] {
        let o = vgps(&[
            "replay",
            r.drive.to_str().unwrap(),
            "--nmea-tcp",
            "127.0.0.1:0",
            "--nmea-wait-client",
            bad,
            "--out",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {stderr}");
        assert!(
            stderr.contains(&format!("`{bad}` is not a non-negative finite number")),
            "{stderr}"
        );
    }
    let o = vgps(&[
        "replay",
        r.drive.to_str().unwrap(),
        "--nmea-wait-client",
        "5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--nmea-tcp"));
}

#[test]
fn the_mcap_file_reads_back_with_mcap_ros2_support() {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/read_mcap_ros2.py");
    let probe = Command::new("python3")
        .args(["-c", "import mcap_ros2.decoder"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        println!(
            "SKIPPED MCAP read-back: python3 with mcap-ros2-support is not installed (pip install -r tests/python/requirements.txt; .ci/run installs it)"
        );
        return;
    }
    let r = replayed();
    let o = Command::new("python3")
        .arg(&script)
        .arg(r.out.join("fixes.mcap"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows[0]["profile"], "ros2");
    let of = |schema: &str| -> Vec<&serde_json::Value> {
        rows.iter().filter(|r| r["schema"] == schema).collect()
    };
    let nav = of("sensor_msgs/msg/NavSatFix");
    let pose = of("geometry_msgs/msg/PoseWithCovarianceStamped");
    let imu = of("sensor_msgs/msg/Imu");
    assert_eq!(
        (nav.len(), pose.len(), imu.len()),
        (r.fixes.len(), r.fixes.len(), r.fixes.len())
    );
    let covariance = |m: &serde_json::Value| -> Vec<f64> {
        m["covariance"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    // σ in fixes.csv has 3 decimals: the covariance's σ rounds to it.
    let same_sigma = |variance: f64, sigma: f64| (variance.sqrt() - sigma).abs() <= 0.000_5 + 1e-9;
    for (k, f) in r.fixes.iter().enumerate() {
        let (n, p) = (nav[k], pose[k]);
        let stamp = n["stamp"][0].as_f64().unwrap() + n["stamp"][1].as_f64().unwrap() * 1e-9;
        assert!((stamp - f.time_s).abs() < 1e-6, "{stamp} {}", f.time_s);
        assert_eq!(
            (n["status"].as_i64(), n["service"].as_i64()),
            (Some(0), Some(0))
        );
        assert_eq!(n["covariance_type"].as_i64(), Some(3));
        assert_eq!(n["frame_id"], "vgps_rig");
        assert_eq!(p["frame_id"], "map");
        assert!((n["lat"].as_f64().unwrap() - f.lat).abs() < 1e-9);
        assert!((n["lon"].as_f64().unwrap() - f.lon).abs() < 1e-9);
        assert!((n["alt"].as_f64().unwrap() - f.alt).abs() < 1e-3);
        let (cn, cp) = (covariance(n), covariance(p));
        for axis in 0..3 {
            assert!(
                same_sigma(cn[4 * axis], f.sigma_enu[axis]),
                "NavSatFix {k} axis {axis}: {cn:?} {f:?}"
            );
            assert!(
                same_sigma(cp[7 * axis], f.sigma_enu[axis]),
                "Pose {k} axis {axis}: {cp:?} {f:?}"
            );
        }
        let ci = covariance(imu[k]);
        assert!((0..3).all(|a| ci[4 * a] > 0.0), "{ci:?}");
    }
    println!(
        "mcap-ros2-support read {} NavSatFix, {} Pose, {} Imu for {} fixes",
        nav.len(),
        pose.len(),
        imu.len(),
        r.fixes.len()
    );
}
