//! Unit tests of the search (`super`).

use super::*;
use crate::matcher::DbLandmark;
use crate::matcher::pairs::{CellCache, PairValues};
use rand::RngExt;
use vgps_geometry::geometry::Ray;

/// Building corners at random on a `side`-metre square (heights 3–25 m, exact survey),
/// a rig at the square's centre 2 m up (rig frame = world frame, z up), and exact
/// bearings to its 15 nearest landmarks within 70 m plus three stray lights above the
/// horizon.
fn scene(seed: u64, count: usize, side: f64) -> (LandmarkDb, Vec<Detection>, Vector3<f64>) {
    let mut r = vgps_geometry::synthetic::rng(seed);
    let landmarks: Vec<DbLandmark> = (0..count)
        .map(|k| DbLandmark {
            id: format!("L{k}"),
            position_in_world: Vector3::new(
                r.random_range(0.0..side),
                r.random_range(0.0..side),
                r.random_range(3.0..25.0),
            ),
            class: None,
            sigma_m: 0.0,
        })
        .collect();
    let rig = Vector3::new(0.5 * side, 0.5 * side, 2.0);
    let mut near: Vec<(f64, Vector3<f64>)> = landmarks
        .iter()
        .map(|l| ((l.position_in_world - rig).norm(), l.position_in_world))
        .filter(|&(d, _)| d < 70.0)
        .collect();
    near.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut detections: Vec<Detection> = near
        .iter()
        .take(15)
        .map(|(d, p)| {
            Detection::new(Ray {
                origin: Vector3::zeros(),
                direction: (p - rig) / *d,
            })
        })
        .collect();
    for _ in 0..3 {
        let mut v = vgps_geometry::synthetic::random_unit_vector(&mut r);
        v.z = v.z.abs();
        detections.push(Detection::new(Ray {
            origin: Vector3::zeros(),
            direction: v,
        }));
    }
    let db = LandmarkDb::new(landmarks).expect("a valid database");
    (db, detections, rig)
}

fn upright() -> MatchOptions {
    MatchOptions {
        up_in_rig: Some((Vector3::z(), 4f64.to_radians())),
        ..MatchOptions::default()
    }
}

/// The same cold start with every cell's cache kept, with none kept and with a budget
/// that covers part of the cells gives the same result; the bytes held never exceed the
/// budget.
#[test]
fn a_cold_start_gives_the_same_result_whatever_the_cache_budget() {
    let (db, detections, rig) = scene(31, 300, 400.0);
    let area = SearchArea::over_landmarks(&db, 0.0, 1.0, 3.0).expect("an area");
    let options = upright();
    let run = |budget| {
        run_with_cache_budget(&db, &detections, &area, &options, budget).expect("a valid search")
    };
    let (full, full_use) = run(usize::MAX);
    assert_eq!(full.status, MatchStatus::Ok, "{}", full.message);
    let estimate = full.estimate.as_ref().expect("a fix");
    let error = (estimate.world_from_rig.translation.vector - rig).norm();
    assert!(error < 0.5, "{error} m from the rig");
    assert!(full.cells > 1_000, "{} cells", full.cells);
    assert_eq!(full_use.transient_cells, 0);
    assert!(full_use.stored_cells > 1_000, "{full_use:?}");

    let (none, none_use) = run(0);
    assert_eq!(none, full);
    // The public entry takes the budget from the options.
    let no_cache = MatchOptions {
        cache_budget_bytes: 0,
        ..options
    };
    assert_eq!(
        super::run(&db, &detections, &area, &no_cache).as_ref(),
        Ok(&full)
    );
    assert_eq!(none_use.stored_cells, 0);
    assert_eq!(none_use.peak_bytes, 0);
    assert!(none_use.transient_cells > 1_000, "{none_use:?}");

    let part = full_use.peak_bytes / 4;
    let (some, some_use) = run(part);
    assert_eq!(some, full);
    assert!(some_use.stored_cells > 0, "{some_use:?}");
    assert!(some_use.transient_cells > 0, "{some_use:?}");
    assert!(some_use.peak_bytes <= part, "{some_use:?} over {part}");
}

/// Per cell, every pair table built from the kept (dense) pair values equals the one
/// built from values computed on the spot, and every kept value equals the one computed
/// on the spot; in the cell nearest the rig, the true landmarks of two detections pass.
#[test]
fn transient_tables_and_pair_values_equal_the_kept_ones() {
    let (db, detections, rig) = scene(32, 200, 300.0);
    let options = upright();
    let area = SearchArea::around(&rig, 30.0, 1.0).expect("an area");
    let directions: Vec<Vector3<f64>> = detections.iter().map(|d| d.ray.direction).collect();
    let angles = bearing_angles(&directions);
    let up = known_up(&options).expect("a valid up");
    let search = Search::new(&db, &detections, directions, angles, up, &area, &options)
        .with_cache_budget(usize::MAX);
    let (centres, shape) = cells(&area, options.cell_size_m).expect("cells");
    let reach = area_reach(&area, shape.radius, &options);
    let (mut cells, context) = cell_data(&search, centres, &area.center(), reach, &shape);
    assert!(cells.len() > 10, "{} cells", cells.len());
    let n = detections.len();
    let mut transient = Vec::new();
    let (mut tables, mut passing) = (0, 0);
    for cell in cells.iter_mut() {
        search.decide_cache(cell);
        assert_eq!(cell.cache, CellCache::Stored);
        let (m, words) = (cell.cands.len(), cell.words);
        for a in 0..n {
            for b in (0..n).filter(|&b| b != a) {
                search.room_for_tables(cell, 1);
                search.ensure_table(cell, &context, a, b);
                transient.clear();
                transient.resize(m * words, 0);
                search.transient_table(cell, &context, a, b, &mut transient);
                assert_eq!(cell.table(a * n + b), &transient[..]);
                tables += 1;
                passing += transient.iter().map(|w| w.count_ones()).sum::<u32>();
            }
        }
        for i in 0..m {
            for j in (0..m).filter(|&j| j != i) {
                if cell.pairs_done[i * words + j / 64] >> (j % 64) & 1 == 0 {
                    continue;
                }
                let (ri, rj) = (cell.rows[i] as usize, cell.rows[j] as usize);
                let kept: PairValues = cell.pairs[ri * cell.used + rj];
                let now = cell.pair_values(&db, &context, i, j);
                assert_eq!(kept.angle.to_bits(), now.angle.to_bits());
                assert_eq!(kept.bound.to_bits(), now.bound.to_bits());
                assert_eq!(kept.det.0.to_bits(), now.det.0.to_bits());
                assert_eq!(kept.det.1.to_bits(), now.det.1.to_bits());
            }
        }
    }
    assert!(
        tables > 1_000 && passing > 1_000,
        "{tables} tables, {passing} bits"
    );
    // The known answer: from the cell nearest the rig, detection 0 and 1 (the two
    // nearest landmarks) are their true landmarks.
    let nearest = cells
        .iter()
        .min_by(|x, y| (x.centre - rig).norm().total_cmp(&(y.centre - rig).norm()))
        .expect("a cell");
    let truth = |d: usize| {
        (0..nearest.cands.len())
            .find(|&c| {
                let l = db.landmarks()[nearest.cands[c].index].position_in_world;
                ((l - rig).normalize() - detections[d].ray.direction).norm() < 1e-9
            })
            .expect("the true landmark is a candidate")
    };
    let (i, j) = (truth(0), truth(1));
    let row = &nearest.table(1)[i * nearest.words..(i + 1) * nearest.words];
    assert_eq!(row[j / 64] >> (j % 64) & 1, 1, "the true pair passes");
}
