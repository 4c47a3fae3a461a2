//! The search cells: the grid over a box, the rings over a disc, and the elevation range of a
//! landmark over a cell.

use super::fast_math::{FAST_ATAN_MAX_ERROR_RAD, fast_atan2};
use super::{MAX_CELLS, MatchError, SearchArea};
use nalgebra::{Vector2, Vector3};

/// The shape of the search cells. Every cell lies within the vertical cylinder of radius
/// `half_horizontal` and half-height `half_vertical` around its centre, and within the ball
/// of `radius` around it.
#[derive(Clone, Copy, Debug)]
pub(super) struct CellShape {
    /// Radius of the ball around a centre that holds the cell, metres.
    pub(super) radius: f64,
    /// Horizontal radius of the cylinder that holds the cell, metres.
    pub(super) half_horizontal: f64,
    /// Half-height of the cell, metres.
    pub(super) half_vertical: f64,
}

/// Relative widening of the disc a ring covering must cover (and narrowing of the cells'
/// radius it may use), for the rounding of the centres' positions.
pub(super) const RING_COVER_SLACK: f64 = 1e-9;

/// How many ring sizes past the fewest that can close a ring are compared (each ring takes
/// the size that covers the most area per cell).
pub(super) const RING_SIZES_TRIED: usize = 24;

/// Centres (relative to the disc's centre) of discs of radius `r` that together cover the
/// disc of radius `big`; `Err(count)` once more than `limit` would be needed.
///
/// Rings from the outside in, then one disc at the centre. `n` discs whose centres are
/// evenly spaced on the circle of radius `ρ` cover every point at a distance `t` from the
/// centre with `t² + ρ² − 2tρ cos α ≤ r²`, `α = π/n` (the point midway between two
/// centres is the farthest from both), i.e. the annulus
/// `ρ cos α ∓ √(r² − ρ² sin² α)`. A ring whose outer edge is the radius still to cover,
/// `R`, has `ρ = R cos α − √(r² − R² sin² α)` (the smaller root of
/// `ρ² − 2Rρ cos α + R² − r² = 0`, real when `R sin α ≤ r`; positive while `R > r`), and
/// covers down to its inner edge, the next ring's `R`. Of the ring sizes that close, the one
/// that covers the most area per disc is taken. A disc of radius 30 m with `r` = 8.5 m
/// takes rings of 13 and 7 cells and the centre: 21 cells, against the 25 squares of 12 m
/// (the same half-diagonal) over its bounding box.
pub(super) fn ring_centres(big: f64, r: f64, limit: usize) -> Result<Vec<Vector2<f64>>, usize> {
    let r = r * (1.0 - RING_COVER_SLACK);
    let mut outer = big * (1.0 + RING_COVER_SLACK) + RING_COVER_SLACK;
    let mut centres = Vec::new();
    while outer > r {
        // The fewest cells that can close a ring: `outer · sin(π/n) ≤ r`.
        let fewest = (std::f64::consts::PI / (r / outer).asin()).ceil().max(3.0) as usize;
        let mut best: Option<(f64, f64, usize, f64)> = None;
        for n in fewest..fewest + RING_SIZES_TRIED {
            let (sin_a, cos_a) = (std::f64::consts::PI / n as f64).sin_cos();
            let d = r * r - (outer * sin_a).powi(2);
            if d < 0.0 {
                continue;
            }
            let rho = outer * cos_a - d.sqrt();
            let inner = rho * cos_a - (r * r - (rho * sin_a).powi(2)).max(0.0).sqrt();
            let per_cell = (outer * outer - inner.max(0.0).powi(2)) / n as f64;
            if best.is_none_or(|(b, ..)| per_cell > b) {
                best = Some((per_cell, inner, n, rho));
            }
        }
        let Some((_, inner, n, rho)) = best else {
            break;
        };
        if centres.len() + n > limit {
            return Err(centres.len() + n);
        }
        centres.extend((0..n).map(|k| {
            let (sin, cos) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
            Vector2::new(rho * cos, rho * sin)
        }));
        if inner <= 0.0 {
            return Ok(centres);
        }
        outer = inner;
    }
    if centres.len() >= limit {
        return Err(centres.len() + 1);
    }
    centres.push(Vector2::zeros());
    Ok(centres)
}

