//! Runs every fuzz-target body (`vgps_fuzz_bodies`) over every file of the committed seed
//! corpus `fuzz/corpus/<target>/` on stable, so that CI exercises the corpus without
//! nightly or cargo-fuzz. The bodies panic when an invariant is broken.

use std::path::Path;

#[test]
fn every_target_has_a_corpus_and_passes_it() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus");
    let mut total = 0;
    for (name, body) in vgps_fuzz_bodies::TARGETS {
        let dir = root.join(name);
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.expect("directory entry").path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        assert!(!files.is_empty(), "{}: empty seed corpus", dir.display());
        for file in &files {
            let data = std::fs::read(file).expect("corpus file");
            let outcome = std::panic::catch_unwind(|| body(&data));
            assert!(outcome.is_ok(), "target {name} fails on {}", file.display());
        }
        total += files.len();
    }
    assert!(total >= vgps_fuzz_bodies::TARGETS.len());
}

#[test]
fn every_target_survives_empty_and_tiny_inputs() {
    for (_, body) in vgps_fuzz_bodies::TARGETS {
        for data in [&b""[..], b"\0", b"\xff\xff\xff\xff", b"id,lat,lon,alt\n"] {
            body(data);
        }
    }
}

#[test]
fn every_target_has_a_fuzz_target_file() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/fuzz_targets");
    for (name, _) in vgps_fuzz_bodies::TARGETS {
        let file = root.join(format!("{name}.rs"));
        let text =
            std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        assert!(
            text.contains("vgps_fuzz_bodies::"),
            "{} does not call vgps_fuzz_bodies",
            file.display()
        );
    }
}
