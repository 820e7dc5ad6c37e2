// Shared WGSL, prepended to the shaders that list it in SHADERS
// (src/backend/gpu/mod.rs; WGSL has no include): the dispatch index and the
// cell grid of kernels/src/grid.rs (cell_of, morton), and the constants of
// the cell-range tables (src/backend/gpu/ranges.rs). A shader that gets this
// file must not declare WG, RANGES, ORIGIN, MAX_COORD, MAX_CELL,
// linear_index, cell_coord or morton itself. Pure functions: what they need
// comes in as arguments.

// Workgroup size of every 2D-dispatched entry point (the hosts' WG = 64).
const WG: u32 = 64u;
// Cells around a query row of the cell-range tables: 27 (start, end)
// ranges, empty ones (0, 0).
const RANGES: u32 = 27u;
// grid.rs: cells are floor(x / H) + ORIGIN, clamped to 21 bits.
const ORIGIN: f32 = 1048576.0;
const MAX_COORD: f32 = 2097151.0;
const MAX_CELL: u32 = 2097151u;

// Linear invocation index of a 2D dispatch of WG-wide workgroups.
fn linear_index(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return gid.y * nwg.x * WG + gid.x;
}

// Integer cell coordinate of one axis (grid.rs cell_of, the same f32
// operations), inv_cell = 1 / cell size: non-finite -> the origin cell,
// clamped to [0, 2^21 - 1].
fn cell_coord(v: f32, inv_cell: f32) -> u32 {
    let f = floor(v * inv_cell);
    if (!(abs(f) <= 3.0e38)) {
        return u32(ORIGIN);
    }
    return u32(clamp(f + ORIGIN, 0.0, MAX_COORD));
}

// Morton key of cell coordinates (grid.rs morton): bit b of axis a goes to
// bit 3 b + a of the 63-bit key, returned as (hi, lo).
fn morton(c: vec3<u32>) -> vec2<u32> {
    var hi = 0u;
    var lo = 0u;
    for (var b = 0u; b < 21u; b++) {
        for (var a = 0u; a < 3u; a++) {
            let bit = (c[a] >> b) & 1u;
            let p = 3u * b + a;
            if (p < 32u) {
                lo |= bit << p;
            } else {
                hi |= bit << (p - 32u);
            }
        }
    }
    return vec2<u32>(hi, lo);
}
