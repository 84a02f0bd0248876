//! Neighbour search on a uniform grid with cell size h (the kernel support).
//!
//! Points are bucketed by a counting sort on their cell key; the caller reorders its particle
//! arrays by the returned permutation, so after [`Grid::build`] the points of one cell are
//! contiguous and neighbouring particles sit close together in memory. Neighbour lists are
//! indexed CSR-style (`offsets[i]..offsets[i+1]` is point i's range) and built in parallel
//! chunks, each into its own buffer, which is where they stay; the buffers are kept between
//! steps so that a step allocates nothing once the sizes have settled.
//!
//! The grid spans the bounding box of the points it was built from, so points anywhere are
//! found. When that box would need far more cells than there are points (a particle flung
//! very far away) the keys fall back to a hash of the cell coordinates, which keeps memory
//! proportional to the point count and results exact (every candidate is distance-checked).

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;
use crate::simd::SimdPath;
use glam::Vec2;

/// Particles per parallel work item when building neighbour lists.
const CHUNK: usize = 512;

/// Neighbour lists. Point `i`'s neighbours are [`Self::of`]`(i)`; [`Self::range`]`(i)`,
/// `offsets[i]..offsets[i + 1]`, is where they sit in the concatenation of all lists, which is
/// the layout of any per-pair array kept beside them.
///
/// The lists of each `CHUNK` consecutive points stay in the buffer their chunk's parallel
/// build wrote them to. Copying the buffers into one array took 2 % of a 100k-particle step
/// and 4 bytes per pair.
#[derive(Default, Clone, Debug)]
pub struct NeighborLists {
    pub offsets: Vec<u32>,
    /// One buffer per chunk of points (those past the last chunk in use are left over from
    /// larger builds).
    chunks: Vec<Vec<u32>>,
    /// Every list is in increasing order (see [`Self::ascending`]).
    ascending: bool,
}

impl NeighborLists {
    /// The neighbours of point `i`.
    #[inline(always)]
    pub fn of(&self, i: usize) -> &[u32] {
        let chunk = i / CHUNK;
        let first = self.offsets[chunk * CHUNK];
        let start = (self.offsets[i] - first) as usize;
        let end = (self.offsets[i + 1] - first) as usize;
        &self.chunks[chunk][start..end]
    }

    /// Append a list for the next point (for lists made by hand, as tests do; the grid
    /// writes its lists itself).
    pub fn push(&mut self, list: &[u32]) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
            self.ascending = true;
        }
        self.ascending &= list.is_sorted();
        let i = self.len();
        let chunk = i / CHUNK;
        if i.is_multiple_of(CHUNK) {
            self.chunks.truncate(chunk);
            self.chunks.push(Vec::new());
        }
        self.chunks[chunk].extend_from_slice(list);
        let end = self.offsets[i] + list.len() as u32;
        self.offsets.push(end);
    }

    /// The range of point `i`'s neighbours in the concatenation of all lists (and in any
    /// per-pair array).
    #[inline]
    pub fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }

    /// Number of points the lists were built for.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// True when built for no points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Total number of (ordered) pairs.
    pub fn pair_count(&self) -> usize {
        self.offsets.last().copied().unwrap_or(0) as usize
    }

    /// Whether every list is in increasing order, so that its first and last entries are its
    /// smallest and largest. A dense grid's lists are: it visits the rows of cells in key
    /// order, each as one range of sorted points. A hashed grid's need not be.
    pub fn ascending(&self) -> bool {
        self.ascending
    }
}

/// A uniform grid over a set of points sorted by cell.
#[derive(Default, Clone, Debug)]
pub struct Grid {
    /// Support radius: neighbours are the points closer than this.
    radius: f32,
    /// 1 / cell edge; the edge is a hair larger than `radius` so rounding never puts a
    /// neighbour two cells away.
    inv_cell: f32,
    origin: Vec2,
    dims: [i64; 2],
    /// Number of keys; dense grids use `dims[0] * dims[1]`, hashed ones a power of two.
    key_count: usize,
    hashed: bool,
    /// `cell_start[k]..cell_start[k + 1]` are the sorted points with key `k`.
    cell_start: Vec<u32>,
    /// Scratch: each point's key.
    keys: Vec<u32>,
    /// The permutation of the last build: sorted position `s` holds original point
    /// `order[s]`.
    order: Vec<u32>,
    /// Sorted positions, so queries do not depend on the caller's arrays.
    sorted: Vec<Vec2>,
    /// The key of each sorted point, so that lists of the grid's own points need not find
    /// their cells again.
    sorted_keys: Vec<u32>,
    /// Scratch: the fill position of each key during the counting sort.
    cursor: Vec<u32>,
    /// A dense grid is used up to this many cells even for few points (see
    /// [`Grid::set_dense_cells_floor`]).
    dense_cells_floor: usize,
    /// Set by [`Grid::set_simd_path`]: the path to take instead of [`SimdPath::in_use`].
    forced_path: Option<SimdPath>,
}

