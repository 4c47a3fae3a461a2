//! The one symmetric 3×3 type of the crate, stored as its upper triangle: used where
//! nalgebra's general `Matrix3` costs measurably (the projector sums of triangulation, the
//! conics of P3P).

/// A symmetric 3×3 matrix stored as its upper triangle (internal, for speed).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Sym3 {
    pub xx: f64,
    pub xy: f64,
    pub xz: f64,
    pub yy: f64,
    pub yz: f64,
    pub zz: f64,
}

impl Sym3 {
    /// The projector `I − uuᵀ` scaled by `w`.
    #[inline(always)]
    pub fn projector(u: &nalgebra::Vector3<f64>, w: f64) -> Self {
        let (wx, wy, wz) = (w * u.x, w * u.y, w * u.z);
        Self {
            xx: w - wx * u.x,
            xy: -wx * u.y,
            xz: -wx * u.z,
            yy: w - wy * u.y,
            yz: -wy * u.z,
            zz: w - wz * u.z,
        }
    }

    /// `w·I`.
    #[inline(always)]
    pub fn diagonal(w: f64) -> Self {
        Self {
            xx: w,
            yy: w,
            zz: w,
            ..Self::default()
        }
    }

    /// `self += w·uuᵀ`.
    #[inline(always)]
    pub fn add_outer(&mut self, w: f64, u: &nalgebra::Vector3<f64>) {
        let (wx, wy, wz) = (w * u.x, w * u.y, w * u.z);
        self.xx += wx * u.x;
        self.xy += wx * u.y;
        self.xz += wx * u.z;
        self.yy += wy * u.y;
        self.yz += wy * u.z;
        self.zz += wz * u.z;
    }

    /// `self − o`.
    #[inline(always)]
    pub fn minus(&self, o: &Self) -> Self {
        Self {
            xx: self.xx - o.xx,
            xy: self.xy - o.xy,
            xz: self.xz - o.xz,
            yy: self.yy - o.yy,
            yz: self.yz - o.yz,
            zz: self.zz - o.zz,
        }
    }

    #[inline(always)]
    pub fn add_assign(&mut self, o: &Self) {
        self.xx += o.xx;
        self.xy += o.xy;
        self.xz += o.xz;
        self.yy += o.yy;
        self.yz += o.yz;
        self.zz += o.zz;
    }

    /// `self += s · o`.
    #[inline(always)]
    pub fn add_scaled(&mut self, s: f64, o: &Self) {
        self.xx += s * o.xx;
        self.xy += s * o.xy;
        self.xz += s * o.xz;
        self.yy += s * o.yy;
        self.yz += s * o.yz;
        self.zz += s * o.zz;
    }

    #[inline(always)]
    pub fn trace(&self) -> f64 {
        self.xx + self.yy + self.zz
    }

    #[inline(always)]
    pub fn mul_vec(&self, v: &nalgebra::Vector3<f64>) -> nalgebra::Vector3<f64> {
        nalgebra::Vector3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// The cofactor (adjugate) matrix, the determinant and `e₂` (sum of principal minors).
    #[inline(always)]
    pub fn cofactors(&self) -> (Self, f64, f64) {
        let c = Self {
            xx: self.yy * self.zz - self.yz * self.yz,
            xy: self.xz * self.yz - self.xy * self.zz,
            xz: self.xy * self.yz - self.xz * self.yy,
            yy: self.xx * self.zz - self.xz * self.xz,
            yz: self.xy * self.xz - self.xx * self.yz,
            zz: self.xx * self.yy - self.xy * self.xy,
        };
        let det = self.xx * c.xx + self.xy * c.xy + self.xz * c.xz;
        (c, det, c.xx + c.yy + c.zz)
    }

    /// `B·S·B` for symmetric `B` (= `self`) and `S`: the sandwich of a covariance.
    #[inline(always)]
    pub fn sandwich(&self, s: &Self) -> Self {
        // T = B·S (all nine entries), then the upper triangle of T·B: 45 products.
        let b = self;
        let row = |b0: f64, b1: f64, b2: f64| {
            [
                b0 * s.xx + b1 * s.xy + b2 * s.xz,
                b0 * s.xy + b1 * s.yy + b2 * s.yz,
                b0 * s.xz + b1 * s.yz + b2 * s.zz,
            ]
        };
        let [t00, t01, t02] = row(b.xx, b.xy, b.xz);
        let [t10, t11, t12] = row(b.xy, b.yy, b.yz);
        let [t20, t21, t22] = row(b.xz, b.yz, b.zz);
        Self {
            xx: t00 * b.xx + t01 * b.xy + t02 * b.xz,
            xy: t00 * b.xy + t01 * b.yy + t02 * b.yz,
            xz: t00 * b.xz + t01 * b.yz + t02 * b.zz,
            yy: t10 * b.xy + t11 * b.yy + t12 * b.yz,
            yz: t10 * b.xz + t11 * b.yz + t12 * b.zz,
            zz: t20 * b.xz + t21 * b.yz + t22 * b.zz,
        }
    }

    #[inline(always)]
    pub fn scale(&self, k: f64) -> Self {
        Self {
            xx: k * self.xx,
            xy: k * self.xy,
            xz: k * self.xz,
            yy: k * self.yy,
            yz: k * self.yz,
            zz: k * self.zz,
        }
    }

    #[inline(always)]
    pub fn to_matrix(self) -> nalgebra::Matrix3<f64> {
        nalgebra::Matrix3::new(
            self.xx, self.xy, self.xz, self.xy, self.yy, self.yz, self.xz, self.yz, self.zz,
        )
    }

    /// The upper triangle of `m`, symmetrised.
    #[inline(always)]
    pub fn from_matrix(m: &nalgebra::Matrix3<f64>) -> Self {
        Self {
            xx: m[(0, 0)],
            xy: 0.5 * (m[(0, 1)] + m[(1, 0)]),
            xz: 0.5 * (m[(0, 2)] + m[(2, 0)]),
            yy: m[(1, 1)],
            yz: 0.5 * (m[(1, 2)] + m[(2, 1)]),
            zz: m[(2, 2)],
        }
    }

    #[inline(always)]
    pub fn is_finite(&self) -> bool {
        (self.xx + self.xy + self.xz + self.yy + self.yz + self.zz).is_finite()
    }

    /// The adjugate (transposed cofactor matrix), symmetric for a symmetric matrix.
    #[inline(always)]
    pub fn adj(&self) -> Self {
        self.cofactors().0
    }

    /// Frobenius inner product `Σᵢⱼ AᵢⱼBᵢⱼ`.
    #[inline(always)]
    pub fn inner(&self, o: &Self) -> f64 {
        self.xx * o.xx
            + self.yy * o.yy
            + self.zz * o.zz
            + 2.0 * (self.xy * o.xy + self.xz * o.xz + self.yz * o.yz)
    }
}
