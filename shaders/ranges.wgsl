// Cell-range tables on the GPU: the twin of src/backend/gpu/ranges.rs
// (fluid_rows, wall_rows), with CellGrid::neighbor_ranges of
// kernels/src/grid.rs. A query row gets the (start, end) particle ranges of
// the occupied cells among the 27 around its cell, in the fixed order of
// neighbor_ranges (z outer, then y, then x; -1, 0, +1; cells outside
// [0, 2^21 - 1] left out), then (0, 0) slots. The CPU finds a cell in a
// hash table, the GPU by binary search in the sorted keys: both find the
// same cell or none, so the tables are bitwise equal. Integer work only,
// except cell_of of the walls (the same f32 operations as grid.rs, as in
// shaders/neighbors.wgsl). fluid_rows also writes cell_row, each fluid
// particle's row (its cell; the fluid is sorted by cell). The tables stay on
// the device: the passes (iisph.wgsl, drift.wgsl) bind these buffers.
//
// Prepended: common_grid.wgsl (WG, RANGES, MAX_CELL, linear_index,
// cell_coord, morton).

struct RangesParams {
    // Rows: fluid cells (fluid_rows) or active walls (wall_rows).
    n_fluid_cells: u32,
    n_wall_cells: u32,
    n_active: u32,
    // 1 / cell size, 1/m (the grid's inv_cell).
    inv_cell: f32,
}

@group(0) @binding(0) var<uniform> P: RangesParams;
// Occupied cells' keys (hi, lo), ascending, and their starts (cells + 1).
@group(0) @binding(1) var<storage, read> fluid_cells: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(3) var<storage, read> wall_cells: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> wall_starts: array<u32>;
// Wall positions (xyz) and the active walls.
@group(0) @binding(5) var<storage, read> wall_pos: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> active_walls: array<u32>;
// Outputs: per fluid cell fluid / wall ranges, per active wall fluid ranges.
@group(0) @binding(7) var<storage, read_write> ff: array<vec2<u32>>;
@group(0) @binding(8) var<storage, read_write> fb: array<vec2<u32>>;
@group(0) @binding(9) var<storage, read_write> bf: array<vec2<u32>>;
// Per fluid particle: its cell, the row of ff / fb.
@group(0) @binding(10) var<storage, read_write> cell_row: array<u32>;

// grid.rs unmorton.
fn unmorton(k: vec2<u32>) -> vec3<u32> {
    var c = vec3<u32>(0u);
    for (var p = 0u; p < 63u; p++) {
        var bit = 0u;
        if (p < 32u) {
            bit = (k.y >> p) & 1u;
        } else {
            bit = (k.x >> (p - 32u)) & 1u;
        }
        c[p % 3u] |= bit << (p / 3u);
    }
    return c;
}

fn less(a: vec2<u32>, b: vec2<u32>) -> bool {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
}

// The particle range of the cell with key `key` in the fluid (t = 0) or
// wall (t = 1) grid, (0, 0) if unoccupied (CellGrid::range).
fn range_of(t: u32, key: vec2<u32>) -> vec2<u32> {
    var lo = 0u;
    var hi = select(P.n_wall_cells, P.n_fluid_cells, t == 0u);
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        var k = vec2<u32>(0u);
        if (t == 0u) {
            k = fluid_cells[mid];
        } else {
            k = wall_cells[mid];
        }
        if (less(k, key)) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    let n = select(P.n_wall_cells, P.n_fluid_cells, t == 0u);
    if (lo >= n) {
        return vec2<u32>(0u);
    }
    if (t == 0u) {
        if (all(fluid_cells[lo] == key)) {
            return vec2<u32>(fluid_starts[lo], fluid_starts[lo + 1u]);
        }
    } else {
        if (all(wall_cells[lo] == key)) {
            return vec2<u32>(wall_starts[lo], wall_starts[lo + 1u]);
        }
    }
    return vec2<u32>(0u);
}

// CellGrid::neighbor_ranges of cell c in grid t, then (0, 0) slots.
fn neighbor_ranges(t: u32, c: vec3<u32>) -> array<vec2<u32>, 27> {
    var out: array<vec2<u32>, 27>;
    var n = 0u;
    for (var dz = 0u; dz < 3u; dz++) {
        for (var dy = 0u; dy < 3u; dy++) {
            for (var dx = 0u; dx < 3u; dx++) {
                let d = vec3<u32>(dx, dy, dz);
                // c + d - 1 within [0, MAX_CELL] on every axis.
                if (any((c + d) < vec3<u32>(1u)) || any((c + d) > vec3<u32>(MAX_CELL + 1u))) {
                    continue;
                }
                let r = range_of(t, morton(c + d - vec3<u32>(1u)));
                if (r.y > r.x) {
                    out[n] = r;
                    n++;
                }
            }
        }
    }
    for (var k = n; k < RANGES; k++) {
        out[k] = vec2<u32>(0u);
    }
    return out;
}

// ranges.rs fluid_rows: row c of ff / fb holds the fluid / wall ranges
// around fluid cell c, and cell_row of the particles of cell c is c.
@compute @workgroup_size(64)
fn fluid_rows(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let c = linear_index(gid, nwg);
    if (c >= P.n_fluid_cells) {
        return;
    }
    let cell = unmorton(fluid_cells[c]);
    let f = neighbor_ranges(0u, cell);
    let b = neighbor_ranges(1u, cell);
    for (var k = 0u; k < RANGES; k++) {
        ff[c * RANGES + k] = f[k];
        fb[c * RANGES + k] = b[k];
    }
    for (var i = fluid_starts[c]; i < fluid_starts[c + 1u]; i++) {
        cell_row[i] = c;
    }
}

// ranges.rs wall_rows: row k of bf holds the fluid ranges around the cell
// of wall active[k].
@compute @workgroup_size(64)
fn wall_rows(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = linear_index(gid, nwg);
    if (k >= P.n_active) {
        return;
    }
    let x = wall_pos[active_walls[k]];
    let cell = vec3<u32>(cell_coord(x.x, P.inv_cell), cell_coord(x.y, P.inv_cell), cell_coord(x.z, P.inv_cell));
    let f = neighbor_ranges(0u, cell);
    for (var q = 0u; q < RANGES; q++) {
        bf[k * RANGES + q] = f[q];
    }
}
