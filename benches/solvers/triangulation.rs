//! Triangulation: two-ray intersection per vertex, and the projector-sum estimator per ray.
//!
//! Each benchmark runs twice: in wall-clock time (`triangulation/...`, criterion's default)
//! and in the CPU time of the benchmark thread (`triangulation_cpu/...`, read from
//! `/proc/thread-self/schedstat`, Linux only), which is not inflated when other processes
//! share the cores. The CPU-time group reports throughput as ns per element (ray or vertex).
use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use vgps::synthetic::rays::{DriveBy, RayProblem};
use vgps::triangulation::{
    RaySum, intersect_two_rays, triangulate_rays, triangulate_rays_weighted,
};

/// Number of pre-generated problems cycled through (defeats branch-history memorisation).
const POOL: usize = 256;

/// Benchmarks of `vgps::triangulation`, in wall-clock time and in thread CPU time.
pub fn benches(c: &mut Criterion) {
    run("triangulation", c);
    if ThreadCpuTime::available() {
        let mut cpu = Criterion::default()
            .with_measurement(ThreadCpuTime)
            .configure_from_args();
        run("triangulation_cpu", &mut cpu);
    }
}

fn run<M: Measurement>(prefix: &str, c: &mut Criterion<M>) {
    let mut rng = vgps::synthetic::rng(3);
    let pairs: Vec<_> = (0..POOL)
        .map(|_| {
            let p = RayProblem::drive_by(&mut rng, 2, &DriveBy::streetlight(), 0.1, 1e-3);
            let o = p.noisy_observations(&mut rng);
            (o[0].ray, o[1].ray)
        })
        .collect();
    let mut i = 0;
    c.bench_function(&format!("{prefix}/intersect_two_rays"), |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (a, r) = &pairs[i];
            intersect_two_rays(black_box(a), black_box(r))
        })
    });

    let mut group = c.benchmark_group(format!("{prefix}/rays"));
    for n in [2usize, 10, 100] {
        let pool: Vec<_> = (0..POOL)
            .map(|_| {
                RayProblem::around(&mut rng, n, 5.0, 80.0, 0.1, 2e-3).noisy_observations(&mut rng)
            })
            .collect();
        group.throughput(Throughput::Elements(n as u64));
        let mut i = 0;
        group.bench_with_input(BenchmarkId::new("triangulate_rays", n), &pool, |b, pool| {
            b.iter(|| {
                i = (i + 1) % POOL;
                triangulate_rays(black_box(&pool[i]))
            })
        });
        group.bench_with_input(
            BenchmarkId::new("triangulate_rays_weighted", n),
            &pool,
            |b, pool| {
                b.iter(|| {
                    i = (i + 1) % POOL;
                    triangulate_rays_weighted(black_box(&pool[i]))
                })
            },
        );
        group.bench_with_input(
            BenchmarkId::new("ray_sum_add_solve", n),
            &pool,
            |b, pool| {
                b.iter(|| {
                    i = (i + 1) % POOL;
                    let mut sum = RaySum::new();
                    for o in black_box(&pool[i]) {
                        let _ = sum.add(o);
                    }
                    sum.solve()
                })
            },
        );
    }
    group.finish();
}

/// CPU time consumed by the calling thread (nanoseconds), from the scheduler's statistics.
struct ThreadCpuTime;

impl ThreadCpuTime {
    fn read() -> u64 {
        std::fs::read_to_string("/proc/thread-self/schedstat")
            .ok()
            .and_then(|s| s.split_whitespace().next()?.parse().ok())
            .unwrap_or(0)
    }

    fn available() -> bool {
        Self::read() > 0
    }
}

impl Measurement for ThreadCpuTime {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        Self::read()
    }
    fn end(&self, start: u64) -> u64 {
        Self::read().saturating_sub(start)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &NanosFormatter
    }
}

/// Formats CPU times in ns, and throughputs as ns per element.
struct NanosFormatter;

impl ValueFormatter for NanosFormatter {
    fn scale_values(&self, _typical: f64, _values: &mut [f64]) -> &'static str {
        "ns (cpu)"
    }
    fn scale_throughputs(&self, _typical: f64, t: &Throughput, values: &mut [f64]) -> &'static str {
        let per = match *t {
            Throughput::Elements(n) | Throughput::ElementsAndBytes { elements: n, .. } => n,
            Throughput::Bytes(n) | Throughput::BytesDecimal(n) | Throughput::Bits(n) => n,
        } as f64;
        values.iter_mut().for_each(|v| *v /= per.max(1.0));
        "ns/elem (cpu)"
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}
