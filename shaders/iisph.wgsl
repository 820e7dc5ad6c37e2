// IISPH relaxed Jacobi loop with pressure boundaries: the GPU twin of the
// Jacobi part of kernels/src/iisph.rs (PHYSICS.md §2.2-2.4, pass 5 of §6),
// with the same function names: pressure_acceleration (P-Eq. 27),
// fluid_jacobi and wall_jacobi (P-Eq. 28), and the mean-error reduction.
//
// The CPU pass reads per-pair gradients stored by the neighbour search; here
// the pairs are found from cell ranges (for each query row, the particle
// ranges of the 27 cells around it) and g_ij = Vbar_ij grad W_ij is
// recomputed from positions and current volumes, so the pair lists never
// leave the host. Every entry point of the loop returns at once when the
// status says the solve has converged, so the host can queue several
// iterations per submission and read the status back once per submission,
// never once per iteration.
//
// Reductions use a fixed tree (no atomics), so a run is reproducible on the
// same device.
//
// Prepended: common_grid.wgsl (WG, RANGES, linear_index) and
// common_kernel.wgsl (KernelParams, grad_over_r, harmonic_volumes,
// pair_gradient; they read P.kernel).

struct IisphParams {
    n_fluid: u32,
    n_active: u32,
    min_iterations: u32,
    max_iterations: u32,
    // The scene's kernel (common_kernel.wgsl).
    kernel: KernelParams,
    // Time step, s; Jacobi relaxation; target mean density error; number of
    // fluid rows in the solve (diag != 0), as f32.
    dt: f32,
    omega: f32,
    max_density_error: f32,
    rows_active: f32,
    // The Chebyshev semi-iteration (kernels/src/chebyshev.rs): the radius
    // estimate (0: plain Jacobi) and the plain sweeps before it starts.
    chebyshev_radius: f32,
    chebyshev_plain: u32,
    pad0: u32,
    pad1: u32,
}

struct Status {
    iterations: u32,
    done: u32,
    density_error: f32,
    // The Chebyshev weight of the last sweep (1 while plain).
    weight: f32,
}

// Reduction: 256 threads x 4 consecutive values per workgroup.
const RED_WG: u32 = 256u;
const RED_PER_THREAD: u32 = 4u;
const RED_SPAN: u32 = 1024u;
// f32::MIN_POSITIVE: rows with |a_ii| below it take no part.
const MIN_DIAG: f32 = 1.17549435e-38;

@group(0) @binding(0) var<uniform> P: IisphParams;
// Fluid x, y, z (m) and current volume V (m^3).
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
// Fluid V/m, m^3/kg.
@group(0) @binding(2) var<storage, read> vm: array<f32>;
// Fluid pressure, Pa.
@group(0) @binding(3) var<storage, read_write> p: array<f32>;
// Fluid pressure acceleration a^p (xyz), m/s^2.
@group(0) @binding(4) var<storage, read_write> ap: array<vec4<f32>>;
// Fluid rows: (source S, diagonal a_ii).
@group(0) @binding(5) var<storage, read> rows: array<vec2<f32>>;
// max(-r_i, 0) per fluid row.
@group(0) @binding(6) var<storage, read_write> err: array<f32>;
// Row of the cell-range tables of each fluid particle (its cell).
@group(0) @binding(7) var<storage, read> cell_row: array<u32>;
// Per fluid cell: fluid ranges, then wall ranges.
@group(0) @binding(8) var<storage, read> ff_ranges: array<vec2<u32>>;
@group(0) @binding(9) var<storage, read> fb_ranges: array<vec2<u32>>;
// Wall x, y, z (m; static), current volume V (m^3; 0 for inactive walls), pressure.
@group(0) @binding(10) var<storage, read> wall_pos: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read> wall_vol: array<f32>;
@group(0) @binding(12) var<storage, read_write> p_wall: array<f32>;
// Active walls (wall indices), their rows (S, a_bb) and fluid ranges.
@group(0) @binding(13) var<storage, read> active_walls: array<u32>;
@group(0) @binding(14) var<storage, read> wall_rows: array<vec2<f32>>;
@group(0) @binding(15) var<storage, read> bf_ranges: array<vec2<u32>>;
@group(0) @binding(16) var<storage, read_write> partials: array<f32>;
@group(0) @binding(17) var<storage, read_write> status: Status;
// The semi-iteration's iterates (the one before the last, the last) of
// the fluid rows and of the active wall rows (by active index).
@group(0) @binding(18) var<storage, read_write> cheb: array<vec2<f32>>;
@group(0) @binding(19) var<storage, read_write> cheb_wall: array<vec2<f32>>;

