//! Small utilities of the search: the map of the per-triple P3P cache ([`SolvedTriples`]), the
//! thread-local pool of cell buffers, bit sets and the crate's one shuffle.

use super::pairs::{CellCache, CellData, cached_bytes};
use nalgebra::Vector3;
use std::cell::RefCell;

/// The map of a detection triple's solved landmark triples: each landmark triple (database
/// indices) to its index in the list of triples to solve. Open addressing with linear
/// probing in a table at most half full, keyed by one multiply per key (the standard
/// SipHash cost as much as a third of a P3P solve, and `std`'s map with `FxHash` about 60
/// instructions per lookup); the entries taken are listed, so that clearing it between
/// detection triples touches only them. Collisions cost a comparison, never a wrong answer.
pub(super) struct SolvedTriples {
    /// `(key, index)`; [`FREE_ENTRY`] as the index: a free entry. A power of two long.
    entries: Vec<([usize; 3], usize)>,
    /// The positions of the entries taken, in insertion order.
    taken: Vec<usize>,
}

/// The index of a free entry of [`SolvedTriples`].
const FREE_ENTRY: usize = usize::MAX;

/// The position of a key in a table of `mask + 1` entries, before probing: the product of
/// the key's one word with `rustc_hash`'s constant, its high bits rotated down (the low bits
/// of a product depend only on the low bits of the factor, which hold only the first
/// landmark index).
fn triple_hash(key: &[usize; 3], mask: usize) -> usize {
    let [i, j, k] = key.map(|x| x as u64);
    let word = i ^ j.rotate_left(21) ^ k.rotate_left(42);
    (word.wrapping_mul(0xf135_7aea_2e62_a9c5).rotate_left(26) as usize) & mask
}

impl SolvedTriples {
    /// An empty map with room for `capacity` keys before it grows.
    pub(super) fn with_capacity(capacity: usize) -> Self {
        let size = capacity.saturating_mul(2).next_power_of_two().max(16);
        Self {
            entries: vec![([0; 3], FREE_ENTRY); size],
            taken: Vec::with_capacity(capacity),
        }
    }

    /// Removes every key (the capacity is kept).
    pub(super) fn clear(&mut self) {
        for &p in &self.taken {
            self.entries[p].1 = FREE_ENTRY;
        }
        self.taken.clear();
    }

    /// The keys held.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.taken.len()
    }

    /// The bytes the map holds (its capacities).
    pub(super) fn held_bytes(&self) -> usize {
        self.entries.capacity() * std::mem::size_of::<([usize; 3], usize)>()
            + self.taken.capacity() * std::mem::size_of::<usize>()
    }

    /// `Ok(index)` of `key`, or `Err(position)`: where [`SolvedTriples::insert`] puts it.
    pub(super) fn find(&self, key: &[usize; 3]) -> Result<usize, usize> {
        let mask = self.entries.len() - 1;
        let mut p = triple_hash(key, mask);
        // The table is at most half full: a free entry ends every probe.
        loop {
            let (k, index) = &self.entries[p];
            if *index == FREE_ENTRY {
                return Err(p);
            }
            if k == key {
                return Ok(*index);
            }
            p = (p + 1) & mask;
        }
    }

    /// Inserts a `key` that [`SolvedTriples::find`] did not find (at the `position` it
    /// gave, unless the table grows first) with its `index`.
    #[inline]
    pub(super) fn insert(&mut self, position: usize, key: [usize; 3], index: usize) {
        if (self.taken.len() + 1) * 2 > self.entries.len() {
            self.grow();
            if let Err(p) = self.find(&key) {
                self.put(p, key, index);
            }
        } else {
            self.put(position, key, index);
        }
    }

    fn put(&mut self, position: usize, key: [usize; 3], index: usize) {
        self.entries[position] = (key, index);
        self.taken.push(position);
    }

    /// Doubles the table, the keys re-inserted in insertion order.
    #[cold]
    fn grow(&mut self) {
        let old = std::mem::take(&mut self.entries);
        let taken = std::mem::take(&mut self.taken);
        self.entries = vec![([0; 3], FREE_ENTRY); old.len() * 2];
        self.taken = Vec::with_capacity(taken.capacity() * 2);
        for p in taken {
            let (key, index) = old[p];
            if let Err(q) = self.find(&key) {
                self.put(q, key, index);
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use std::collections::HashMap;

    /// [`SolvedTriples`] gives what a `HashMap` gives, through its growth from the smallest
    /// table and after clearing, on keys with many repeats and shared first indices.
    #[test]
    fn solved_triples_find_what_a_hash_map_finds() {
        let mut r = vgps_geometry::synthetic::rng(5);
        let mut map = SolvedTriples::with_capacity(0);
        for round in 0..4 {
            let mut reference: HashMap<[usize; 3], usize> = HashMap::new();
            let span = [40, 400, 4_000, 40][round];
            for _ in 0..20_000 {
                let key = [
                    r.random_range(0..span),
                    r.random_range(0..span),
                    r.random_range(0..span) + (usize::MAX >> 1) * (round % 2),
                ];
                match map.find(&key) {
                    Ok(index) => assert_eq!(reference.get(&key), Some(&index)),
                    Err(position) => {
                        assert_eq!(reference.get(&key), None);
                        let index = reference.len();
                        reference.insert(key, index);
                        map.insert(position, key, index);
                    }
                }
                assert_eq!(map.len(), reference.len());
            }
            for (key, index) in &reference {
                assert_eq!(map.find(key), Ok(*index));
            }
            map.clear();
            assert_eq!(map.len(), 0);
            for key in reference.keys() {
                assert!(map.find(key).is_err());
            }
        }
    }
}
