//! WGS84 conversions: geodetic → ECEF, ECEF → geodetic, geodetic → local ENU, ENU → geodetic.
use criterion::Criterion;
use std::hint::black_box;
use vgps::geo::{Geodetic, LocalFrame};

/// Benchmarks of the `geo` module on points near San Francisco.
pub fn benches(c: &mut Criterion) {
    let origin = Geodetic::try_new(37.7749, -122.4194, 10.0).expect("valid origin");
    let point = Geodetic::try_new(37.8024, -122.4058, 64.0).expect("valid point");
    let frame = LocalFrame::new(origin);
    let ecef = point.to_ecef();
    let enu = frame.to_enu(&point);
    c.bench_function("geo/geodetic_to_ecef", |b| {
        b.iter(|| black_box(&point).to_ecef())
    });
    c.bench_function("geo/ecef_to_geodetic", |b| {
        b.iter(|| Geodetic::try_from_ecef(black_box(&ecef)))
    });
    c.bench_function("geo/geodetic_to_enu", |b| {
        b.iter(|| frame.to_enu(black_box(&point)))
    });
    c.bench_function("geo/enu_to_geodetic", |b| {
        b.iter(|| frame.try_to_geodetic(black_box(&enu)))
    });
}
