//! The whole-image stage of the vertex detector ([`super::vertex`]): Sobel gradients and
//! the Shi–Tomasi response (the smaller eigenvalue of the mean structure tensor over a
//! (2·`radius` + 1)² window), computed in integers.
//!
//! Why integers: a Sobel sum of 8-bit pixels is an integer of at most 4 · 255 in
//! magnitude, so the gradients (DN per pixel, the sums / 8) are stored exactly as `i16`
//! sums, and the tensor's window sums of their products are exact in `i32`. The former
//! `f32` pipeline computed the same sums exactly as long as each partial sum stayed below
//! 2²⁴ (a window of 25 gradients all above ≈ 100 DN per pixel); within that, the responses
//! here are bit-identical to it (the tests compare them), and beyond it these are the exact
//! ones. Exact sums also allow any summation order, so the window sums run as a few passes
//! of shifted slice additions that the compiler vectorises, and the buffers are reused
//! across images ([`Scratch`]) instead of allocating eight image-sized arrays per image.

/// Sobel gradients of an image as the kernel's integer sums (eighths of a DN per pixel);
/// zero on the one-pixel border.
#[derive(Clone, Debug, Default)]
pub(crate) struct Gradients {
    /// Width (pixels).
    pub w: usize,
    /// Height (pixels).
    pub h: usize,
    /// Horizontal Sobel sums, row-major.
    pub kx: Vec<i16>,
    /// Vertical Sobel sums, row-major.
    pub ky: Vec<i16>,
    /// Row buffers of [`Gradients::compute`]: the vertical and the horizontal smoothing.
    column_sum: Vec<i16>,
    column_diff: Vec<i16>,
}

impl Gradients {
    /// The gradient `(∂/∂u, ∂/∂v)` at the row-major index `j` (DN per pixel).
    #[inline]
    pub fn at(&self, j: usize) -> (f64, f64) {
        (f64::from(self.kx[j]) / 8.0, f64::from(self.ky[j]) / 8.0)
    }

    /// Computes the gradients of the `w` × `h` 8-bit image `src` (row-major), reusing the
    /// buffers. An image narrower or lower than 3 pixels has zero gradients; `src` shorter
    /// than `w · h` gives zero gradients too (never a panic).
    pub fn compute(&mut self, src: &[u8], w: usize, h: usize) {
        self.w = w;
        self.h = h;
        if w < 3 || h < 3 || src.len() < w * h {
            for k in [&mut self.kx, &mut self.ky] {
                k.clear();
                k.resize(w * h, 0);
            }
            return;
        }
        // The interior is written below; only the one-pixel border is zeroed here (a
        // clearing pass over the whole image costs as much as the kernel).
        for k in [&mut self.kx, &mut self.ky] {
            k.resize(w * h, 0);
            k[..w].fill(0);
            k[(h - 1) * w..].fill(0);
            for v in 1..h - 1 {
                k[v * w] = 0;
                k[v * w + w - 1] = 0;
            }
        }
        self.column_sum.resize(w, 0);
        self.column_diff.resize(w, 0);
        let (s, d) = (&mut self.column_sum, &mut self.column_diff);
        for v in 1..h - 1 {
            let above = &src[(v - 1) * w..v * w];
            let row = &src[v * w..(v + 1) * w];
            let below = &src[(v + 1) * w..(v + 2) * w];
            // The kernel is separable: [1 2 1] across times [−1 0 1] along.
            for u in 0..w {
                let (a, b, c) = (i16::from(above[u]), i16::from(row[u]), i16::from(below[u]));
                s[u] = a + 2 * b + c;
                d[u] = c - a;
            }
            let kx = &mut self.kx[v * w + 1..(v + 1) * w - 1];
            for (k, (l, r)) in kx.iter_mut().zip(s.iter().zip(&s[2..])) {
                *k = r - l;
            }
            let ky = &mut self.ky[v * w + 1..(v + 1) * w - 1];
            for (k, ((l, m), r)) in ky.iter_mut().zip(d.iter().zip(&d[1..]).zip(&d[2..])) {
                *k = l + 2 * m + r;
            }
        }
    }
}

/// Buffers of the whole-image stage, kept per thread between images.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    /// The gradients of the last image.
    pub gradients: Gradients,
    /// The Shi–Tomasi response of the last image, row-major ((DN/px)²).
    pub response: Vec<f32>,
    /// Horizontal window sums of the three tensor products for the last 2·radius + 2 rows.
    ring: Vec<i32>,
    /// Tensor products of one row.
    products: Vec<i32>,
    /// Vertical window sums of one row.
    sums: Vec<i32>,
}

