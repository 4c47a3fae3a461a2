//! `vgps replay` under faults: killed mid-run, a full disk (file-size limit, EFBIG), an
//! output directory that cannot be written (works as root and in CI: a path under a regular
//! file, ENOTDIR; an output file name taken by a directory, EISDIR on the rename). In every
//! case the previous report in `--out` stays whole and parses, and no temporary file is left
//! except, after a SIGKILL, the clearly named `.NAME.tmp-PID-XXXXXXXX` of the write in progress (eight random
//! alphanumeric characters).
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::Duration;

/// The ten files of a replay report.
const OUTPUTS: [&str; 10] = [
    "fixes.csv",
    "report.json",
    "report.html",
    "track.geojson",
    "track.kml",
    "track.gpx",
    "fixes.nmea",
    "track.png",
    "error.png",
    "summary.txt",
];

/// A short simulated drive (`--preset short`, 30 m) and a previous replay report of it,
/// made once per test run: (temp dir, drive, report directory).
fn prepared() -> &'static (tempfile::TempDir, PathBuf, PathBuf) {
    static PREPARED: OnceLock<(tempfile::TempDir, PathBuf, PathBuf)> = OnceLock::new();
    PREPARED.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let drive = dir.path().join("drive");
        let report = dir.path().join("previous");
        let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
            .args(["simulate", "--preset", "short", "--length-m", "30", "--out"])
            .arg(&drive)
            .output()
            .expect("vgps runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
            .arg("replay")
            .arg(&drive)
            .args(["--quiet", "--threads", "1", "--out"])
            .arg(&report)
            .output()
            .expect("vgps runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (dir, drive, report)
    })
}

/// A copy of the previous report in a fresh directory `t/out`.
fn previous_report_in(t: &Path) -> PathBuf {
    let out = t.join("out");
    std::fs::create_dir_all(&out).expect("mkdir");
    for name in OUTPUTS {
        std::fs::copy(prepared().2.join(name), out.join(name)).expect("copy");
    }
    out
}

/// Asserts every output in `dir` is whole: it parses (JSON, CSV with a constant number of
/// fields, XML-ish tails, PNG signature and IEND), and returns the names of the files that
/// are not temporary ones.
fn assert_report_whole(dir: &Path) {
    let read = |name: &str| std::fs::read(dir.join(name)).expect(name);
    let json: serde_json::Value =
        serde_json::from_slice(&read("report.json")).expect("report.json parses");
    assert!(json.is_object());
    serde_json::from_slice::<serde_json::Value>(&read("track.geojson")).expect("geojson");
    let csv = String::from_utf8(read("fixes.csv")).expect("utf-8");
    // The csv reader refuses a row whose field count differs from the header's.
    let mut rows = 0;
    for r in csv::Reader::from_reader(csv.as_bytes()).records() {
        r.expect("fixes.csv row");
        rows += 1;
    }
    assert!(rows > 0, "fixes.csv has no rows");
    assert_eq!(csv.lines().count(), rows + 1, "one line per frame");
    assert!(csv.ends_with('\n'));
    for (name, tail) in [
        ("report.html", "</html>"),
        ("track.kml", "</kml>"),
        ("track.gpx", "</gpx>"),
    ] {
        let text = String::from_utf8(read(name)).expect("utf-8");
        assert!(text.trim_end().ends_with(tail), "{name} is cut");
    }
    let nmea = String::from_utf8(read("fixes.nmea")).expect("utf-8");
    for line in nmea.lines() {
        assert!(line.starts_with('$') && line.contains('*'), "{line}");
    }
    for name in ["track.png", "error.png"] {
        let png = read(name);
        assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "{name}");
        assert_eq!(&png[png.len() - 8..png.len() - 4], b"IEND", "{name} is cut");
    }
    assert!(!read("summary.txt").is_empty());
}

/// The temporary files in `dir`.
fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("read dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp"))
        .collect()
}

/// `.NAME.tmp-PID-XXXXXXXX` with NAME one of the outputs and eight random alphanumerics.
fn clearly_named(temp: &str) -> bool {
    OUTPUTS.iter().any(|o| {
        temp.strip_prefix(&format!(".{o}.tmp-"))
            .is_some_and(|rest| {
                let mut parts = rest.split('-');
                parts.next().is_some_and(|p| p.parse::<u32>().is_ok())
                    && parts.next().is_some_and(|r| {
                        r.len() == 8 && r.bytes().all(|b| b.is_ascii_alphanumeric())
                    })
                    && parts.next().is_none()
            })
    })
}

