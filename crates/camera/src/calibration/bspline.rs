//! Tensor-product cubic B-spline surfaces `f(x, y)`, as the Ladybug SDK stores its warps.
//!
//! A surface has knot vectors `U` (along x, `nx + 4` knots) and `V` (along y, `ny + 4`
//! knots), non-decreasing, and `nx · ny` coefficients; coefficient `(i, j)` (i along x,
//! j along y) is stored at index `i · ny + j` (x-major: the first `ny` coefficients are the
//! column `i = 0`), the order of the Ladybug `.conf` file. The value is
//! `f(x, y) = Σᵢ Σⱼ Nᵢ(x) Mⱼ(y) c(i, j)` with `Nᵢ`, `Mⱼ` the cubic B-spline basis functions
//! of `U` and `V` (Cox–de Boor). The domain is `[U₃, U_nx] × [V₃, V_ny]` (for a clamped
//! spline, the first and last knots); outside it the polynomial piece of the nearest span is
//! continued (smooth extrapolation, used only by Newton iterations that step a little out).
//!
//! Evaluation works on the four non-zero basis functions of the span holding `x` (de Boor's
//! triangular recurrence, "The NURBS Book" algorithm A2.2), with their first derivatives from
//! the degree-2 functions of the same span: 16 coefficients per value.

use serde::{Deserialize, Serialize};

/// The degree of the splines (cubic).
pub const DEGREE: usize = 3;

/// A cubic tensor-product B-spline surface (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "BSplineSurfaceParams", into = "BSplineSurfaceParams")]
pub struct BSplineSurface {
    params: BSplineSurfaceParams,
}

/// The serde form of a [`BSplineSurface`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BSplineSurfaceParams {
    /// Knots along x (`nx + 4`, non-decreasing, finite).
    pub knots_x: Vec<f64>,
    /// Knots along y (`ny + 4`, non-decreasing, finite).
    pub knots_y: Vec<f64>,
    /// Coefficients, `nx · ny`, coefficient `(i, j)` at index `i · ny + j`.
    pub coefs: Vec<f64>,
}