impl Scratch {
    /// Fills [`Scratch::response`] from [`Scratch::gradients`]: the smaller eigenvalue of
    /// the mean structure tensor over a (2·`radius` + 1)² window (borders clamped). With
    /// gradients `k / 8` the tensor's sums are `Σk² / 64`, and the arithmetic after the
    /// sums is the former `f32` one, operation by operation.
    ///
    /// With `floor` (the detector's smallest response, > 1), a pixel whose tensor has a
    /// diagonal sum below `floor − 0.1` (in units of the mean) gets `−∞` instead of its
    /// response: the smaller eigenvalue is at most the smaller diagonal entry, and the
    /// `f32` evaluation errs by under 0.01 (≈ 2⁻²² of the largest mean, (1020 / 8)²), so
    /// its response is below `floor` too. The eigenvalue's square root and divisions are
    /// then spent only where it may be a candidate (most of a day image is sky or facade).
    pub fn shi_tomasi(&mut self, radius: usize, floor: Option<f32>) {
        let (w, h) = (self.gradients.w, self.gradients.h);
        let k = 2 * radius + 1;
        // Every element is written below: no clearing pass.
        self.response.resize(w * h, 0.0);
        if w == 0 || h == 0 {
            return;
        }
        // Rows v − radius … v + radius + 1 (clamped) are in the ring while row v is summed.
        let slots = k + 1;
        self.ring.resize(slots * 3 * w, 0);
        self.products.resize(3 * w, 0);
        self.sums.clear();
        self.sums.resize(3 * w, 0);
        let count = (k * k) as f32;
        // The integer diagonal sum below which a response is certainly below `floor`.
        let skip_below = match floor {
            Some(f) if f.is_finite() && f > 1.0 => {
                (((f64::from(f) - 0.1) * 64.0 * f64::from(count)).floor()).min(i32::MAX as f64)
                    as i32
            }
            _ => i32::MIN,
        };
        let mut computed = 0; // rows with horizontal sums in the ring
        let mut ensure = |ring: &mut [i32], products: &mut [i32], last: usize| {
            while computed <= last {
                let slot = &mut ring[(computed % slots) * 3 * w..(computed % slots + 1) * 3 * w];
                row_window_sums(&self.gradients, computed, radius, products, slot);
                computed += 1;
            }
        };
        ensure(&mut self.ring, &mut self.products, radius.min(h - 1));
        let slot = |row: usize| (row % slots) * 3 * w..(row % slots + 1) * 3 * w;
        for d in 0..k {
            let row = d.saturating_sub(radius).min(h - 1);
            for (s, x) in self.sums.iter_mut().zip(&self.ring[slot(row)]) {
                *s += x;
            }
        }
        for v in 0..h {
            let (xx, rest) = self.sums.split_at(w);
            let (yy, xy) = rest.split_at(w);
            let out = &mut self.response[v * w..(v + 1) * w];
            eigen_row(out, xx, yy, xy, count, skip_below);
            if v + 1 < h {
                // Slide the window down a row: exact in integers, so no drift.
                let (enter, leave) = ((v + radius + 1).min(h - 1), v.saturating_sub(radius));
                ensure(&mut self.ring, &mut self.products, enter);
                let (add, sub) = (&self.ring[slot(enter)], &self.ring[slot(leave)]);
                for (s, (a, b)) in self.sums.iter_mut().zip(add.iter().zip(sub)) {
                    *s += a - b;
                }
            }
        }
    }
}

/// Lanes of [`eigen_row`]'s chunks: a whole chunk of skipped pixels (most of a day image)
/// costs one vectorised comparison, and a chunk with a possible candidate is computed in
/// full without a branch per pixel (so that the compiler vectorises it too).
const EIGEN_CHUNK: usize = 16;

/// The responses of one row from the window sums `xx`, `yy`, `xy` (of `count` pixels):
/// the smaller eigenvalue, or `−∞` where the smaller diagonal sum is below `skip_below`.
fn eigen_row(out: &mut [f32], xx: &[i32], yy: &[i32], xy: &[i32], count: f32, skip_below: i32) {
    let eigen = |sxx: i32, syy: i32, sxy: i32| {
        let a = (sxx as f32 / 64.0) / count;
        let c = (syy as f32 / 64.0) / count;
        let b = (sxy as f32 / 64.0) / count;
        let half = 0.5 * (a + c);
        let r = half - (0.25 * (a - c) * (a - c) + b * b).sqrt();
        if sxx.min(syy) < skip_below {
            f32::NEG_INFINITY
        } else {
            r
        }
    };
    let chunks = out
        .chunks_mut(EIGEN_CHUNK)
        .zip(xx.chunks(EIGEN_CHUNK))
        .zip(yy.chunks(EIGEN_CHUNK).zip(xy.chunks(EIGEN_CHUNK)));
    for ((o, xx), (yy, xy)) in chunks {
        // `fold`, not `any`: no early exit, so one vector comparison per chunk.
        let live = xx
            .iter()
            .zip(yy)
            .fold(false, |live, (a, c)| live | ((*a).min(*c) >= skip_below));
        if !live {
            o.fill(f32::NEG_INFINITY);
            continue;
        }
        for (o, ((a, c), b)) in o.iter_mut().zip(xx.iter().zip(yy).zip(xy)) {
            *o = eigen(*a, *c, *b);
        }
    }
}

