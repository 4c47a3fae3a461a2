//! `vgps detect` with a calibration that names no image size (a Ladybug INI dump): the size
//! comes from `--image-size` or from the images (issue 23); before, every image was
//! refused as `wrong_size`.

use std::path::Path;
use std::process::Command;

fn vgps(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_vgps"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("vgps runs")
}

/// A 3 m simulated drive with images whose calibration is replaced by an INI without size.
fn drive_with_unsized_ini(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("drive");
    let o = Command::new(env!("CARGO_BIN_EXE_vgps"))
        .args([
            "simulate",
            "--preset",
            "short",
            "--length-m",
            "3",
            "--images",
            "--quiet",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("vgps runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let manifest = std::fs::read_to_string(out.join("drive.json")).expect("manifest");
    let calib = manifest
        .split("\"calibration\"")
        .nth(1)
        .and_then(|r| r.split('"').nth(1))
        .expect("calibration name")
        .to_string();
    let ini = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/calibration/ladybug_no_size.ini"),
    )
    .expect("ini");
    std::fs::write(out.join(&calib), ini).expect("write");
    out
}

#[test]
fn detect_takes_the_image_size_from_the_images_or_the_option() {
    let dir = tempfile::tempdir().expect("tmp");
    let drive = drive_with_unsized_ini(dir.path());
    let d = drive.to_string_lossy().into_owned();
    let o = vgps(&["detect", &d, "--quiet", "--out", "det.csv"], dir.path());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("names no image size: using"), "{stderr}");
    assert!(!stderr.contains("exceeds the limits"), "{stderr}");
    // A contradicting size is refused by the images' sizes (wrong_size per image), the
    // calibration itself accepts any size.
    let o = vgps(
        &[
            "detect",
            &d,
            "--quiet",
            "--out",
            "det2.csv",
            "--image-size",
            "10x10",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("using 10×10 (--image-size)"), "{stderr}");
}

/// `vgps replay --from-images` with a rig from an INI dump (no image size): with images
/// whose headers give no size (BMP), it refuses with a message asking for `--image-size`;
/// with `--image-size W,H` it replays the images (none refused for their size).
#[test]
fn replay_from_images_takes_the_image_size_option() {
    let dir = tempfile::tempdir().expect("tmp");
    let drive = drive_with_unsized_ini(dir.path());
    // The same pixels as BMP (content-sniffed, so the file names stay): no PNG/JPEG header.
    let mut size = None;
    let mut converted = 0;
    let mut dirs = vec![drive.clone()];
    let mut files = Vec::new();
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).expect("drive") {
            let p = e.expect("entry").path();
            if p.is_dir() {
                dirs.push(p);
            } else {
                files.push(p);
            }
        }
    }
    for p in files {
        if p.extension().is_some_and(|x| x == "png") {
            let img = image::open(&p).expect("png").into_luma8();
            size = Some(img.dimensions());
            img.save_with_format(&p, image::ImageFormat::Bmp)
                .expect("bmp");
            converted += 1;
        }
    }
    let (w, h) = size.expect("the drive has images");
    assert!(converted >= 6, "{converted} images");
    let d = drive.to_string_lossy().into_owned();
    let o = vgps(
        &["replay", &d, "--from-images", "--quiet", "--out", "r1"],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("names no image size") && stderr.contains("give --image-size WxH"),
        "{stderr}"
    );
    assert!(!dir.path().join("r1/fixes.csv").exists());
    let size_arg = format!("{w},{h}");
    let o = vgps(
        &[
            "replay",
            &d,
            "--from-images",
            "--quiet",
            "--image-size",
            &size_arg,
            "--out",
            "r2",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("using {w}×{h} (--image-size)")),
        "{stderr}"
    );
    assert!(!stderr.contains("exceeds the limits"), "{stderr}");
    assert!(!stderr.contains("wrong_size"), "{stderr}");
    assert!(dir.path().join("r2/fixes.csv").is_file());
}
