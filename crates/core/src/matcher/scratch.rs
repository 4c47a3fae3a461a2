//! Small utilities of the search: the key of the per-triple P3P cache (hashed by
//! `rustc_hash::FxBuildHasher`: the standard SipHash cost as much as a third of a P3P solve), the
//! thread-local pool of cell buffers, bit sets and the crate's one shuffle.

use super::pairs::{CellCache, CellData, cached_bytes};
use nalgebra::Vector3;
use std::cell::RefCell;
use std::hash::Hasher;

/// A landmark index triple, the key of the per-detection-triple P3P cache.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) struct TripleKey(pub(super) [usize; 3]);

impl std::hash::Hash for TripleKey {
    fn hash<H: Hasher>(&self, state: &mut H) {
        // One word per key: collisions cost a comparison, never a wrong answer.
        let [i, j, k] = self.0.map(|x| x as u64);
        state.write_u64(i ^ j.rotate_left(21) ^ k.rotate_left(42));
    }
}

/// At most this many cells' buffers are kept per thread for the next frame (a prior frame
/// has about 25 cells; a cold start's thousands are not kept).
pub(super) const MAX_POOLED_CELLS: usize = 64;

/// At most this many bytes of cache buffers are kept in a thread's pool (32 MiB): the cells of
/// a cold start over a long visibility range hold several MB each, and 64 of them would
/// stay allocated between frames.
pub(super) const MAX_POOLED_BYTES: usize = 1 << 25;

thread_local! {
    /// Cells of earlier frames of this thread, whose buffers the next frame reuses: filling
    /// a fresh `m × m` buffer of pair values cost about 0.15 ms of a 1.3 ms prior frame (25
    /// cells of 65 kB, with page faults). An entry of `pairs` is only read once computed
    /// ([`CellData::ensure_pairs`] keeps `pairs_done`), so a reused one needs no filling;
    /// every other buffer is cleared.
    static CELL_POOL: RefCell<Vec<CellData>> = const { RefCell::new(Vec::new()) };
}

/// A cell with empty buffers, from the pool when it has one (see [`CELL_POOL`]).
pub(super) fn take_cell() -> CellData {
    CELL_POOL
        .with_borrow_mut(|pool| pool.pop())
        .unwrap_or_else(|| CellData {
            centre: Vector3::zeros(),
            cands: Vec::new(),
            cache: CellCache::Undecided,
            pairs: Vec::new(),
            rows: Vec::new(),
            used: 0,
            pairs_done: Vec::new(),
            slots_shared: Vec::new(),
            sides: Vec::new(),
            indices: Vec::new(),
            words: 0,
            allowed: Vec::new(),
            slots: Vec::new(),
            store: Vec::new(),
        })
}

/// Gives cells back to the pool (at most [`MAX_POOLED_CELLS`] holding at most
/// [`MAX_POOLED_BYTES`] of cache buffers; the others are freed); `try_with`, since a thread
/// that ends drops its pool.
pub(super) fn recycle_cells(cells: &mut Vec<CellData>) {
    let _ = CELL_POOL.try_with(|pool| {
        if let Ok(mut pool) = pool.try_borrow_mut() {
            let mut held: usize = pool.iter().map(cached_bytes).sum();
            for cell in cells.drain(..) {
                if pool.len() >= MAX_POOLED_CELLS {
                    break;
                }
                let bytes = cached_bytes(&cell);
                if held + bytes <= MAX_POOLED_BYTES {
                    held += bytes;
                    pool.push(cell);
                }
            }
        }
    });
}

/// The cells of a frame; their buffers go back to the pool when the frame is done.
pub(super) struct Cells(pub(super) Vec<CellData>);

impl Drop for Cells {
    fn drop(&mut self) {
        recycle_cells(&mut self.0);
    }
}

impl std::ops::Deref for Cells {
    type Target = Vec<CellData>;
    fn deref(&self) -> &Vec<CellData> {
        &self.0
    }
}

impl std::ops::DerefMut for Cells {
    fn deref_mut(&mut self) -> &mut Vec<CellData> {
        &mut self.0
    }
}

pub(super) fn bit_set(bits: &mut [u64], k: usize) {
    bits[k / 64] |= 1 << (k % 64);
}

/// Calls `f` with the index of every set bit, in increasing order.
pub(super) fn for_each_bit(bits: &[u64], mut f: impl FnMut(usize)) {
    for (w, &word) in bits.iter().enumerate() {
        let mut rest = word;
        while rest != 0 {
            f(w * 64 + rest.trailing_zeros() as usize);
            rest &= rest - 1;
        }
    }
}

/// Fisher–Yates shuffle, from the last element down (the order the matcher's triples and the
/// test kit's scenarios were generated with; `rand`'s `SliceRandom::shuffle` draws another
/// permutation from the same generator, which would change the documented frames).
pub(crate) fn shuffle<R: rand::Rng + ?Sized, T>(rng: &mut R, items: &mut [T]) {
    use rand::RngExt;
    for i in (1..items.len()).rev() {
        let j = rng.random_range(0..=i);
        items.swap(i, j);
    }
}