/// The four non-zero basis values and derivatives at `x` of the span `span`
/// (`U[span] ≤ x < U[span + 1]` inside the domain), for `N_{span−3} … N_span`.
#[inline]
fn basis(knots: &[f64], span: usize, x: f64) -> ([f64; 4], [f64; 4]) {
    let mut n = [1.0, 0.0, 0.0, 0.0];
    let mut left = [0.0; 4];
    let mut right = [0.0; 4];
    let mut quadratic = [0.0; 3];
    for j in 1..=DEGREE {
        left[j] = x - knots[span + 1 - j];
        right[j] = knots[span + j] - x;
        let mut saved = 0.0;
        for r in 0..j {
            let denominator = right[r + 1] + left[j - r];
            let temp = if denominator == 0.0 {
                0.0
            } else {
                n[r] / denominator
            };
            n[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        n[j] = saved;
        if j == DEGREE - 1 {
            quadratic = [n[0], n[1], n[2]];
        }
    }
    // N'_{k,3} = 3 N_{k,2} / (U[k+3] − U[k]) − 3 N_{k+1,2} / (U[k+4] − U[k+1]), k = span−3+r;
    // the non-zero quadratics at the span are N_{span−2,2} … N_{span,2} = quadratic[0..3].
    let mut d = [0.0; 4];
    let ratio = |value: f64, a: usize, b: usize| {
        let h = knots[b] - knots[a];
        if h == 0.0 { 0.0 } else { value / h }
    };
    for (r, dr) in d.iter_mut().enumerate() {
        let k = span + r - 3;
        let first = if r >= 1 {
            ratio(quadratic[r - 1], k, k + 3)
        } else {
            0.0
        };
        let second = if r <= 2 {
            ratio(quadratic[r], k + 1, k + 4)
        } else {
            0.0
        };
        *dr = 3.0 * (first - second);
    }
    (n, d)
}

/// The span index `k ∈ [3, n − 1]` with `U[k] ≤ x < U[k + 1]`, the end spans taken for `x`
/// outside the domain (and for NaN).
#[inline]
fn find_span(knots: &[f64], n: usize, x: f64) -> usize {
    // Last span whose start is ≤ x, among the spans of the domain with a non-zero length.
    let mut lo = DEGREE;
    let mut hi = n; // exclusive
    // Binary search for the largest k in [3, n) with knots[k] <= x.
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if knots[mid] <= x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // Skip back over zero-length spans (repeated interior knots at the end of the domain).
    while lo > DEGREE && knots[lo + 1] == knots[lo] {
        lo -= 1;
    }
    lo
}

impl BSplineSurface {
    /// Validates: at least 4 coefficients per axis (`nx, ny ≥ 4`), knot counts `nx + 4` and
    /// `ny + 4` given by `coefs.len() = nx · ny`, finite non-decreasing knots with a domain
    /// of non-zero length, finite coefficients. `nx` is `knots_x.len() − 4`.
    ///
    /// # Errors
    /// The reason, naming the offending knot or coefficient (0-based index).
    pub fn new(params: BSplineSurfaceParams) -> Result<Self, String> {
        let p = &params;
        for (name, knots) in [("KnotsX", &p.knots_x), ("KnotsY", &p.knots_y)] {
            if knots.len() < 2 * (DEGREE + 1) {
                return Err(format!(
                    "{name}: {} knots, a cubic spline needs at least {}",
                    knots.len(),
                    2 * (DEGREE + 1)
                ));
            }
            for (k, v) in knots.iter().enumerate() {
                if !v.is_finite() {
                    return Err(format!("{name}: knot {k} = {v} is not finite"));
                }
                if k > 0 && *v < knots[k - 1] {
                    return Err(format!(
                        "{name}: knot {k} = {v} is smaller than knot {} = {} (knots must not \
                         decrease)",
                        k - 1,
                        knots[k - 1]
                    ));
                }
            }
            let n = knots.len() - DEGREE - 1;
            if !(knots[n] > knots[DEGREE]) {
                return Err(format!(
                    "{name}: the domain [{}, {}] is empty",
                    knots[DEGREE], knots[n]
                ));
            }
        }
        let nx = p.knots_x.len() - DEGREE - 1;
        let ny = p.knots_y.len() - DEGREE - 1;
        if p.coefs.len() != nx * ny {
            return Err(format!(
                "{} coefficients, but {} × {} knots need {nx} × {ny} = {}",
                p.coefs.len(),
                p.knots_x.len(),
                p.knots_y.len(),
                nx * ny
            ));
        }
        if let Some((k, v)) = p.coefs.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!("coefficient {k} = {v} is not finite"));
        }
        Ok(Self { params })
    }

    /// The parameters.
    pub fn params(&self) -> &BSplineSurfaceParams {
        &self.params
    }

    /// Number of coefficients `(nx, ny)`.
    pub fn size(&self) -> (usize, usize) {
        (
            self.params.knots_x.len() - DEGREE - 1,
            self.params.knots_y.len() - DEGREE - 1,
        )
    }

    /// The domain `((x_min, x_max), (y_min, y_max))`.
    pub fn domain(&self) -> ((f64, f64), (f64, f64)) {
        let (nx, ny) = self.size();
        let (u, v) = (&self.params.knots_x, &self.params.knots_y);
        ((u[DEGREE], u[nx]), (v[DEGREE], v[ny]))
    }

    /// `f(x, y)`.
    #[inline]
    pub fn value(&self, x: f64, y: f64) -> f64 {
        self.value_and_gradient(x, y).0
    }

    /// `f(x, y)` and its gradient `(∂f/∂x, ∂f/∂y)`.
    #[inline]
    pub fn value_and_gradient(&self, x: f64, y: f64) -> (f64, [f64; 2]) {
        let (nx, ny) = self.size();
        let p = &self.params;
        let sx = find_span(&p.knots_x, nx, x);
        let sy = find_span(&p.knots_y, ny, y);
        let (bx, dx) = basis(&p.knots_x, sx, x);
        let (by, dy) = basis(&p.knots_y, sy, y);
        let (mut f, mut fx, mut fy) = (0.0, 0.0, 0.0);
        for a in 0..4 {
            let row = (sx - DEGREE + a) * ny + sy - DEGREE;
            let c = &p.coefs[row..row + 4];
            let (mut s, mut sd) = (0.0, 0.0);
            for b in 0..4 {
                s += by[b] * c[b];
                sd += dy[b] * c[b];
            }
            f += bx[a] * s;
            fx += dx[a] * s;
            fy += bx[a] * sd;
        }
        (f, [fx, fy])
    }
}

impl TryFrom<BSplineSurfaceParams> for BSplineSurface {
    type Error = String;
    fn try_from(params: BSplineSurfaceParams) -> Result<Self, Self::Error> {
        Self::new(params)
    }
}

