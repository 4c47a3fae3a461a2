//! `vgps replay` end to end on the reference drive (3,255 frames at 15 fps) from its
//! `detections.csv`: `vgps::cli::replay::run` as the command line runs it, i.e. reading and
//! checking every file of the drive, localizing every frame (the first acquisition
//! included) and writing every report file (fsync'd, atomically) into a temporary
//! directory. Criterion reports frames per second; the target of issue #7 is ≥ 2,000.
use clap::Parser;
use criterion::{Criterion, Throughput};
use vgps::cli::ReplaySettings;
use vgps::cli::demo::DEMO_SEED;
use vgps::cli::replay::{ReplayArgs, run};
use vgps::simulate::{Preset, Scenario, simulate};

/// `vgps replay`'s arguments, parsed as the command line parses them.
#[derive(Parser)]
struct Replay {
    #[command(flatten)]
    args: ReplayArgs,
}

/// Benchmark of the whole replay of the reference drive, as `vgps demo` writes it.
pub fn benches(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let drive_dir = dir.path().join("reference");
    let drive = simulate(&Scenario::preset(Preset::Reference, DEMO_SEED)).expect("drive");
    drive.write(&drive_dir).expect("drive written");
    let out_dir = dir.path().join("replay");
    let replay = Replay::parse_from([
        "replay".as_ref(),
        drive_dir.as_os_str(),
        "--out".as_ref(),
        out_dir.as_os_str(),
        "--quiet".as_ref(),
    ]);
    let settings = ReplaySettings::try_from(replay.args).expect("valid settings");
    let mut group = c.benchmark_group("replay");
    group.sample_size(10);
    group.throughput(Throughput::Elements(drive.frames.len() as u64));
    group.bench_function("reference_drive_end_to_end", |b| {
        b.iter(|| {
            let (mut out, mut err) = (Vec::new(), Vec::new());
            run(&settings, &mut out, &mut err).expect("replay");
            std::hint::black_box((out, err))
        })
    });
    group.finish();
}
