//! Uniform grid of cell size H over Morton (Z-order) keys: the cell of every
//! particle, the ranges of particles per cell in Morton order, and a hash
//! table from a cell key to its range.

/// Cell coordinates are `floor(x / H) + ORIGIN`, so that negative positions
/// map to positive cells; 21 bits per axis (+-2^20 cells of size H).
const ORIGIN: i64 = 1 << 20;
const MAX_COORD: i64 = (1 << 21) - 1;

/// Spreads the low 21 bits of `v` to every third bit.
#[inline(always)]
fn part1by2(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Gathers every third bit of `v` into the low 21 bits (inverse of part1by2).
#[inline(always)]
fn compact1by2(v: u64) -> u64 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x | (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x >> 8)) & 0x001f_0000_ff00_00ff;
    x = (x | (x >> 16)) & 0x001f_0000_0000_ffff;
    x = (x | (x >> 32)) & 0x1f_ffff;
    x
}

/// Cell coordinates of a Morton key.
#[inline(always)]
pub fn unmorton(k: u64) -> [u32; 3] {
    [compact1by2(k) as u32, compact1by2(k >> 1) as u32, compact1by2(k >> 2) as u32]
}

/// Morton key of integer cell coordinates (each < 2^21).
#[inline(always)]
pub fn morton(c: [u32; 3]) -> u64 {
    part1by2(c[0] as u64) | (part1by2(c[1] as u64) << 1) | (part1by2(c[2] as u64) << 2)
}

/// Integer cell coordinates of a position, for cells of size `1 / inv_cell`.
/// Coordinates are clamped to the key range; clamping never separates two
/// particles closer than a cell, so neighbour search stays exact.
#[inline(always)]
pub fn cell_of(x: f32, y: f32, z: f32, inv_cell: f32) -> [u32; 3] {
    let c = |v: f32| -> u32 {
        let f = (v * inv_cell).floor();
        // NaN maps to the origin cell; the step's NaN check reports it.
        let i = if f.is_finite() { f as i64 } else { 0 };
        (i + ORIGIN).clamp(0, MAX_COORD) as u32
    };
    [c(x), c(y), c(z)]
}

/// Cells of a set of particles that is sorted by Morton key.
#[derive(Clone, Debug, Default)]
pub struct CellGrid {
    /// 1 / cell size, 1/m.
    pub inv_cell: f32,
    /// Occupied cells' keys, ascending.
    pub cells: Vec<u64>,
    /// `starts[c]..starts[c + 1]` are the particles of cell `c`.
    pub starts: Vec<u32>,
    /// The most particles in one cell.
    pub fullest: u32,
    /// Open-addressing table: cell index + 1, 0 = empty.
    table: Vec<u32>,
    shift: u32,
}

#[inline(always)]
fn hash(key: u64, shift: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> shift) as usize
}

impl CellGrid {
    /// Rebuilds the grid from the particles' keys, which must be ascending.
    /// Reuses its buffers, so a grid of stable size allocates nothing.
    pub fn build(&mut self, sorted_keys: &[u64], cell_size: f32) {
        self.inv_cell = 1.0 / cell_size;
        self.cells.clear();
        self.starts.clear();
        for (i, &k) in sorted_keys.iter().enumerate() {
            if self.cells.last() != Some(&k) {
                debug_assert!(self.cells.last().is_none_or(|&l| l < k), "keys not sorted");
                self.cells.push(k);
                self.starts.push(i as u32);
            }
        }
        self.starts.push(sorted_keys.len() as u32);
        self.fullest = self.starts.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
        let want = (self.cells.len() * 2).next_power_of_two().max(16);
        self.table.clear();
        self.table.resize(want, 0);
        self.shift = 64 - want.trailing_zeros();
        let mask = want - 1;
        for (c, &k) in self.cells.iter().enumerate() {
            let mut s = hash(k, self.shift);
            while self.table[s] != 0 {
                s = (s + 1) & mask;
            }
            self.table[s] = c as u32 + 1;
        }
    }