impl Grid {
    /// An empty grid for neighbours closer than `radius`.
    pub fn new(radius: f32) -> Self {
        Self {
            radius,
            inv_cell: 1.0 / (radius * (1.0 + 1.0e-4)),
            ..Default::default()
        }
    }

    /// Keep the grid dense (no hashing) up to `cells` cells however few points it holds. A
    /// grid of wall particles spans the whole tank with a few points per cell along its
    /// edges; hashed, every fluid query pays a hash and scans buckets shared with far-away
    /// wall cells. Dense, the empty cells cost one comparison each. The caller sizes this by
    /// the number of queries it will make.
    pub fn set_dense_cells_floor(&mut self, cells: usize) {
        self.dense_cells_floor = cells;
    }

    /// Take `path` instead of [`SimdPath::in_use`]: the AVX-512 candidate filter on
    /// [`SimdPath::Avx512`], the scalar one otherwise. Both give the same lists in the same
    /// order; the switch is for tests and measurements. `path` must be one this CPU runs.
    pub fn set_simd_path(&mut self, path: SimdPath) {
        assert!(path.available(), "this CPU cannot run the {path} path");
        self.forced_path = Some(path);
    }

    /// What the AVX-512 kernels read of this grid, which must be dense.
    #[cfg(target_arch = "x86_64")]
    fn dense_shape(&self) -> avx512::DenseGrid {
        assert!(!self.hashed, "the AVX-512 kernels take dense grids only");
        avx512::DenseGrid {
            origin: self.origin,
            inv_cell: self.inv_cell,
            dims: self.dims,
            key_count: self.key_count,
        }
    }

    /// Whether the AVX-512 cell passes run.
    fn avx512(&self) -> bool {
        self.forced_path.unwrap_or_else(SimdPath::in_use) == SimdPath::Avx512
    }