/// The cells that cover the search area: their centres and shape.
///
/// A box: a grid of `size`-edged cells (as many along each axis as it takes, stretched to
/// fit). A cylinder: layers of height `size` (stretched to fit), each covered by rings of
/// round cells with the half-diagonal of a square `size` cell ([`ring_centres`]); a cell
/// whose disc misses the box is dropped.
pub(super) fn cells(
    area: &SearchArea,
    size: f64,
) -> Result<(Vec<Vector3<f64>>, CellShape), MatchError> {
    let extent = area.max_in_world - area.min_in_world;
    let count = |e: f64| ((e / size).ceil() as usize).max(1);
    if let Some(big) = area.horizontal_radius_m {
        if !(big.is_finite() && big >= 0.0) {
            return Err(MatchError::InvalidArea);
        }
        let layers = count(extent.z);
        let height = extent.z / layers as f64;
        let half_horizontal = size * std::f64::consts::FRAC_1_SQRT_2;
        let half_vertical = 0.5 * height;
        let centre = area.center();
        let limit = MAX_CELLS / layers;
        let ring = ring_centres(big, half_horizontal, limit)
            .map_err(|n| MatchError::AreaTooLarge(n.saturating_mul(layers)))?;
        // The cells whose disc meets the box (all of them for `SearchArea::around`).
        let ring: Vec<Vector2<f64>> = ring
            .into_iter()
            .map(|p| centre.xy() + p)
            .filter(|p| {
                let nearest = Vector2::new(
                    p.x.clamp(area.min_in_world.x, area.max_in_world.x),
                    p.y.clamp(area.min_in_world.y, area.max_in_world.y),
                );
                (nearest - p).norm() <= half_horizontal
            })
            .collect();
        let centres = (0..layers)
            .flat_map(|iz| {
                let z = area.min_in_world.z + height * (iz as f64 + 0.5);
                ring.iter().map(move |p| Vector3::new(p.x, p.y, z))
            })
            .collect();
        let shape = CellShape {
            radius: half_horizontal.hypot(half_vertical),
            half_horizontal,
            half_vertical,
        };
        return Ok((centres, shape));
    }
    let counts: Vec<usize> = (0..3).map(|k| count(extent[k])).collect();
    let total = counts[0]
        .saturating_mul(counts[1])
        .saturating_mul(counts[2]);
    if total > MAX_CELLS {
        return Err(MatchError::AreaTooLarge(total));
    }
    let step = Vector3::from_fn(|k, _| extent[k] / counts[k] as f64);
    let mut centres = Vec::with_capacity(total);
    for iz in 0..counts[2] {
        for iy in 0..counts[1] {
            for ix in 0..counts[0] {
                let f = Vector3::new(ix as f64 + 0.5, iy as f64 + 0.5, iz as f64 + 0.5);
                centres.push(area.min_in_world + step.component_mul(&f));
            }
        }
    }
    let shape = CellShape {
        radius: 0.5 * step.norm(),
        half_horizontal: 0.5 * step.xy().norm(),
        half_vertical: 0.5 * step.z,
    };
    Ok((centres, shape))
}

