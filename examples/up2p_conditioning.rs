//! How good is a two-point known-vertical (`up2p`) pose as a matcher hypothesis on the
//! synthetic city? For every pair of true detections (≥ 17° apart) of 300 frames, the up2p
//! pose with the nominal up (`+z`) while the rig really tilts by up to `TILT_DEG` in pitch
//! and roll (0.05° bearing noise): percentiles of its position error and of the worst
//! predicted-direction error over the frame's other true detections.
//!
//! Run: `cargo run --release --example up2p_conditioning -- [TILT_DEG (3)]`
use vgps::geometry::{angle_between, bearing_in_rig};
use vgps::solvers::up2p;
use vgps::synthetic::matcher::{CityConfig, CityWorld, FrameConfig};
use vgps::synthetic::rng;
fn main() {
    let mut r = rng(3);
    let world = CityWorld::generate(&mut r, &CityConfig::default());
    let mut pos = Vec::new();
    let mut dir = Vec::new();
    let tilt: f64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3.0);
    for _ in 0..300 {
        let p0 = world.random_rig_pose(&mut r);
        use rand::RngExt;
        let t = tilt.to_radians();
        let yaw = p0.rotation.matrix()[(1, 0)].atan2(p0.rotation.matrix()[(0, 0)]);
        let pose = vgps::geometry::Pose::from_parts(
            p0.translation,
            nalgebra::Rotation3::from_euler_angles(
                r.random_range(-t..=t),
                r.random_range(-t..=t),
                yaw,
            ),
        );
        let frame = world.frame(&mut r, &pose, &FrameConfig::default());
        let t: Vec<(usize, usize)> = frame
            .truth
            .iter()
            .enumerate()
            .filter_map(|(d, l)| l.map(|l| (d, l)))
            .collect();
        for x in 0..t.len() {
            for y in x + 1..t.len() {
                let (a, i) = t[x];
                let (b, j) = t[y];
                if angle_between(&frame.detections[a], &frame.detections[b]) < 0.3 {
                    continue;
                }
                let pts = [world.landmarks[i], world.landmarks[j]];
                let sols = up2p(
                    &nalgebra::Vector3::z(),
                    &[frame.detections[a], frame.detections[b]],
                    &pts,
                );
                let Some(best) = sols.iter().min_by(|p, q| {
                    (p.translation.vector - pose.translation.vector)
                        .norm()
                        .total_cmp(&(q.translation.vector - pose.translation.vector).norm())
                }) else {
                    pos.push(1e9);
                    dir.push(1e9);
                    continue;
                };
                pos.push((best.translation.vector - pose.translation.vector).norm());
                let mut worst: f64 = 0.0;
                for &(c, k) in &t {
                    if c == a || c == b {
                        continue;
                    }
                    if let Some(p) = bearing_in_rig(best, &world.landmarks[k]) {
                        worst = worst.max(angle_between(&p, &frame.detections[c]));
                    }
                }
                dir.push(worst.to_degrees());
            }
        }
    }
    pos.sort_by(f64::total_cmp);
    dir.sort_by(f64::total_cmp);
    let q = |v: &Vec<f64>, f: f64| v[((v.len() as f64 - 1.0) * f) as usize];
    println!(
        "n {} pos err m: p50 {:.2} p75 {:.2} p90 {:.2} p99 {:.2}",
        pos.len(),
        q(&pos, 0.5),
        q(&pos, 0.75),
        q(&pos, 0.9),
        q(&pos, 0.99)
    );
    println!(
        "worst dir err deg: p50 {:.2} p75 {:.2} p90 {:.2} p99 {:.2}",
        q(&dir, 0.5),
        q(&dir, 0.75),
        q(&dir, 0.9),
        q(&dir, 0.99)
    );
}