/// The horizontal window sums (columns clamped) of the tensor products `kx²`, `ky²`,
/// `kx·ky` of row `v`, into `out` (three runs of `w`); `products` is a row buffer.
fn row_window_sums(g: &Gradients, v: usize, radius: usize, products: &mut [i32], out: &mut [i32]) {
    let w = g.w;
    let kx = &g.kx[v * w..(v + 1) * w];
    let ky = &g.ky[v * w..(v + 1) * w];
    let (pxx, rest) = products.split_at_mut(w);
    let (pyy, pxy) = rest.split_at_mut(w);
    for u in 0..w {
        let (x, y) = (i32::from(kx[u]), i32::from(ky[u]));
        pxx[u] = x * x;
        pyy[u] = y * y;
        pxy[u] = x * y;
    }
    let k = 2 * radius + 1;
    for (p, o) in [&*pxx, &*pyy, &*pxy]
        .into_iter()
        .zip(out.chunks_exact_mut(w))
    {
        if w > 2 * radius {
            let interior = &mut o[radius..w - radius];
            if radius == 2 {
                // The detector's window, as one pass of five shifted loads.
                let taps = p.iter().zip(&p[1..]).zip(&p[2..]).zip(&p[3..]).zip(&p[4..]);
                for (s, ((((a, b), c), d), e)) in interior.iter_mut().zip(taps) {
                    *s = a + b + c + d + e;
                }
            } else {
                interior.fill(0);
                for d in 0..k {
                    for (s, x) in interior.iter_mut().zip(&p[d..]) {
                        *s += x;
                    }
                }
            }
        }
        // Within `radius` of either end (everywhere in a narrow row): clamped columns.
        for u in (0..radius.min(w)).chain(w.saturating_sub(radius).max(radius.min(w))..w) {
            o[u] = (0..k)
                .map(|d| p[(u + d).saturating_sub(radius).min(w - 1)])
                .sum();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The former `f32` Sobel gradients (the reference the integer ones must equal).
    fn sobel_f32(src: &[u8], w: usize, h: usize) -> (Vec<f32>, Vec<f32>) {
        let mut gx = vec![0f32; w * h];
        let mut gy = vec![0f32; w * h];
        for v in 1..h - 1 {
            for u in 1..w - 1 {
                let p = |du: isize, dv: isize| {
                    src[((v as isize + dv) as usize) * w + (u as isize + du) as usize] as f32
                };
                let i = v * w + u;
                gx[i] = ((p(1, -1) + 2.0 * p(1, 0) + p(1, 1))
                    - (p(-1, -1) + 2.0 * p(-1, 0) + p(-1, 1)))
                    / 8.0;
                gy[i] = ((p(-1, 1) + 2.0 * p(0, 1) + p(1, 1))
                    - (p(-1, -1) + 2.0 * p(0, -1) + p(1, -1)))
                    / 8.0;
            }
        }
        (gx, gy)
    }

    /// The former `f32` response: per-pixel products, a clamped box sum by rows then
    /// columns, the eigenvalue.
    fn shi_tomasi_f32(gx: &[f32], gy: &[f32], w: usize, h: usize, radius: usize) -> Vec<f32> {
        let box_sum = |src: &[f32]| {
            let r = radius as isize;
            let mut tmp = vec![0f32; w * h];
            for v in 0..h {
                for u in 0..w {
                    let mut s = 0.0;
                    for d in -r..=r {
                        s += src[v * w + (u as isize + d).clamp(0, w as isize - 1) as usize];
                    }
                    tmp[v * w + u] = s;
                }
            }
            let mut out = vec![0f32; w * h];
            for v in 0..h {
                for d in -r..=r {
                    let vv = (v as isize + d).clamp(0, h as isize - 1) as usize;
                    for u in 0..w {
                        out[v * w + u] += tmp[vv * w + u];
                    }
                }
            }
            out
        };
        let xx = box_sum(&gx.iter().map(|x| x * x).collect::<Vec<_>>());
        let yy = box_sum(&gy.iter().map(|y| y * y).collect::<Vec<_>>());
        let xy = box_sum(&gx.iter().zip(gy).map(|(x, y)| x * y).collect::<Vec<_>>());
        let count = ((2 * radius + 1) * (2 * radius + 1)) as f32;
        (0..w * h)
            .map(|i| {
                let (a, c, b) = (xx[i] / count, yy[i] / count, xy[i] / count);
                let half = 0.5 * (a + c);
                half - (0.25 * (a - c) * (a - c) + b * b).sqrt()
            })
            .collect()
    }

    /// A pseudo-random image (a fixed LCG): noise of amplitude `amplitude` DN on a ramp,
    /// with a bright block (edges and corners).
    fn noisy(w: usize, h: usize, amplitude: u32, seed: u64) -> Vec<u8> {
        let mut state = seed;
        (0..w * h)
            .map(|i| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = ((state >> 33) as u32) % (amplitude + 1);
                let (u, v) = (i % w, i / w);
                let block = if (w / 4..w / 2).contains(&u) && (h / 3..h / 2).contains(&v) {
                    90
                } else {
                    0
                };
                (40 + u as u32 / 4 + block + noise).min(255) as u8
            })
            .collect()
    }

    /// The integer gradients equal the former `f32` ones, and the integer response equals
    /// the former one bit for bit, on noisy images of several sizes and window radii
    /// (including rows and columns narrower than the window).
    #[test]
    fn integer_response_equals_the_f32_reference() {
        let mut scratch = Scratch::default();
        let mut skipped = 0;
        for (k, &(w, h, amplitude, radius)) in [
            (64, 48, 40, 2),
            (97, 33, 255, 2),
            (40, 41, 10, 1),
            (7, 5, 200, 2),
            (3, 9, 255, 3),
            (130, 70, 60, 4),
        ]
        .iter()
        .enumerate()
        {
            let src = noisy(w, h, amplitude, k as u64 + 1);
            scratch.gradients.compute(&src, w, h);
            let (gx, gy) = sobel_f32(&src, w, h);
            for j in 0..w * h {
                let (x, y) = scratch.gradients.at(j);
                assert_eq!(
                    (x, y),
                    (f64::from(gx[j]), f64::from(gy[j])),
                    "case {k}, {j}"
                );
            }
            scratch.shi_tomasi(radius, None);
            let reference = shi_tomasi_f32(&gx, &gy, w, h, radius);
            for (j, (a, b)) in scratch.response.iter().zip(&reference).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "case {k}, pixel {j}: {a} vs {b}");
            }
            // With a floor: the same bits where the response reaches it, below it elsewhere
            // (the floor must skip pixels somewhere, or this tests nothing).
            for floor in [2.0f32, 20.0, 150.0] {
                scratch.shi_tomasi(radius, Some(floor));
                for (j, (a, b)) in scratch.response.iter().zip(&reference).enumerate() {
                    if *b >= floor {
                        assert_eq!(a.to_bits(), b.to_bits(), "case {k}, floor {floor}, {j}");
                    } else {
                        assert!(*a < floor, "case {k}, floor {floor}, pixel {j}: {a}");
                    }
                }
                skipped += scratch
                    .response
                    .iter()
                    .filter(|r| **r == f32::NEG_INFINITY)
                    .count();
            }
        }
        assert!(skipped > 1000, "only {skipped} pixels skipped");
    }

    /// Known answers: a vertical step of 80 DN has the Sobel sum 4·80 on its two sides and
    /// none elsewhere; the response of a straight edge is 0 (one eigenvalue), of a flat
    /// image 0, and of a corner positive.
    #[test]
    fn known_gradients_and_responses() {
        let (w, h) = (12, 10);
        let step: Vec<u8> = (0..w * h)
            .map(|i| if i % w >= 6 { 100 } else { 20 })
            .collect();
        let mut scratch = Scratch::default();
        scratch.gradients.compute(&step, w, h);
        for v in 1..h - 1 {
            for u in 1..w - 1 {
                let expected = if u == 5 || u == 6 { 320 } else { 0 };
                assert_eq!(scratch.gradients.kx[v * w + u], expected, "({u}, {v})");
                assert_eq!(scratch.gradients.ky[v * w + u], 0);
            }
        }
        scratch.shi_tomasi(2, None);
        // Zero up to the rounding of `half − √(half²)`.
        assert!(scratch.response.iter().all(|&r| r.abs() < 1e-3));

        let corner: Vec<u8> = (0..w * h)
            .map(|i| if i % w >= 6 && i / w >= 5 { 100 } else { 20 })
            .collect();
        scratch.gradients.compute(&corner, w, h);
        scratch.shi_tomasi(2, None);
        assert!(scratch.response[5 * w + 6] > 50.0);

        // Bad sizes: no panic, zero gradients.
        scratch.gradients.compute(&corner, w, h + 5);
        assert!(scratch.gradients.kx.iter().all(|&k| k == 0));
        scratch.gradients.compute(&[], 0, 0);
        scratch.shi_tomasi(2, None);
        assert!(scratch.response.is_empty());
    }
}
