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

// Bits 0..9 of x to bits 0, 3, .., 27 (grid.rs part1by2 on 32 bits).
fn spread10(x: u32) -> u32 {
    var v = x & 0x3ffu;
    v = (v | (v << 16u)) & 0x030000ffu;
    v = (v | (v << 8u)) & 0x0300f00fu;
    v = (v | (v << 4u)) & 0x030c30c3u;
    v = (v | (v << 2u)) & 0x09249249u;
    return v;
}

// Bits 0..20 of x to bits 0, 3, .., 60 of a 64-bit word, as (hi, lo):
// bits 0..10 to lo bits 0..30, bits 11..20 to bits 33..60 (hi bits 1..28).
fn spread21(x: u32) -> vec2<u32> {
    let lo = spread10(x) | (((x >> 10u) & 1u) << 30u);
    let hi = spread10(x >> 11u) << 1u;
    return vec2<u32>(hi, lo);
}

// Morton key of cell coordinates (grid.rs morton): bit b of axis a goes to
// bit 3 b + a of the 63-bit key, returned as (hi, lo); part1by2 of each
// axis as in grid.rs, on two 32-bit words.
fn morton(c: vec3<u32>) -> vec2<u32> {
    let x = spread21(c.x);
    let y = spread21(c.y);
    let z = spread21(c.z);
    // x | y << 1 | z << 2 on (hi, lo) words.
    let hi = x.x | (y.x << 1u) | (y.y >> 31u) | (z.x << 2u) | (z.y >> 30u);
    let lo = x.y | (y.y << 1u) | (z.y << 2u);
    return vec2<u32>(hi, lo);
}
