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
    /// [`Scratch::shi_tomasi_bounded`]: horizontal window sums of the bound's terms of
    /// `kx` and `ky` for the last 2·radius + 2 rows.
    bound_ring: Vec<i16>,
    /// The bound's terms of one row, padded by the radius on both sides.
    bound_terms: Vec<i16>,
    /// The bound's vertical window sums of one row (`kx`, then `ky`).
    bound_sums: Vec<i16>,
    /// The brightest pixel of each [`BRIGHT_BLOCK`]² block of the last image, row-major
    /// ([`Scratch::block_maxima`]).
    bright: Vec<u8>,
    /// Blocks per row of [`Scratch::bright`].
    bright_w: usize,
    /// Column maxima of a block row (buffer).
    column_max: Vec<u8>,
}

/// Side of the blocks of [`Scratch::block_maxima`] (pixels).
pub(crate) const BRIGHT_BLOCK: usize = 8;

impl Scratch {
    /// Fills the block maxima of the `w` × `h` 8-bit image `src` (row-major; shorter than
    /// `w · h`: no block), for [`Scratch::brightest_near`].
    pub fn block_maxima(&mut self, src: &[u8], w: usize, h: usize) {
        let b = BRIGHT_BLOCK;
        let (bw, bh) = (w.div_ceil(b), h.div_ceil(b));
        self.bright.clear();
        self.bright_w = bw;
        if src.len() < w * h {
            self.bright_w = 0;
            return;
        }
        self.column_max.resize(w, 0);
        for by in 0..bh {
            let m = &mut self.column_max;
            m.fill(0);
            for row in src[by * b * w..((by + 1) * b).min(h) * w].chunks_exact(w) {
                for (m, p) in m.iter_mut().zip(row) {
                    *m = (*m).max(*p);
                }
            }
            self.bright
                .extend(m.chunks(b).map(|c| c.iter().copied().fold(0, u8::max)));
        }
    }