    /// The index of the cell with key `key`, if occupied.
    #[inline(always)]
    pub fn find(&self, key: u64) -> Option<usize> {
        if self.cells.is_empty() {
            return None;
        }
        let mask = self.table.len() - 1;
        let mut s = hash(key, self.shift);
        loop {
            let e = self.table[s];
            if e == 0 {
                return None;
            }
            if self.cells[(e - 1) as usize] == key {
                return Some((e - 1) as usize);
            }
            s = (s + 1) & mask;
        }
    }

    /// The particle range of the cell with key `key` (empty if unoccupied).
    #[inline(always)]
    pub fn range(&self, key: u64) -> (u32, u32) {
        match self.find(key) {
            Some(c) => (self.starts[c], self.starts[c + 1]),
            None => (0, 0),
        }
    }

    /// The ranges of the 27 cells around (and including) cell `c`, in a
    /// fixed order; empty cells are skipped. Returns how many were written.
    #[inline]
    pub fn neighbor_ranges(&self, c: [u32; 3], out: &mut [(u32, u32); 27]) -> usize {
        // Dilated (bit-spread) coordinates of c-1, c, c+1 per axis; a
        // neighbour's key is the OR of one from each axis.
        let dil = |v: u32, shift: u32| -> [Option<u64>; 3] {
            let d = |w: i64| (0..=MAX_COORD).contains(&w).then(|| part1by2(w as u64) << shift);
            [d(v as i64 - 1), d(v as i64), d(v as i64 + 1)]
        };
        let (xs, ys, zs) = (dil(c[0], 0), dil(c[1], 1), dil(c[2], 2));
        let mut n = 0;
        for z in zs.iter().flatten() {
            for y in ys.iter().flatten() {
                for x in xs.iter().flatten() {
                    let r = self.range(x | y | z);
                    if r.1 > r.0 {
                        out[n] = r;
                        n += 1;
                    }
                }
            }
        }
        n
    }

    /// The keys of every cell within one cell of an occupied cell
    /// (occupied cells included), ascending, without duplicates: build a
    /// [`CellGrid`] from them to test "is anything of this grid within
    /// reach of that cell" with one lookup.
    pub fn dilated_keys(&self) -> Vec<u64> {
        let mut keys = Vec::new();
        self.dilated_keys_into(&mut keys);
        keys
    }

    /// [`CellGrid::dilated_keys`] into `keys` (cleared first), which keeps
    /// its capacity: at most 27 keys a cell, reserved up front, so a set of
    /// particles that does not spread over more cells allocates nothing.
    pub fn dilated_keys_into(&self, keys: &mut Vec<u64>) {
        keys.clear();
        keys.reserve(self.cells.len() * 27);
        for &k in &self.cells {
            let c = unmorton(k);
            for dz in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let q = [c[0] as i64 + dx, c[1] as i64 + dy, c[2] as i64 + dz];
                        if q.iter().all(|v| (0..=MAX_COORD).contains(v)) {
                            keys.push(morton([q[0] as u32, q[1] as u32, q[2] as u32]));
                        }
                    }
                }
            }
        }
        keys.sort_unstable();
        keys.dedup();
    }

    /// Number of occupied cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no cell is occupied.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_bits() {
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([3, 3, 3]), 63);
        let m = (1u32 << 21) - 1;
        assert_eq!(morton([m, m, m]), (1u64 << 63) - 1);
        for c in [[0, 0, 0], [5, 77, 1234], [m, 0, m - 3], [1 << 20, 3, 99]] {
            assert_eq!(unmorton(morton(c)), c);
        }
    }

    #[test]
    fn negative_positions_get_distinct_cells() {
        let a = cell_of(-0.01, 0.0, 0.0, 10.0);
        let b = cell_of(0.01, 0.0, 0.0, 10.0);
        assert_eq!(a[0] + 1, b[0]);
    }

    #[test]
    fn grid_finds_every_cell() {
        let mut keys: Vec<u64> = (0..1000u64).map(|i| (i * 7919) % 5003).collect();
        keys.sort_unstable();
        let mut g = CellGrid::default();
        g.build(&keys, 1.0);
        for (i, &k) in keys.iter().enumerate() {
            let (s, e) = g.range(k);
            assert!((s as usize) <= i && i < e as usize);
        }
        assert_eq!(g.range(5004), (0, 0));
    }
}
