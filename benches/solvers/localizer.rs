//! `vgps::localizer::Localizer::process` over the reference drive (3,255 frames at 15 fps,
//! ~40 detections per frame of which 20% false, a 330 m stretch without surveyed landmarks):
//! the whole drive after the first fix, i.e. tracking, surrogate mapping and the occasional
//! re-acquisition, with the drive's satellite GPS as `vgps replay` gives it. Criterion reports
//! frames per second.
use criterion::{BatchSize, Criterion, Throughput};
use std::sync::Arc;
use vgps::drive::gnss::gnss_at;
use vgps::localizer::{Frame, GnssPosition, LandmarkMap, Localizer, LocalizerOptions};
use vgps::simulate::{Preset, Scenario, simulate};

/// Benchmark of `process` on every frame of the reference drive but the first.
pub fn benches(c: &mut Criterion) {
    let drive = simulate(&Scenario::preset(Preset::Reference, 1)).expect("reference drive");
    let landmarks = drive.surveyed_landmarks().expect("landmarks");
    let map = Arc::new(LandmarkMap::from_landmarks(&landmarks, None).expect("map"));
    let rig = Arc::new(drive.scenario.rig.clone());
    let frames: Vec<Frame> = drive
        .frames
        .iter()
        .map(|f| {
            let detections: Vec<_> = f.detections.iter().map(|d| d.detection.clone()).collect();
            let gnss = gnss_at(&drive.gnss, f.time_s).map(|position| GnssPosition { position });
            Frame::from_detections(f.time_s, &detections, &map, gnss)
        })
        .collect();
    let first = frames[0].clone();
    let mut warmed = Localizer::new(rig, map, LocalizerOptions::default()).expect("localizer");
    warmed.process(&first);
    let mut group = c.benchmark_group("localizer");
    group.sample_size(10);
    group.throughput(Throughput::Elements((frames.len() - 1) as u64));
    group.bench_function("process_reference_drive", |b| {
        b.iter_batched(
            || warmed.clone(),
            |mut localizer| {
                for f in &frames[1..] {
                    std::hint::black_box(localizer.process(f));
                }
            },
            BatchSize::LargeInput,
        )
    });
    group.finish();
}