    /// The support radius this grid answers for.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Bucket `points` by cell. Returns the permutation (`order[s]` = original index of the
    /// point now at sorted position `s`); callers reorder their arrays with it so that the
    /// indices in neighbour lists are sorted positions.
    pub fn build(&mut self, points: &[Vec2]) -> &[u32] {
        let n = points.len();
        let (lo, hi) = bounds(points);
        let extent = hi - lo;
        // `as` saturates a huge extent (a coordinate of 1e308 in a scene file); the addition
        // must not wrap it round to a negative cell count.
        let nx = ((extent.x * self.inv_cell).floor() as i64).saturating_add(1);
        let ny = ((extent.y * self.inv_cell).floor() as i64).saturating_add(1);
        let dense_cells = (nx as f64) * (ny as f64);
        let limit = (4 * n).max(4096).max(self.dense_cells_floor) as f64;
        if n == 0 || dense_cells <= limit {
            self.hashed = false;
            self.origin = lo;
            self.dims = [nx.max(1), ny.max(1)];
            self.key_count = (self.dims[0] * self.dims[1]) as usize;
        } else {
            self.hashed = true;
            // Absolute cells: no large origin offset to lose precision against.
            self.origin = Vec2::ZERO;
            self.dims = [nx, ny];
            self.key_count = (2 * n).next_power_of_two();
        }

        // Counting sort by key.
        let mut keys = std::mem::take(&mut self.keys);
        keys.resize(n, 0);
        let simd_keys = !self.hashed && self.avx512() && self.key_count <= i32::MAX as usize;
        #[cfg(target_arch = "x86_64")]
        let dense = simd_keys.then(|| self.dense_shape());
        #[cfg(not(target_arch = "x86_64"))]
        let _ = simd_keys;
        keys.par_chunks_mut(LIGHT_PASS_MIN_ITEMS)
            .zip(points.par_chunks(LIGHT_PASS_MIN_ITEMS))
            .for_each(|(k, p)| {
                #[cfg(target_arch = "x86_64")]
                let done = dense.map_or(0, |dense| avx512::dense_keys(&dense, p, k));
                #[cfg(not(target_arch = "x86_64"))]
                let done = 0;
                for (k, &p) in k[done..].iter_mut().zip(&p[done..]) {
                    *k = self.point_key(p);
                }
            });
        self.keys = keys;
        self.cell_start.clear();
        self.cell_start.resize(self.key_count + 1, 0);
        for &k in &self.keys {
            self.cell_start[k as usize + 1] += 1;
        }
        for k in 0..self.key_count {
            self.cell_start[k + 1] += self.cell_start[k];
        }
        self.order.resize(n, 0);
        self.cursor.clear();
        self.cursor
            .extend_from_slice(&self.cell_start[..self.key_count]);
        for (i, &k) in self.keys.iter().enumerate() {
            let slot = &mut self.cursor[k as usize];
            self.order[*slot as usize] = i as u32;
            *slot += 1;
        }
        // The sorted copy of the positions and their keys, in one parallel pass.
        let keys = &self.keys;
        self.order
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|&i| (points[i as usize], keys[i as usize]))
            .unzip_into_vecs(&mut self.sorted, &mut self.sorted_keys);
        &self.order
    }

    /// The positions in sorted order.
    pub fn sorted_points(&self) -> &[Vec2] {
        &self.sorted
    }

    /// The permutation of the last build.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    #[inline]
    fn cell_of(&self, p: Vec2) -> [i64; 2] {
        // In f64: far from the origin, an f32 product would misplace points by whole cells.
        // `as` saturates, so points at any distance get a (possibly out-of-grid) cell.
        let inv = self.inv_cell as f64;
        let cx = floor_to_i64((p.x as f64 - self.origin.x as f64) * inv);
        let cy = floor_to_i64((p.y as f64 - self.origin.y as f64) * inv);
        [cx, cy]
    }

    /// Key of a point the grid was built from (always inside the grid).
    #[inline]
    fn point_key(&self, p: Vec2) -> u32 {
        let [cx, cy] = self.cell_of(p);
        let c = if self.hashed {
            [cx, cy]
        } else {
            [cx.clamp(0, self.dims[0] - 1), cy.clamp(0, self.dims[1] - 1)]
        };
        self.key_of_cell(c).unwrap_or(0)
    }

    #[inline]
    fn key_of_cell(&self, c: [i64; 2]) -> Option<u32> {
        if self.hashed {
            // Large primes (Teschner et al. 2003); wrapping keeps far cells well defined.
            let h = (c[0].wrapping_mul(73_856_093)) ^ (c[1].wrapping_mul(19_349_663));
            Some((h as u64 & (self.key_count as u64 - 1)) as u32)
        } else if c[0] < 0 || c[1] < 0 || c[0] >= self.dims[0] || c[1] >= self.dims[1] {
            None
        } else {
            Some((c[1] * self.dims[0] + c[0]) as u32)
        }
    }

    /// Visit every sorted index `j` within the support of `p` (including a point at `p`
    /// itself). `f` gets `j` and the offset `p - x_j`.
    #[inline]
    pub fn for_each_near(&self, p: Vec2, mut f: impl FnMut(u32, Vec2)) {
        if self.sorted.is_empty() {
            return;
        }
        let c = self.cell_of(p);
        let r2 = self.radius * self.radius;
        let mut visit = |start: u32, end: u32| {
            for j in start..end {
                let r = p - self.sorted[j as usize];
                if r.length_squared() < r2 {
                    f(j, r);
                }
            }
        };
        if !self.hashed {
            let mut block = [(0u32, 0u32); 3];
            let len = self.dense_block(c, &mut block);
            for &(start, end) in &block[..len] {
                visit(start, end);
            }
            return;
        }
        let mut seen = [u32::MAX; 9];
        let mut nseen = 0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let Some(key) =
                    self.key_of_cell([c[0].saturating_add(dx), c[1].saturating_add(dy)])
                else {
                    continue;
                };
                // Two of the nine cells may share a hash bucket: scan it once.
                if seen[..nseen].contains(&key) {
                    continue;
                }
                seen[nseen] = key;
                nseen += 1;
                visit(
                    self.cell_start[key as usize],
                    self.cell_start[key as usize + 1],
                );
            }
        }
    }

    /// Whether any of this grid's points lies within the support of `p`.
    pub fn any_near(&self, p: Vec2) -> bool {
        let mut found = false;
        self.for_each_near(p, |_, _| found = true);
        found
    }

    /// The points of the (up to) 3 x 3 cells around cell `c` of a dense grid, as one range
    /// per non-empty row of three cells; returns how many ranges were written.
    #[inline]
    fn dense_block(&self, c: [i64; 2], block: &mut [(u32, u32); 3]) -> usize {
        let mut len = 0;
        let x0 = c[0].saturating_sub(1).max(0);
        let x1 = c[0].saturating_add(1).min(self.dims[0] - 1);
        if x0 > x1 {
            return 0;
        }
        for cy in c[1].saturating_sub(1).max(0)..=c[1].saturating_add(1).min(self.dims[1] - 1) {
            // The cells of one row are consecutive keys, so their points are one range.
            let row = cy * self.dims[0];
            let start = self.cell_start[(row + x0) as usize];
            let end = self.cell_start[(row + x1) as usize + 1];
            if start < end {
                block[len] = (start, end);
                len += 1;
            }
        }
        len
    }

    /// Neighbour lists of `queries` against this grid's points. With `exclude_self`, the
    /// queries are this grid's own sorted points and a point is not its own neighbour.
    pub fn neighbor_lists(&self, queries: &[Vec2], exclude_self: bool, out: &mut NeighborLists) {
        let n = queries.len();
        assert!(
            !exclude_self || n == self.sorted.len(),
            "lists without self are for the grid's own points"
        );
        debug_assert!(!exclude_self || queries == self.sorted);
        let chunks = n.div_ceil(CHUNK);
        out.offsets.resize(n + 1, 0);
        if out.chunks.len() < chunks {
            out.chunks.resize_with(chunks, Vec::new);
        }
        out.offsets[0] = 0;
        out.ascending = !self.hashed;
        let avx512 = self.avx512();
        // Pass 1 (parallel over chunks): each chunk lists its points' neighbours into its own
        // buffer and writes its points' counts.
        out.offsets[1..]
            .par_chunks_mut(CHUNK)
            .zip(out.chunks[..chunks].par_iter_mut())
            .enumerate()
            .for_each(|(c, (counts, buf))| {
                buf.clear();
                let base = c * CHUNK;
                if self.hashed {
                    for (k, count) in counts.iter_mut().enumerate() {
                        let i = base + k;
                        let before = buf.len();
                        self.for_each_near(queries[i], |j, _| {
                            if !(exclude_self && j as usize == i) {
                                buf.push(j);
                            }
                        });
                        *count = (buf.len() - before) as u32;
                    }
                    return;
                }
                // Dense grid: queries arrive sorted by cell, so the ranges of the 3 x 3
                // block are looked up once per run of queries in the same cell. The grid's
                // own points know their cell's key from the sort; other queries find their
                // cells (an f64 floor per coordinate), 16 at a time where AVX-512 is.
                let r2 = self.radius * self.radius;
                // Other queries' cells, 16 at a time on AVX-512.
                let mut cells = [[0i64; 2]; 16];
                let mut block_cell = [i64::MIN; 2];
                let mut block_key = u32::MAX;
                let mut block = [(0u32, 0u32); 3];
                let mut block_len = 0;
                let chunk_end = base + counts.len();
                #[cfg(target_arch = "x86_64")]
                let dense = avx512.then(|| self.dense_shape());
                for (k, count) in counts.iter_mut().enumerate() {
                    let i = base + k;
                    let p = queries[i];
                    if exclude_self {
                        let key = self.sorted_keys[i];
                        if key != block_key {
                            block_key = key;
                            let c = [key as i64 % self.dims[0], key as i64 / self.dims[0]];
                            block_len = self.dense_block(c, &mut block);
                        }
                    } else {
                        #[cfg(target_arch = "x86_64")]
                        let c = if let Some(dense) = &dense {
                            if k % 16 == 0 {
                                let next = &queries[i..(i + 16).min(chunk_end)];
                                avx512::block_cells(dense, next, &mut cells);
                            }
                            cells[k % 16]
                        } else {
                            self.cell_of(p)
                        };
                        #[cfg(not(target_arch = "x86_64"))]
                        let c = self.cell_of(p);
                        if c != block_cell {
                            block_cell = c;
                            block_len = self.dense_block(c, &mut block);
                        }
                    }
                    let before = buf.len();
                    let skip = if exclude_self { i as u32 } else { u32::MAX };
                    for &(start, end) in &block[..block_len] {
                        let candidates = &self.sorted[start as usize..end as usize];
                        push_near(candidates, start, p, r2, skip, avx512, buf);
                    }
                    *count = (buf.len() - before) as u32;
                }
            });
        // Pass 2: the counts become offsets.
        for i in 0..n {
            out.offsets[i + 1] += out.offsets[i];
        }
    }
}