impl From<BSplineSurface> for BSplineSurfaceParams {
    fn from(s: BSplineSurface) -> Self {
        s.params
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Cox–de Boor recursion, straight from the definition (0/0 = 0), with the
    /// right-closed last span of a clamped domain.
    fn cox_de_boor(knots: &[f64], i: usize, p: usize, x: f64) -> f64 {
        if p == 0 {
            let n = knots.len() - DEGREE - 1;
            let last = knots[n];
            let inside = knots[i] <= x && x < knots[i + 1];
            let at_end = x == last && knots[i + 1] == last && knots[i] < last;
            return if inside || at_end { 1.0 } else { 0.0 };
        }
        let a = if knots[i + p] > knots[i] {
            (x - knots[i]) / (knots[i + p] - knots[i]) * cox_de_boor(knots, i, p - 1, x)
        } else {
            0.0
        };
        let b = if knots[i + p + 1] > knots[i + 1] {
            (knots[i + p + 1] - x) / (knots[i + p + 1] - knots[i + 1])
                * cox_de_boor(knots, i + 1, p - 1, x)
        } else {
            0.0
        };
        a + b
    }

    fn surface() -> BSplineSurface {
        // Clamped, non-uniform, with a double interior knot along y.
        let knots_x = vec![0.0, 0.0, 0.0, 0.0, 0.2, 0.45, 0.7, 1.0, 1.0, 1.0, 1.0];
        let knots_y = vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.3, 0.8, 1.0, 1.0, 1.0, 1.0];
        let (nx, ny) = (knots_x.len() - 4, knots_y.len() - 4);
        let coefs = (0..nx * ny)
            .map(|k| ((k * 37 % 11) as f64 - 5.0) * 0.1 + (k as f64).sin())
            .collect();
        BSplineSurface::new(BSplineSurfaceParams {
            knots_x,
            knots_y,
            coefs,
        })
        .expect("valid surface")
    }

    fn direct(s: &BSplineSurface, x: f64, y: f64) -> f64 {
        let p = s.params();
        let (nx, ny) = s.size();
        let mut f = 0.0;
        for i in 0..nx {
            for j in 0..ny {
                f += cox_de_boor(&p.knots_x, i, 3, x)
                    * cox_de_boor(&p.knots_y, j, 3, y)
                    * p.coefs[i * ny + j];
            }
        }
        f
    }

    #[test]
    fn matches_the_direct_basis_evaluation_over_the_domain() {
        let s = surface();
        let mut worst: f64 = 0.0;
        for a in 0..=40 {
            for b in 0..=40 {
                let (x, y) = (f64::from(a) / 40.0, f64::from(b) / 40.0);
                worst = worst.max((s.value(x, y) - direct(&s, x, y)).abs());
            }
        }
        assert!(worst < 1e-13, "largest difference {worst:e}");
    }

    #[test]
    fn partition_of_unity_and_linear_precision() {
        // Coefficients all 1 give 1; Greville abscissae as coefficients give f(x, y) = x.
        let s = surface();
        let p = s.params().clone();
        let (nx, ny) = s.size();
        let ones = BSplineSurface::new(BSplineSurfaceParams {
            coefs: vec![1.0; nx * ny],
            ..p.clone()
        })
        .expect("valid");
        let greville: Vec<f64> = (0..nx)
            .flat_map(|i| {
                let g = (p.knots_x[i + 1] + p.knots_x[i + 2] + p.knots_x[i + 3]) / 3.0;
                std::iter::repeat_n(g, ny)
            })
            .collect();
        let linear = BSplineSurface::new(BSplineSurfaceParams {
            coefs: greville,
            ..p
        })
        .expect("valid");
        for (x, y) in [
            (0.0, 0.0),
            (0.13, 0.3),
            (0.5, 0.77),
            (1.0, 1.0),
            (0.999, 0.2),
        ] {
            assert!((ones.value(x, y) - 1.0).abs() < 1e-14);
            let (f, g) = linear.value_and_gradient(x, y);
            assert!((f - x).abs() < 1e-14, "{f} vs {x}");
            assert!((g[0] - 1.0).abs() < 1e-12 && g[1].abs() < 1e-12, "{g:?}");
        }
    }

    #[test]
    fn gradient_matches_central_differences() {
        let s = surface();
        let h = 1e-6;
        for (x, y) in [(0.1, 0.1), (0.33, 0.61), (0.69, 0.29), (0.9, 0.95)] {
            let (_, g) = s.value_and_gradient(x, y);
            let gx = (s.value(x + h, y) - s.value(x - h, y)) / (2.0 * h);
            let gy = (s.value(x, y + h) - s.value(x, y - h)) / (2.0 * h);
            assert!((g[0] - gx).abs() < 1e-6 && (g[1] - gy).abs() < 1e-6);
        }
    }

    #[test]
    fn rejects_decreasing_knots_wrong_counts_and_non_finite_values() {
        let p = surface().params().clone();
        let mut bad = p.clone();
        bad.knots_x[5] = 0.1;
        let e = BSplineSurface::new(bad).unwrap_err();
        assert!(e.contains("KnotsX: knot 5"), "{e}");
        let mut bad = p.clone();
        bad.coefs.pop();
        assert!(
            BSplineSurface::new(bad)
                .unwrap_err()
                .contains("coefficients")
        );
        let mut bad = p.clone();
        bad.coefs[3] = f64::NAN;
        assert!(
            BSplineSurface::new(bad)
                .unwrap_err()
                .contains("coefficient 3")
        );
        let mut bad = p;
        bad.knots_y.truncate(7);
        assert!(BSplineSurface::new(bad).is_err());
    }
}