var<workgroup> scratch: array<f32, RED_WG>;

// a^p_f = -(V_f/m_f) sum_j Vbar (p_f + p_j) grad W over fluid and wall
// neighbours (P-Eq. 27, factor 2 restored).
fn pressure_acceleration_at(i: u32) {
    let xi = pos[i];
    let pi = p[i];
    let row = cell_row[i] * RANGES;
    var s = vec3<f32>(0.0);
    for (var c = 0u; c < RANGES; c++) {
        let r = ff_ranges[row + c];
        for (var j = r.x; j < r.y; j++) {
            let xj = pos[j];
            s += (pi + p[j]) * pair_gradient(xi.xyz, xj.xyz, xi.w, xj.w);
        }
    }
    for (var c = 0u; c < RANGES; c++) {
        let r = fb_ranges[row + c];
        for (var b = r.x; b < r.y; b++) {
            s += (pi + p_wall[b]) * pair_gradient(xi.xyz, wall_pos[b].xyz, xi.w, wall_vol[b]);
        }
    }
    ap[i] = vec4<f32>(-vm[i] * s, 0.0);
}

@compute @workgroup_size(64)
fn pressure_acceleration(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    if (i >= P.n_fluid || status.done != 0u) {
        return;
    }
    pressure_acceleration_at(i);
}

// After the loop: a^p from the final pressures.
@compute @workgroup_size(64)
fn pressure_acceleration_final(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    if (i >= P.n_fluid) {
        return;
    }
    pressure_acceleration_at(i);
}

// (Ap)_f = dt^2 sum_j Vbar (a^p_f - a^p_j).grad W (walls: a^p = 0),
// r_f = S_f - (Ap)_f, p_f <- max(0, p_f + omega r_f / a_ff) (P-Eq. 28);
// err_f = max(-r_f, 0).
@compute @workgroup_size(64)
fn fluid_jacobi(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    if (i >= P.n_fluid || status.done != 0u) {
        return;
    }
    let rw = rows[i];
    if (abs(rw.y) < MIN_DIAG) {
        p[i] = 0.0;
        err[i] = 0.0;
        return;
    }
    let xi = pos[i];
    let ai = ap[i].xyz;
    let row = cell_row[i] * RANGES;
    var acc = 0.0;
    for (var c = 0u; c < RANGES; c++) {
        let r = ff_ranges[row + c];
        for (var j = r.x; j < r.y; j++) {
            let xj = pos[j];
            acc += dot(ai - ap[j].xyz, pair_gradient(xi.xyz, xj.xyz, xi.w, xj.w));
        }
    }
    for (var c = 0u; c < RANGES; c++) {
        let r = fb_ranges[row + c];
        for (var b = r.x; b < r.y; b++) {
            acc += dot(ai, pair_gradient(xi.xyz, wall_pos[b].xyz, xi.w, wall_vol[b]));
        }
    }
    let res = rw.x - P.dt * P.dt * acc;
    p[i] = max(p[i] + P.omega * res / rw.y, 0.0);
    err[i] = max(-res, 0.0);
}

// Active wall rows: (Ap)_b = -dt^2 sum_f Vbar a^p_f.grad W_bf, then as fluid_jacobi.
@compute @workgroup_size(64)
fn wall_jacobi(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = linear_index(gid, nwg);
    if (k >= P.n_active || status.done != 0u) {
        return;
    }
    let b = active_walls[k];
    let rw = wall_rows[k];
    if (abs(rw.y) < MIN_DIAG) {
        p_wall[b] = 0.0;
        return;
    }
    let xb = wall_pos[b].xyz;
    let vb = wall_vol[b];
    let row = k * RANGES;
    var acc = 0.0;
    for (var c = 0u; c < RANGES; c++) {
        let r = bf_ranges[row + c];
        for (var j = r.x; j < r.y; j++) {
            let xj = pos[j];
            acc += dot(ap[j].xyz, pair_gradient(xb, xj.xyz, vb, xj.w));
        }
    }
    let res = rw.x + P.dt * P.dt * acc;
    p_wall[b] = max(p_wall[b] + P.omega * res / rw.y, 0.0);
}

