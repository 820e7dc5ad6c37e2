// Neighbour search, sort part: the GPU twin of compute_keys and
// sort_permutation in kernels/src/neighbors.rs (with cell_of and morton of
// kernels/src/grid.rs), pass 0 of PHYSICS.md §6.
//
// compute_keys writes each particle's 63-bit Morton cell key as two u32
// (hi, lo) with its index; sort_permutation is one compare-exchange step
// of a bitonic sort of (key, index) over the next power of two (padding
// sorts last). Keys are unique with the index, so the order is the one the
// CPU's sort gives, bit for bit. Integer work only: no rounding differs.

struct NeighborParams {
    n: u32,
    n_pow2: u32,
    // Bitonic step: sequence size k, compare distance j.
    k: u32,
    j: u32,
    // 1 / cell size, 1/m (the CPU's inv_cell, same f32).
    inv_cell: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

const WG: u32 = 64u;
// grid.rs: cells are floor(x / H) + ORIGIN, clamped to 21 bits.
const ORIGIN: f32 = 1048576.0;
const MAX_COORD: f32 = 2097151.0;

@group(0) @binding(0) var<uniform> P: NeighborParams;
// Positions x, y, z (m); w unused.
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
// (key hi, key lo, index, 0).
@group(0) @binding(2) var<storage, read_write> keys: array<vec4<u32>>;

fn linear_index(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return gid.y * nwg.x * WG + gid.x;
}

// Integer cell coordinate of one axis (grid.rs cell_of): non-finite -> the
// origin cell, clamped to [0, 2^21 - 1].
fn cell_coord(v: f32) -> u32 {
    let f = floor(v * P.inv_cell);
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

@compute @workgroup_size(64)
fn compute_keys(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    if (i >= P.n_pow2) {
        return;
    }
    if (i >= P.n) {
        keys[i] = vec4<u32>(0xffffffffu, 0xffffffffu, 0xffffffffu, 0u);
        return;
    }
    let x = pos[i];
    let k = morton(vec3<u32>(cell_coord(x.x), cell_coord(x.y), cell_coord(x.z)));
    keys[i] = vec4<u32>(k.x, k.y, i, 0u);
}

// a < b in (hi, lo, index) order.
fn less(a: vec4<u32>, b: vec4<u32>) -> bool {
    if (a.x != b.x) {
        return a.x < b.x;
    }
    if (a.y != b.y) {
        return a.y < b.y;
    }
    return a.z < b.z;
}

@compute @workgroup_size(64)
fn sort_permutation(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    let l = i ^ P.j;
    if (i >= P.n_pow2 || l <= i) {
        return;
    }
    let a = keys[i];
    let b = keys[l];
    let ascending = (i & P.k) == 0u;
    if (less(b, a) == ascending) {
        keys[i] = b;
        keys[l] = a;
    }
}