/// Append to `buf` the index `first + k` of every `candidates[k]` closer to `p` than
/// `√r2`, in order, leaving out the index `skip`. This is the inner loop of the list build:
/// about 36 candidates per particle, a third of them neighbours, so a branch on the test is
/// mispredicted often; the AVX-512 path tests 16 candidates at once and compresses the
/// survivors into `buf`, the other paths keep them one at a time, both without a branch. Both compute `|p − x|²` as `dx·dx + dy·dy` with
/// the same roundings, so they give the same lists.
#[inline]
fn push_near(
    candidates: &[Vec2],
    first: u32,
    p: Vec2,
    r2: f32,
    skip: u32,
    avx512: bool,
    buf: &mut Vec<u32>,
) {
    #[cfg(target_arch = "x86_64")]
    if avx512 {
        avx512::push_near(candidates, first, p, r2, skip, buf);
        return;
    }
    let _ = avx512;
    // Without a branch on the test, which a third of the candidates pass in no pattern the
    // predictor can learn: every index is written at the end of what was kept, and the end
    // moves on only past a neighbour.
    let start = buf.len();
    buf.resize(start + candidates.len(), 0);
    let out = &mut buf[start..];
    let mut kept = 0;
    for (k, &x) in candidates.iter().enumerate() {
        let j = first + k as u32;
        out[kept] = j;
        kept += usize::from(((p - x).length_squared() < r2) & (j != skip));
    }
    buf.truncate(start + kept);
}