// Tree sum of scratch[0..RED_WG] into scratch[0].
fn tree_sum(t: u32) {
    for (var stride = RED_WG / 2u; stride > 0u; stride = stride / 2u) {
        if (t < stride) {
            scratch[t] += scratch[t + stride];
        }
        workgroupBarrier();
    }
}

// Mean error, stage 1: the sum of each span of RED_SPAN errors, in a fixed
// tree (each thread adds its 4 consecutive values in order, then the tree).
@compute @workgroup_size(256)
fn mean_error_partial(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_index) t: u32,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let group = wid.y * nwg.x + wid.x;
    let base = group * RED_SPAN + t * RED_PER_THREAD;
    var s = 0.0;
    for (var k = 0u; k < RED_PER_THREAD; k++) {
        if (base + k < P.n_fluid) {
            s += err[base + k];
        }
    }
    scratch[t] = s;
    workgroupBarrier();
    tree_sum(t);
    if (t == 0u && group * RED_SPAN < P.n_fluid && status.done == 0u) {
        partials[group] = scratch[0];
    }
}

// Mean error, stage 2 (one workgroup): the sum of the partial sums (thread t
// adds partials t, t + 256, ... in order, then the tree), divided by the
// number of rows; counts the iteration and decides convergence: at least
// min_iterations and mean error <= max_density_error, or max_iterations.
@compute @workgroup_size(256)
fn mean_error(@builtin(local_invocation_index) t: u32) {
    let n_parts = (P.n_fluid + RED_SPAN - 1u) / RED_SPAN;
    let rounds = (n_parts + RED_WG - 1u) / RED_WG;
    var s = 0.0;
    for (var k = 0u; k < rounds; k++) {
        let idx = k * RED_WG + t;
        if (idx < n_parts) {
            s += partials[idx];
        }
    }
    scratch[t] = s;
    workgroupBarrier();
    tree_sum(t);
    if (t == 0u && status.done == 0u) {
        let it = status.iterations + 1u;
        let e = scratch[0] / P.rows_active;
        status.iterations = it;
        status.density_error = e;
        if ((it >= P.min_iterations && e <= P.max_density_error) || it >= P.max_iterations) {
            status.done = 1u;
        }
        // chebyshev::Weights::after_sweep.
        let r2 = P.chebyshev_radius * P.chebyshev_radius;
        var w = 1.0;
        if (it == P.chebyshev_plain + 2u) {
            w = 2.0 / (2.0 - r2);
        } else if (it > P.chebyshev_plain + 2u) {
            w = 4.0 / (4.0 - r2 * status.weight);
        }
        status.weight = w;
    }
}

// chebyshev::extrapolate on one row: `pj` the plain sweep's pressure, `c2`
// (the iterate before the last, the last); returns the row's new pressure
// and leaves (the last, the new) in c2.
fn chebyshev_row(pj: f32, c2: ptr<function, vec2<f32>>) -> f32 {
    let q = (*c2).x;
    let c = (*c2).y;
    let w = status.weight;
    var np = pj;
    if (w != 1.0 && q > 0.0 && c > 0.0) {
        np = max(w * (pj - q) + q, 0.0);
    }
    *c2 = vec2<f32>(c, np);
    return np;
}

// After mean_error, when the sweep was not the last: the fluid rows'
// extrapolation (only dispatched with P.chebyshev_radius > 0).
@compute @workgroup_size(64)
fn chebyshev_fluid(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    if (i >= P.n_fluid || status.done != 0u) {
        return;
    }
    var c2 = cheb[i];
    p[i] = chebyshev_row(p[i], &c2);
    cheb[i] = c2;
}

// The same for the active wall rows.
@compute @workgroup_size(64)
fn chebyshev_walls(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let k = linear_index(gid, nwg);
    if (k >= P.n_active || status.done != 0u) {
        return;
    }
    let b = active_walls[k];
    var c2 = cheb_wall[k];
    p_wall[b] = chebyshev_row(p_wall[b], &c2);
    cheb_wall[k] = c2;
}
