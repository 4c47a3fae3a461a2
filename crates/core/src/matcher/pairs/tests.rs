//! Unit tests of the pair tables (`super`).

use super::*;
use rand::RngExt;
use vgps_geometry::geometry::angle_between;

#[test]
fn pair_angle_wander_bounds_every_point_of_the_ball() {
    let mut r = vgps_geometry::synthetic::rng(21);
    let mut tighter = 0;
    for _ in 0..2_000 {
        let radius = r.random_range(0.5..10.0);
        let li = Vector3::new(
            r.random_range(-80.0..80.0),
            r.random_range(-80.0..80.0),
            r.random_range(-5.0..30.0),
        );
        // Half the second landmarks near the first (a row of lamps), half anywhere.
        let lj = if r.random::<bool>() {
            li + Vector3::new(
                r.random_range(-30.0..30.0),
                r.random_range(-3.0..3.0),
                r.random_range(-1.0..1.0),
            )
        } else {
            Vector3::new(
                r.random_range(-80.0..80.0),
                r.random_range(-80.0..80.0),
                r.random_range(-5.0..30.0),
            )
        };
        let candidate = |l: &Vector3<f64>| {
            let range = l.norm();
            CellCandidate::new(0, l, l / range, range, radius, 0.0)
        };
        let (ci, cj) = (candidate(&li), candidate(&lj));
        let bound = pair_angle_wander(&ci, &cj, (li - lj).norm(), radius);
        if bound < ci.wander + cj.wander {
            tighter += 1;
        }
        let phi = angle_between(&li, &lj);
        for _ in 0..50 {
            let x = vgps_geometry::synthetic::random_unit_vector(&mut r)
                * radius
                * r.random_range(0.0..1.0f64).cbrt();
            let moved = angle_between(&(li - x), &(lj - x));
            assert!(
                (moved - phi).abs() <= bound + 1e-12,
                "{moved} vs {phi}: bound {bound}"
            );
        }
    }
    // The gradient bound is the tighter one for most pairs.
    assert!(tighter > 1_000, "{tighter}");
}

#[test]
fn survey_angle_bounds_every_survey_error_seen_from_the_ball() {
    let mut r = vgps_geometry::synthetic::rng(22);
    let mut useful = 0;
    for _ in 0..2_000 {
        let radius = r.random_range(0.5..10.0);
        let survey = r.random_range(0.01..2.0);
        let l = vgps_geometry::synthetic::random_unit_vector(&mut r) * r.random_range(0.0..60.0);
        let bound = survey_angle(survey, l.norm(), radius);
        useful += usize::from(bound < 0.1);
        for _ in 0..50 {
            let x = vgps_geometry::synthetic::random_unit_vector(&mut r)
                * radius
                * r.random_range(0.0..1.0f64).cbrt();
            let moved = l + vgps_geometry::synthetic::random_unit_vector(&mut r)
                * survey
                * r.random_range(0.0..1.0f64).cbrt();
            let turn = angle_between(&(moved - x), &(l - x));
            assert!(turn <= bound + 1e-12, "{turn} > {bound}");
        }
    }
    assert!(useful > 1_000, "{useful}");
    assert_eq!(survey_angle(0.0, 5.0, 8.0), 0.0);
}

#[test]
fn det_range_from_above_holds_over_the_cell_and_the_survey_bounds() {
    let mut r = vgps_geometry::synthetic::rng(22);
    let (mut narrow, mut tested) = (0, 0);
    let point = |r: &mut rand_chacha::ChaCha8Rng| {
        Vector3::new(
            r.random_range(-60.0..60.0),
            r.random_range(-60.0..60.0),
            r.random_range(0.0..30.0),
        )
    };
    for _ in 0..2_000 {
        let (li, lj) = (point(&mut r), point(&mut r));
        let (ei, ej) = (r.random_range(0.0..0.5), r.random_range(0.0..0.5));
        let (half, half_z): (f64, f64) = (r.random_range(0.5..10.0), r.random_range(0.0..2.0));
        let radius = (half * half + half_z * half_z).sqrt();
        let (lo, hi) = det_range_from_above((&li, ei), (&lj, ej), &Vector3::zeros(), radius, half);
        assert!(lo <= hi);
        if hi - lo < 0.5 {
            narrow += 1;
        }
        for _ in 0..50 {
            let a = r.random_range(0.0..std::f64::consts::TAU);
            let rho = half * r.random_range(0.0..1.0f64).sqrt();
            let x = Vector3::new(
                rho * a.cos(),
                rho * a.sin(),
                r.random_range(-half_z..=half_z),
            );
            let shift = |r: &mut rand_chacha::ChaCha8Rng, e: f64| {
                vgps_geometry::synthetic::random_unit_vector(r) * e * r.random_range(0.0..=1.0)
            };
            let (pi, pj) = (li + shift(&mut r, ei), lj + shift(&mut r, ej));
            let (ui, uj) = ((pi - x).normalize(), (pj - x).normalize());
            let det = Vector3::z().dot(&ui.cross(&uj));
            assert!(
                det >= lo - 1e-12 && det <= hi + 1e-12,
                "{det} not in [{lo}, {hi}]"
            );
            tested += 1;
        }
    }
    assert!(narrow > 1_000, "{narrow}");
    assert!(tested == 100_000);
}

#[test]
fn det_of_bearings_bounds_every_tilt_and_noise_within_the_tolerances() {
    let mut r = vgps_geometry::synthetic::rng(23);
    for _ in 0..2_000 {
        let up = vgps_geometry::synthetic::random_unit_vector(&mut r);
        let tol = r.random_range(0.0..0.2);
        let noise = r.random_range(0.0..0.01);
        let a = vgps_geometry::synthetic::random_unit_vector(&mut r);
        let b = vgps_geometry::synthetic::random_unit_vector(&mut r);
        let (value, margin) = det_of_bearings(&up, tol, noise, &a, &b);
        // A direction within `angle` of `v`.
        let turn = |r: &mut rand_chacha::ChaCha8Rng, v: &Vector3<f64>, angle: f64| {
            let axis = vgps_geometry::synthetic::random_unit_vector(r);
            match vgps_geometry::geometry::try_unit(&v.cross(&axis)) {
                Some(w) => {
                    let t = angle * r.random_range(0.0..=1.0);
                    v * t.cos() + w * t.sin()
                }
                None => *v,
            }
        };
        for _ in 0..50 {
            let true_up = turn(&mut r, &up, tol);
            let (ta, tb) = (turn(&mut r, &a, noise), turn(&mut r, &b, noise));
            let det = true_up.dot(&ta.cross(&tb));
            assert!(
                (det - value).abs() <= margin + 1e-12,
                "{det} vs {value} ± {margin}"
            );
        }
    }
}