#[test]
fn killed_mid_run_leaves_the_previous_report_whole() {
    for delay_ms in [200u64, 1500, 4000] {
        let t = tempfile::tempdir().expect("temp dir");
        let out = previous_report_in(t.path());
        let mut child = Command::new(env!("CARGO_BIN_EXE_vgps"))
            .arg("replay")
            .arg(&prepared().1)
            .args(["--quiet", "--threads", "1", "--out"])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn");
        std::thread::sleep(Duration::from_millis(delay_ms));
        let finished = child.try_wait().expect("wait").is_some();
        let _ = child.kill();
        child.wait().expect("reaped");
        assert_report_whole(&out);
        for temp in temp_files(&out) {
            assert!(clearly_named(&temp), "unexpected temporary file `{temp}`");
        }
        println!("killed after {delay_ms} ms (had finished: {finished}): report whole");
    }
}

#[test]
fn full_disk_is_an_output_error_and_leaves_whole_files() {
    let t = tempfile::tempdir().expect("temp dir");
    let out = previous_report_in(t.path());
    // Files are limited to 16 blocks (8–16 KiB): the PNGs cannot be written (EFBIG; the
    // SIGXFSZ that would kill the process is ignored, and stays ignored across exec).
    let script = format!(
        "ulimit -f 16; trap '' XFSZ; exec '{}' replay '{}' --quiet --threads 1 --out '{}'",
        env!("CARGO_BIN_EXE_vgps"),
        prepared().1.display(),
        out.display()
    );
    let o = Command::new("sh")
        .args(["-c", &script])
        .output()
        .expect("sh runs");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "stderr: {stderr}");
    assert!(
        stderr.contains("cannot write the output") && stderr.contains(&*out.to_string_lossy()),
        "stderr: {stderr}"
    );
    assert!(stderr.contains("too large"), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "stderr: {stderr}");
    assert_report_whole(&out);
    assert_eq!(temp_files(&out), Vec::<String>::new());
}

#[test]
fn output_under_a_regular_file_fails_fast_with_exit_1() {
    let t = tempfile::tempdir().expect("temp dir");
    std::fs::write(t.path().join("file"), "a regular file\n").expect("write");
    let out = t.path().join("file/report");
    let started = std::time::Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
        .arg("replay")
        .arg(&prepared().1)
        .args(["--quiet", "--out"])
        .arg(&out)
        .output()
        .expect("vgps runs");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "stderr: {stderr}");
    assert!(stderr.contains(&*out.to_string_lossy()), "stderr: {stderr}");
    assert!(stderr.contains("Not a directory"), "stderr: {stderr}");
    assert!(o.stdout.is_empty());
    // Before the frames are localized (the whole replay of this drive takes seconds).
    println!("failed after {:?}", started.elapsed());
    let entries: Vec<_> = std::fs::read_dir(t.path()).expect("dir").collect();
    assert_eq!(entries.len(), 1, "something was written next to the file");
}

#[test]
fn output_name_taken_by_a_directory_keeps_the_other_files_whole() {
    let t = tempfile::tempdir().expect("temp dir");
    let out = previous_report_in(t.path());
    // `track.png` cannot be replaced: a directory holds its name.
    std::fs::remove_file(out.join("track.png")).expect("rm");
    std::fs::create_dir(out.join("track.png")).expect("mkdir");
    std::fs::write(out.join("track.png/keep"), "x").expect("write");
    let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
        .arg("replay")
        .arg(&prepared().1)
        .args(["--quiet", "--threads", "1", "--out"])
        .arg(&out)
        .output()
        .expect("vgps runs");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "stderr: {stderr}");
    assert!(stderr.contains("track.png"), "stderr: {stderr}");
    assert_eq!(temp_files(&out), Vec::<String>::new());
    assert!(out.join("track.png/keep").exists());
    // The files written before it are whole (new), the ones after it whole (old).
    serde_json::from_slice::<serde_json::Value>(
        &std::fs::read(out.join("report.json")).expect("read"),
    )
    .expect("report.json parses");
    let png = std::fs::read(out.join("error.png")).expect("read");
    assert_eq!(&png[png.len() - 8..png.len() - 4], b"IEND");
}