/// The range of elevations (radians) of the offset `v = L − c` seen from every point of the
/// cylinder of horizontal radius `half_horizontal` and half-height `half_vertical` around the
/// cell centre `c` (which contains the cell). Elevation `atan2(dz, d)` is monotone in the
/// height difference `dz` and in the horizontal distance `d ≥ 0` separately, so its extremes
/// are at the corners of `[dz ± half_vertical] × [max(0, d − half_horizontal), d +
/// half_horizontal]`. Evaluated by [`fast_atan2`] and widened by its error bound, so the
/// range still holds every elevation.
pub(super) fn elevation_range(
    v: &Vector3<f64>,
    half_horizontal: f64,
    half_vertical: f64,
) -> (f64, f64) {
    let d = v.xy().norm();
    let (d_lo, d_hi) = ((d - half_horizontal).max(0.0), d + half_horizontal);
    let (dz_lo, dz_hi) = (v.z - half_vertical, v.z + half_vertical);
    // Increasing in `dz`; in `d`, decreasing above the viewpoint and increasing below it:
    // the two extreme corners, without evaluating the other two.
    let lo = fast_atan2(dz_lo, if dz_lo >= 0.0 { d_hi } else { d_lo });
    let hi = fast_atan2(dz_hi, if dz_hi >= 0.0 { d_lo } else { d_hi });
    (lo - FAST_ATAN_MAX_ERROR_RAD, hi + FAST_ATAN_MAX_ERROR_RAD)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn elevation_range_bounds_every_point_of_the_cylinder() {
        let mut r = vgps_geometry::synthetic::rng(4);
        for _ in 0..200 {
            let v = Vector3::new(
                r.random_range(-60.0..60.0),
                r.random_range(-60.0..60.0),
                r.random_range(-5.0..20.0),
            );
            let (hh, hz) = (r.random_range(0.5..10.0), r.random_range(0.0..2.0));
            let (lo, hi) = elevation_range(&v, hh, hz);
            assert!(lo <= hi);
            for _ in 0..50 {
                let a = r.random_range(0.0..std::f64::consts::TAU);
                let rho = hh * r.random_range(0.0..1.0f64).sqrt();
                let x = Vector3::new(rho * a.cos(), rho * a.sin(), r.random_range(-hz..=hz));
                let w = v - x;
                let e = w.z.atan2(w.xy().norm());
                assert!(
                    e >= lo - 1e-12 && e <= hi + 1e-12,
                    "{e} not in [{lo}, {hi}]"
                );
            }
            // Tight: the centre's own elevation is inside, and the corners are reached.
            let e0 = v.z.atan2(v.xy().norm());
            assert!(lo <= e0 && e0 <= hi);
        }
    }

    #[test]
    fn ring_centres_cover_every_point_of_the_disc() {
        let mut g = vgps_geometry::synthetic::rng(21);
        for (big, r) in [
            (30.0, 12.0 * std::f64::consts::FRAC_1_SQRT_2),
            (30.0, 5.0),
            (15.0, 8.0),
            (7.9, 8.0),
            (0.0, 8.0),
            (250.0, 8.5),
            (1.0, 0.05),
        ] {
            let centres = ring_centres(big, r, MAX_CELLS).unwrap();
            let nearest = |p: Vector2<f64>| {
                centres
                    .iter()
                    .map(|c| (p - c).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            // Random points, and the circle's edge densely (where a ring's gaps are).
            for k in 0..20_000 {
                let p = if k % 2 == 0 {
                    let (t, u): (f64, f64) = (g.random_range(0.0..1.0), g.random_range(0.0..1.0));
                    let (sin, cos) = (std::f64::consts::TAU * t).sin_cos();
                    Vector2::new(cos, sin) * (big * u.sqrt())
                } else {
                    let (sin, cos) = (std::f64::consts::TAU * k as f64 / 20_000.0).sin_cos();
                    Vector2::new(cos, sin) * big
                };
                assert!(nearest(p) <= r, "{big} {r}: {p:?} is {} away", nearest(p));
            }
            // Fewer cells than the grid over the bounding box, for a disc of a few cells.
            let side = r * std::f64::consts::SQRT_2;
            let grid = ((2.0 * big / side).ceil().max(1.0) as usize).pow(2);
            assert!(
                centres.len() <= grid,
                "{big} {r}: {} > {grid}",
                centres.len()
            );
        }
        // The prior of the Monte Carlo (30 m, 12 m cells): 21 cells instead of 25.
        let prior = ring_centres(30.0, 12.0 * std::f64::consts::FRAC_1_SQRT_2, MAX_CELLS);
        assert_eq!(prior.map(|c| c.len()), Ok(21));
        // Too many cells: refused with the count so far.
        assert!(ring_centres(1e4, 1.0, 1000).is_err_and(|n| n > 1000));
    }
}