#[cfg(target_arch = "x86_64")]
mod avx512;

/// `v.floor() as i64` without the libm call that `floor` becomes on baseline x86-64 (no
/// SSE4.1 `roundsd`): truncate, then step down where truncation went up. Saturates like
/// `as` (±∞ and out-of-range values to the i64 limits, NaN to 0), and is exact in between:
/// below 2⁵³ in magnitude the truncated value converts back exactly, and beyond it `v`
/// is an integer already.
#[inline]
fn floor_to_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Bounding box of a point set; (0,0)-(0,0) when empty.
fn bounds(points: &[Vec2]) -> (Vec2, Vec2) {
    if points.is_empty() {
        return (Vec2::ZERO, Vec2::ZERO);
    }
    points
        .par_iter()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .fold(
            || (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
        .reduce(
            || (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        )
}

/// Gather `values` into `scratch` by `order` and swap, so `values[s]` becomes the old
/// `values[order[s]]`.
pub fn permute<T: Copy + Send + Sync>(values: &mut Vec<T>, order: &[u32], scratch: &mut Vec<T>) {
    debug_assert_eq!(values.len(), order.len());
    scratch.clear();
    // In parallel: five arrays of the fluid are reordered every step, and a serial copy
    // leaves the second core idle meanwhile.
    scratch.par_extend(
        order
            .par_iter()
            .with_min_len(LIGHT_PASS_MIN_ITEMS)
            .map(|&i| values[i as usize]),
    );
    std::mem::swap(values, scratch);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute_force(points: &[Vec2], radius: f32, i: usize) -> Vec<u32> {
        let mut v: Vec<u32> = (0..points.len())
            .filter(|&j| j != i && (points[i] - points[j]).length_squared() < radius * radius)
            .map(|j| j as u32)
            .collect();
        v.sort_unstable();
        v
    }

    fn check(points: Vec<Vec2>, radius: f32) {
        let mut grid = Grid::new(radius);
        let order = grid.build(&points).to_vec();
        let sorted: Vec<Vec2> = order.iter().map(|&i| points[i as usize]).collect();
        assert_eq!(grid.sorted_points(), &sorted[..]);
        let mut lists = NeighborLists::default();
        grid.neighbor_lists(&sorted, true, &mut lists);
        assert_eq!(lists.len(), points.len());
        assert_same_on_both_paths(&mut grid, &sorted, true, &lists);
        // A dense grid's lists are in increasing order (the blocks' 16-bit indices rely on
        // it); a hashed grid's are not claimed to be.
        assert_eq!(lists.ascending(), !grid.hashed);
        for i in 0..sorted.len() {
            assert!(grid.hashed || lists.of(i).is_sorted(), "point {i}");
            let mut got = lists.of(i).to_vec();
            got.sort_unstable();
            assert_eq!(
                got,
                brute_force(&sorted, radius, i),
                "point {i} at {:?}",
                sorted[i]
            );
        }
    }

    /// The portable candidate filter gives exactly `lists` (the default path's), in the same
    /// order.
    fn assert_same_on_both_paths(
        grid: &mut Grid,
        queries: &[Vec2],
        exclude_self: bool,
        lists: &NeighborLists,
    ) {
        let mut portable = NeighborLists::default();
        grid.set_simd_path(SimdPath::Portable);
        grid.neighbor_lists(queries, exclude_self, &mut portable);
        grid.forced_path = None;
        assert_eq!(portable.offsets, lists.offsets);
        for i in 0..lists.len() {
            assert_eq!(portable.of(i), lists.of(i), "point {i}");
        }
    }

    /// `grid`'s lists for `queries` (another point set) against brute force; returns the
    /// number of pairs.
    fn check_cross(grid: &mut Grid, queries: &[Vec2], radius: f32) -> usize {
        let mut lists = NeighborLists::default();
        grid.neighbor_lists(queries, false, &mut lists);
        assert_same_on_both_paths(grid, queries, false, &lists);
        let points = grid.sorted_points();
        for (i, &p) in queries.iter().enumerate() {
            let mut got = lists.of(i).to_vec();
            got.sort_unstable();
            let want: Vec<u32> = (0..points.len())
                .filter(|&j| (p - points[j]).length_squared() < radius * radius)
                .map(|j| j as u32)
                .collect();
            assert_eq!(got, want, "query {i} at {p:?}");
        }
        lists.pair_count()
    }

    #[test]
    fn points_on_cell_borders() {
        // A lattice whose spacing is exactly half the radius puts points on every cell edge
        // and pairs at exactly the radius (which are not neighbours: W(h) = 0).
        let r = 0.04f32;
        let mut pts = Vec::new();
        for i in 0..30 {
            for j in 0..20 {
                pts.push(Vec2::new(i as f32 * r * 0.5, j as f32 * r * 0.5));
            }
        }
        check(pts, r);
    }

    /// A dense grid of `points` to compare the AVX-512 cell passes with the scalar ones, on
    /// a CPU with AVX-512F.
    #[cfg(target_arch = "x86_64")]
    fn dense_grid_for_simd(radius: f32, points: &[Vec2]) -> Grid {
        assert!(SimdPath::Avx512.available(), "this CPU has no AVX-512F");
        let mut grid = Grid::new(radius);
        grid.build(points);
        assert!(!grid.hashed);
        grid
    }

    /// The AVX-512 key pass gives each point the scalar key, and so the same sort: on cell
    /// edges (a lattice at half the cell edge, with points a hair either side), past the
    /// grid's edges, at infinities and NaN, and in a tail shorter than 16.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[ignore = "needs an AVX-512F CPU: .ci/run runs the AVX-512 tests where there is one"]
    fn avx512_keys_are_the_scalar_keys() {
        let r = 0.04f32;
        let mut pts = Vec::new();
        for i in 0..40 {
            for j in 0..25 {
                let p = Vec2::new(i as f32 * r * 0.5 + 0.3, j as f32 * r * 0.5 - 0.7);
                pts.extend([p, p + Vec2::splat(1.0e-7), p - Vec2::splat(1.0e-7)]);
            }
        }
        let grid = dense_grid_for_simd(r, &pts);
        let extremes = [
            Vec2::new(f32::NAN, 0.5),
            Vec2::new(0.5, f32::NAN),
            Vec2::new(f32::INFINITY, f32::NEG_INFINITY),
            Vec2::new(-1.0e30, 1.0e30),
            Vec2::new(-5.0, 50.0),
            Vec2::new(-0.0, 0.0),
        ];
        pts.extend(extremes.iter().cycle().take(21));
        // 3,021 points: 188 full vectors and a tail of 13.
        let mut simd = vec![0; pts.len()];
        let done = avx512::dense_keys(&grid.dense_shape(), &pts, &mut simd);
        assert_eq!(done, 3_008);
        for (k, &p) in simd[done..].iter_mut().zip(&pts[done..]) {
            *k = grid.point_key(p);
        }
        let scalar: Vec<u32> = pts.iter().map(|&p| grid.point_key(p)).collect();
        assert_eq!(simd, scalar);
        let cells: std::collections::HashSet<u32> = scalar.iter().copied().collect();
        assert!(cells.len() > 100, "{} cells", cells.len());
    }

    /// The AVX-512 cells of queries give the blocks `cell_of` gives: inside the grid, on its
    /// edges, one and two cells out, far out, at infinities and NaN, and for fewer than 16
    /// points.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[ignore = "needs an AVX-512F CPU: .ci/run runs the AVX-512 tests where there is one"]
    fn avx512_query_cells_give_the_scalar_blocks() {
        let r = 0.04f32;
        let pts: Vec<Vec2> = (0..400)
            .map(|k| Vec2::new((k % 20) as f32 * 0.03, (k / 20) as f32 * 0.03))
            .collect();
        let grid = dense_grid_for_simd(r, &pts);
        let mut queries = Vec::new();
        for i in -6..30 {
            for j in -6..30 {
                let p = Vec2::new(i as f32 * r * 0.5, j as f32 * r * 0.5);
                queries.extend([p, p + Vec2::splat(1.0e-6), p - Vec2::splat(1.0e-6)]);
            }
        }
        queries.extend([
            Vec2::new(f32::NAN, 0.1),
            Vec2::new(0.1, f32::NAN),
            Vec2::new(f32::INFINITY, 0.1),
            Vec2::new(0.1, f32::NEG_INFINITY),
            Vec2::new(-1.0e30, 1.0e30),
            Vec2::new(3.0e9, -3.0e9),
        ]);
        let blocks = |c: [i64; 2]| {
            let mut block = [(0u32, 0u32); 3];
            let len = grid.dense_block(c, &mut block);
            block[..len].to_vec()
        };
        let mut non_empty = 0;
        for group in queries.chunks(13).chain(queries.chunks(16)) {
            let mut cells = [[0i64; 2]; 16];
            avx512::block_cells(&grid.dense_shape(), group, &mut cells);
            for (&p, &c) in group.iter().zip(&cells) {
                let want = blocks(grid.cell_of(p));
                assert_eq!(blocks(c), want, "{p:?}");
                non_empty += !want.is_empty() as usize;
            }
        }
        assert!(non_empty > 1000, "{non_empty} queries with neighbours");
    }

    #[test]
    fn hand_made_lists_are_ascending_until_one_is_not() {
        let mut lists = NeighborLists::default();
        lists.push(&[1, 5, 9]);
        lists.push(&[]);
        lists.push(&[0, 2]);
        assert!(lists.ascending());
        lists.push(&[4, 3]);
        assert!(!lists.ascending());
        lists.push(&[7]);
        assert!(!lists.ascending(), "one unordered list is enough");
    }

    #[test]
    fn far_away_points_use_the_hashed_grid() {
        let mut pts: Vec<Vec2> = (0..200)
            .map(|i| Vec2::new((i % 20) as f32 * 0.01, (i / 20) as f32 * 0.01))
            .collect();
        pts.push(Vec2::new(1.0e6, -3.0e5));
        pts.push(Vec2::new(1.0e6 + 0.01, -3.0e5));
        pts.push(Vec2::new(-5.0e4, 7.0e4));
        let mut grid = Grid::new(0.02);
        grid.build(&pts);
        assert!(grid.hashed, "a huge bounding box should switch to hashing");
        check(pts, 0.02);
    }

    #[test]
    fn extents_beyond_the_cell_range_do_not_panic() {
        // A scene coordinate of 1e308 becomes an infinite f32; f32::MAX apart overflows the
        // cell count. Both once wrapped the count to a negative number.
        for far in [
            Vec2::new(f32::MAX, f32::MAX),
            Vec2::new(-f32::MAX, f32::MAX),
            Vec2::new(f32::INFINITY, 0.0),
        ] {
            let pts = vec![Vec2::ZERO, Vec2::new(0.01, 0.0), far];
            let mut grid = Grid::new(0.02);
            grid.set_dense_cells_floor(1 << 18);
            grid.build(&pts);
            let mut lists = NeighborLists::default();
            grid.neighbor_lists(grid.sorted_points().to_vec().as_slice(), true, &mut lists);
            let near: usize = (0..3)
                .filter(|&i| grid.sorted_points()[i].x.abs() < 1.0)
                .map(|i| lists.of(i).len())
                .sum();
            assert_eq!(
                near, 2,
                "the two close points find each other next to {far:?}"
            );
        }
    }

    #[test]
    fn cross_set_queries_match_brute_force() {
        let fluid: Vec<Vec2> = (0..300)
            .map(|i| Vec2::new((i * 37 % 101) as f32 * 0.013, (i * 53 % 97) as f32 * 0.011))
            .collect();
        let walls: Vec<Vec2> = (0..150)
            .map(|i| Vec2::new(i as f32 * 0.009 - 0.1, 0.5 + (i % 3) as f32 * 0.01))
            .collect();
        let mut grid = Grid::new(0.05);
        grid.build(&walls);
        check_cross(&mut grid, &fluid, 0.05);
    }

    #[test]
    fn a_wall_grid_kept_dense_answers_queries_inside_and_far_outside() {
        // Two wall layers around a 4 m x 3 m tank: few points over a large box, which
        // would be hashed without the floor.
        let r = 0.01f32;
        let mut walls = Vec::new();
        for layer in 0..2 {
            let o = -(layer as f32 + 0.5) * r;
            let mut x = o;
            while x <= 4.0 - o {
                walls.push(Vec2::new(x, o));
                walls.push(Vec2::new(x, 3.0 - o));
                x += r;
            }
            let mut y = o;
            while y <= 3.0 - o {
                walls.push(Vec2::new(o, y));
                walls.push(Vec2::new(4.0 - o, y));
                y += r;
            }
        }
        let radius = 2.0 * r;
        let mut grid = Grid::new(radius);
        grid.build(&walls);
        assert!(grid.hashed, "without the floor this wall grid is hashed");
        grid.set_dense_cells_floor(1 << 18);
        grid.build(&walls);
        assert!(!grid.hashed, "the floor keeps it dense");
        // Queries sorted along x then y (runs in one cell, as the fluid arrives), then
        // points on cell borders, outside the tank and very far away.
        let mut queries: Vec<Vec2> = (0..4000)
            .map(|i| Vec2::new((i / 60) as f32 * 0.0061, (i % 60) as f32 * 0.0049))
            .collect();
        queries.extend([
            Vec2::new(0.0, 0.0),
            Vec2::new(radius * 3.0, -radius),
            Vec2::new(4.0 + radius, 1.5),
            Vec2::new(-0.05, 3.05),
            Vec2::new(1.0e6, -1.0e6),
            Vec2::new(-3.0e4, 2.0),
        ]);
        assert!(check_cross(&mut grid, &queries, radius) > 0);
    }

    #[test]
    fn floor_to_i64_is_floor_then_as() {
        let edge = 2f64.powi(53);
        for v in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999,
            -2.000_001,
            1e-300,
            -1e-300,
            edge - 0.5,
            -edge + 0.5,
            edge * 3.0,
            -edge * 3.0,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            assert_eq!(floor_to_i64(v), v.floor() as i64, "{v}");
        }
    }

    #[test]
    fn permute_gathers_by_order() {
        let mut v = vec![10, 20, 30, 40];
        let mut scratch = Vec::new();
        permute(&mut v, &[2, 0, 3, 1], &mut scratch);
        assert_eq!(v, vec![30, 10, 40, 20]);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn random_configurations_match_brute_force(
            pts in prop::collection::vec((-2.0f32..2.0, -1.0f32..3.0), 0..400),
            radius in 0.01f32..0.5,
            far in prop::collection::vec((-1.0e5f32..1.0e5, -1.0e5f32..1.0e5), 0..3),
        ) {
            let mut points: Vec<Vec2> = pts.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
            // Clusters and duplicates stress the buckets.
            let n = points.len();
            for k in 0..n / 10 {
                points.push(points[k]);
            }
            points.extend(far.iter().map(|&(x, y)| Vec2::new(x, y)));
            check(points, radius);
        }
    }
}
