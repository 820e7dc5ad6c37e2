// Neighbour search, sort part: the GPU twin of compute_keys and
// sort_permutation in kernels/src/neighbors.rs (with cell_of and morton of
// kernels/src/grid.rs), pass 0 of PHYSICS.md §6.
//
// compute_keys writes each particle's 63-bit Morton cell key as two u32
// (hi, lo) with its index; sort_permutation is one compare-exchange step
// of a bitonic sort of (key, index) over the next power of two (padding
// sorts last). Keys are unique with the index, so the order is the one the
// CPU's sort gives, bit for bit. Integer work only: no rounding differs.
//
// Prepended: common_grid.wgsl (WG, linear_index, cell_coord, morton).

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

@group(0) @binding(0) var<uniform> P: NeighborParams;
// Positions x, y, z (m); w unused.
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
// (key hi, key lo, index, 0).
@group(0) @binding(2) var<storage, read_write> keys: array<vec4<u32>>;

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
    let k = morton(vec3<u32>(cell_coord(x.x, P.inv_cell), cell_coord(x.y, P.inv_cell), cell_coord(x.z, P.inv_cell)));
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