    /// The brightest pixel of the last [`Scratch::block_maxima`] image within `radius` of
    /// `(u, v)` (a square; the blocks that meet it, so possibly brighter than the square's
    /// own maximum, never darker), or `u8::MAX` when there are no block maxima.
    pub fn brightest_near(&self, u: usize, v: usize, radius: usize) -> u8 {
        let b = BRIGHT_BLOCK;
        let bw = self.bright_w;
        if bw == 0 || self.bright.len() < bw {
            return u8::MAX;
        }
        let bh = self.bright.len() / bw;
        let (x0, x1) = (u.saturating_sub(radius) / b, ((u + radius) / b).min(bw - 1));
        let (y0, y1) = (v.saturating_sub(radius) / b, ((v + radius) / b).min(bh - 1));
        let mut most = 0;
        for y in y0..=y1 {
            for x in x0..=x1 {
                most = most.max(self.bright[y * bw + x]);
            }
        }
        most
    }
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
        // The bounded path needs the detector's window, a floor that skips something, and
        // rows and columns at least as long as the window.
        let bound = match skip_below(floor, 2 * radius + 1) / 64 - 25 {
            b if radius == BOUNDED_RADIUS && w > 2 * radius && h > 2 * radius && b > 0 => {
                b.min(i32::from(BOUND_TERM_MAX)) as i16
            }
            _ => return self.shi_tomasi_sliding(radius, floor),
        };
        self.shi_tomasi_bounded(floor, bound);
    }

    /// [`Scratch::shi_tomasi`] by sliding exact window sums over every pixel (any radius).
    fn shi_tomasi_sliding(&mut self, radius: usize, floor: Option<f32>) {
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
        let skip_below = skip_below(floor, k);
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

/// The integer diagonal sum (of `k`² squared Sobel sums) below which a response is
/// certainly below `floor` ([`Scratch::shi_tomasi`]); `i32::MIN` without a floor.
fn skip_below(floor: Option<f32>, k: usize) -> i32 {
    let count = (k * k) as f32;
    match floor {
        Some(f) if f.is_finite() && f > 1.0 => {
            (((f64::from(f) - 0.1) * 64.0 * f64::from(count)).floor()).min(i32::MAX as f64) as i32
        }
        _ => i32::MIN,
    }
}

/// The window radius of [`Scratch::shi_tomasi_bounded`] (the detector's 5 × 5).
const BOUNDED_RADIUS: usize = 2;
/// Largest term of the bound's window sums: 25 of them stay below 2¹⁵ (the sums are compared as `i16`, which SSE2 has).
const BOUND_TERM_MAX: i16 = 1310;

/// The bound's term of a Sobel sum `k` (|k| ≤ 1020): `⌊k² / 64⌋`, at most
/// [`BOUND_TERM_MAX`]. As `(32·k)² / 2¹⁶`, a high-half 16-bit multiplication (8 lanes);
/// the clamp to ±1023 keeps `32·k` in `i16` whatever the input.
#[inline]
fn bound_term(k: i16) -> i16 {
    let s = i32::from(k.clamp(-1023, 1023) * 32);
    (((s * s) >> 16) as i16).min(BOUND_TERM_MAX)
}

impl Scratch {
    /// [`Scratch::shi_tomasi`] for the 5 × 5 window with a floor: the exact window sums
    /// and eigenvalues only for the 16-pixel chunks ([`EIGEN_CHUNK`]) in which some pixel
    /// may pass the diagonal test, the rest `−∞` (what the exact test gives there), so the
    /// responses are bit-identical to [`Scratch::shi_tomasi_sliding`]'s.
    ///
    /// The test of a chunk slides 16-bit window sums (8 lanes) of the terms
    /// `t = min(⌊k² / 64⌋, 1310)` of `kx` and of `ky`: a pixel whose exact sum `Σk²` reaches
    /// the integer floor `s` has `Σ⌊k² / 64⌋ > s / 64 − 25` (25 terms, each rounded down by
    /// under 1), and the clamp only lowers a sum that already reaches the clamp's value, so
    /// `Σt ≥ bound = min(⌊s / 64⌋ − 25, 1310)`. Sums of 25 terms ≤ 1310 fit `i16`, so the
    /// sliding window (wrapping additions and subtractions) stays exact. Most of a day
    /// image is sky or facade: a few per cent of the chunks are computed.
    fn shi_tomasi_bounded(&mut self, floor: Option<f32>, bound: i16) {
        let radius = BOUNDED_RADIUS;
        let (w, h) = (self.gradients.w, self.gradients.h);
        let k = 2 * radius + 1;
        self.response.resize(w * h, 0.0);
        let count = (k * k) as f32;
        let skip_below = skip_below(floor, k);
        let slots = k + 1;
        self.bound_ring.resize(slots * 2 * w, 0);
        self.bound_terms.resize(w + 2 * radius, 0);
        self.bound_sums.clear();
        self.bound_sums.resize(2 * w, 0);
        let g = &self.gradients;
        let mut computed = 0; // rows with horizontal sums in the ring
        let mut ensure = |ring: &mut [i16], terms: &mut [i16], last: usize| {
            while computed <= last {
                let slot = &mut ring[(computed % slots) * 2 * w..(computed % slots + 1) * 2 * w];
                let (sx, sy) = slot.split_at_mut(w);
                let row = computed * w..(computed + 1) * w;
                bound_row_sums(&g.kx[row.clone()], terms, sx);
                bound_row_sums(&g.ky[row], terms, sy);
                computed += 1;
            }
        };
        ensure(&mut self.bound_ring, &mut self.bound_terms, radius);
        let slot = |row: usize| (row % slots) * 2 * w..(row % slots + 1) * 2 * w;
        for d in 0..k {
            let row = d.saturating_sub(radius).min(h - 1);
            for (s, x) in self.bound_sums.iter_mut().zip(&self.bound_ring[slot(row)]) {
                *s = s.wrapping_add(*x);
            }
        }
        for v in 0..h {
            let (bx, by) = self.bound_sums.split_at(w);
            let out = &mut self.response[v * w..(v + 1) * w];
            // The row at `−∞` in one pass, then the chunks that may pass (fixed-size
            // chunks: each test is a few vector instructions, no loop).
            out.fill(f32::NEG_INFINITY);
            let (cx, rest_x) = bx.as_chunks::<EIGEN_CHUNK>();
            let (cy, rest_y) = by.as_chunks::<EIGEN_CHUNK>();
            for (i, (cx, cy)) in cx.iter().zip(cy).enumerate() {
                // `fold`, not `any`: no early exit.
                let live = cx
                    .iter()
                    .zip(cy)
                    .fold(false, |live, (a, c)| live | ((*a).min(*c) >= bound));
                if live {
                    let u0 = i * EIGEN_CHUNK;
                    exact_chunk(g, v, u0, &mut out[u0..u0 + EIGEN_CHUNK], count, skip_below);
                }
            }
            let u0 = w - rest_x.len();
            if rest_x
                .iter()
                .zip(rest_y)
                .any(|(a, c)| (*a).min(*c) >= bound)
            {
                exact_chunk(g, v, u0, &mut out[u0..], count, skip_below);
            }
            if v + 1 < h {
                let (enter, leave) = ((v + radius + 1).min(h - 1), v.saturating_sub(radius));
                ensure(&mut self.bound_ring, &mut self.bound_terms, enter);
                let (add, sub) = (&self.bound_ring[slot(enter)], &self.bound_ring[slot(leave)]);
                for (s, (a, b)) in self.bound_sums.iter_mut().zip(add.iter().zip(sub)) {
                    *s = s.wrapping_add(*a).wrapping_sub(*b);
                }
            }
        }
    }
}

/// The horizontal 5-pixel window sums (columns clamped) of the bound's terms of the Sobel
/// sums `k` (one row) into `out`; `terms` is a buffer of `k.len() + 4`.
fn bound_row_sums(k: &[i16], terms: &mut [i16], out: &mut [i16]) {
    let w = k.len();
    let r = BOUNDED_RADIUS;
    for (t, x) in terms[r..r + w].iter_mut().zip(k) {
        *t = bound_term(*x);
    }
    for i in 0..r {
        terms[i] = terms[r];
        terms[r + w + i] = terms[r + w - 1];
    }
    let p = &terms[..w + 2 * r];
    let taps = p.iter().zip(&p[1..]).zip(&p[2..]).zip(&p[3..]).zip(&p[4..]);
    for (s, ((((a, b), c), d), e)) in out.iter_mut().zip(taps) {
        *s = a
            .wrapping_add(*b)
            .wrapping_add(*c)
            .wrapping_add(*d)
            .wrapping_add(*e);
    }
}

/// The responses of the pixels `u0 … u0 + out.len()` of row `v` (at most [`EIGEN_CHUNK`])
/// from their exact 5 × 5 window sums (rows and columns clamped), as [`eigen_row`].
fn exact_chunk(g: &Gradients, v: usize, u0: usize, out: &mut [f32], count: f32, skip_below: i32) {
    const N: usize = EIGEN_CHUNK;
    const R: usize = BOUNDED_RADIUS;
    let (w, h) = (g.w, g.h);
    let n = out.len().min(N);
    let (mut xx, mut yy, mut xy) = ([0i32; N], [0i32; N], [0i32; N]);
    if v >= R && v + R < h && u0 >= R && u0 + n + R <= w {
        // Inside the image: the products of the 5 rows' n + 4 pixels, summed by columns.
        let (mut pxx, mut pyy, mut pxy) = ([0i32; N + 2 * R], [0i32; N + 2 * R], [0i32; N + 2 * R]);
        for row in v - R..=v + R {
            let span = row * w + u0 - R..row * w + u0 + n + R;
            let (kx, ky) = (&g.kx[span.clone()], &g.ky[span]);
            for (((a, b), c), (x, y)) in pxx
                .iter_mut()
                .zip(pyy.iter_mut())
                .zip(pxy.iter_mut())
                .zip(kx.iter().zip(ky))
            {
                let (x, y) = (i32::from(*x), i32::from(*y));
                *a += x * x;
                *b += y * y;
                *c += x * y;
            }
        }
        for d in 0..=2 * R {
            for j in 0..n {
                xx[j] += pxx[j + d];
                yy[j] += pyy[j + d];
                xy[j] += pxy[j + d];
            }
        }
    } else {
        // At the image's edge: clamped rows and columns, as the sliding sums.
        let clamp = |i: usize, d: usize, len: usize| (i + d).saturating_sub(R).min(len - 1);
        for j in 0..n {
            for dv in 0..=2 * R {
                for du in 0..=2 * R {
                    let at = clamp(v, dv, h) * w + clamp(u0 + j, du, w);
                    let (x, y) = (i32::from(g.kx[at]), i32::from(g.ky[at]));
                    xx[j] += x * x;
                    yy[j] += y * y;
                    xy[j] += x * y;
                }
            }
        }
    }
    eigen_row(
        &mut out[..n],
        &xx[..n],
        &yy[..n],
        &xy[..n],
        count,
        skip_below,
    );
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

    /// The bounded response equals the sliding one bit for bit (pixels that cannot pass
    /// the floor are `−∞` in both), on noisy images of many sizes (widths not a multiple of
    /// the chunk, images as small as the window) and floors (down to where the bound
    /// skips nothing, up to where its terms are clamped), while the bound both skips and
    /// computes chunks.
    #[test]
    fn bounded_response_equals_the_sliding_response() {
        let (mut bounded, mut sliding) = (Scratch::default(), Scratch::default());
        let (mut skipped, mut computed) = (0, 0);
        for (k, &(w, h, amplitude)) in [
            (64, 48, 40),
            (97, 33, 255),
            (203, 91, 12),
            (5, 5, 255),
            (6, 40, 100),
            (40, 6, 100),
            (17, 17, 30),
            (130, 70, 60),
        ]
        .iter()
        .enumerate()
        {
            let src = noisy(w, h, amplitude, 100 + k as u64);
            bounded.gradients.compute(&src, w, h);
            sliding.gradients.compute(&src, w, h);
            for floor in [1.5f32, 2.0, 20.0, 150.0, 1000.0, 20_000.0] {
                bounded.shi_tomasi(2, Some(floor));
                sliding.shi_tomasi_sliding(2, Some(floor));
                for (j, (a, b)) in bounded.response.iter().zip(&sliding.response).enumerate() {
                    assert_eq!(a.to_bits(), b.to_bits(), "{w}×{h}, floor {floor}, {j}");
                }
                assert_eq!(bounded.response.len(), w * h);
                for row in bounded.response.chunks(w) {
                    for chunk in row.chunks(EIGEN_CHUNK) {
                        if chunk.iter().all(|r| *r == f32::NEG_INFINITY) {
                            skipped += 1;
                        } else {
                            computed += 1;
                        }
                    }
                }
            }
        }
        assert!(
            skipped > 500 && computed > 500,
            "{skipped} skipped, {computed} computed"
        );
        // The bound's term: ⌊k² / 64⌋ clamped, for every Sobel sum.
        for k in -1020i16..=1020 {
            let exact = (i32::from(k) * i32::from(k) / 64).min(i32::from(BOUND_TERM_MAX));
            assert_eq!(i32::from(bound_term(k)), exact, "{k}");
        }
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
