// Drift velocities of the mixture model: the GPU twin of
// kernels/src/drift.rs (PHYSICS.md §4.1, pass 10 of §6), with the same
// function names: phase_velocity, mixture_velocity, drift_velocity. The
// largest drift speed (max_drift_speed) is taken on the host from the
// read-back drift velocities.
//
// The CPU pass reads per-pair g_ij = Vbar_ij grad W_ij from the fluid-fluid
// pair lists (scaled by the harmonic pair volume in pass 4); here the pairs
// are found from the cell-range tables of shaders/ranges.wgsl (27 particle
// ranges per fluid cell) and g_ij is recomputed from positions and current
// volumes. Summation order: the GPU adds each neighbour's term one by one in
// the order of the cell ranges (cells in CellGrid::neighbor_ranges order,
// particles ascending); the CPU adds them in 16 SIMD lanes, then across
// lanes. Per-particle phase loops (mass, s, m) run k = 0.. in the same order
// as the CPU.
//
// Per-phase arrays are stored phase-major: element (k, i) at k * n + i.
//
// With porous solids (PHYSICS.md §4.2) the host runs the three kernels
// twice per step: for the outer fractions alpha with P-Eq. 11's porous term
// (extra = grad p^pore_fk, extra_scale = -phi), then for the inner fractions
// beta (P-Eq. 12: alpha <- beta, alpha_f <- beta_f, sigma_k <- sigma',
// no phase pressure, extra = q_k,f, extra_scale = -tau', and every volume
// h^3: the CPU's inner pairs hold h^3 grad W_ij).

struct DriftParams {
    n: u32,
    n_phases: u32,
    // 1: phase pressures p_k = alphahat_k p (pf holds p / alpha_f); 0: shared.
    fraction_pressure: u32,
    // 1: F_k = w_k - alpha_k m (conservative transport); 0: F_k = alpha_k u_mk.
    conservative: u32,
    // The scene's kernel (common_kernel.wgsl).
    kernel: KernelParams,
    // 1: add extra_scale e_k to v_k and alpha_k extra_scale e_k to w_k
    // (kernels/src/porous.rs add_phase_term); 0: no extra term.
    extra_term: u32,
    extra_scale: f32,
    // > 0: every particle's volume (the inner pass's h^3), m^3; 0: pos.w.
    uniform_volume: f32,
    pad: u32,
    // Per phase (rho_k, tau_k, sigma_k, 0).
    phase: array<vec4<f32>, 8>,
}

// PHYSICS.md §4.1 guards (kernels/src/phases.rs).
const MIN_ALPHA_F: f32 = 0.01;
const MIN_PHASE_FRACTION: f32 = 0.01;

@group(0) @binding(0) var<uniform> P: DriftParams;
// Fluid x, y, z (m) and current volume V (m^3).
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
// alpha_k per phase and particle.
@group(0) @binding(2) var<storage, read> alpha: array<f32>;
// alpha_f = sum_k alpha_k.
@group(0) @binding(3) var<storage, read> alpha_f: array<f32>;
// p / alpha_f (only read with fraction_pressure), Pa.
@group(0) @binding(4) var<storage, read> pf: array<f32>;
// a = -(a^visc + a^p) (xyz), m/s^2.
@group(0) @binding(5) var<storage, read> acc: array<vec4<f32>>;
// Row of the cell-range tables of each fluid particle (its cell), and the
// fluid ranges per fluid cell.
@group(0) @binding(6) var<storage, read> cell_row: array<u32>;
@group(0) @binding(7) var<storage, read> ff_ranges: array<vec2<u32>>;
// v_k, then u_mk (xyz), per phase and particle, m/s.
@group(0) @binding(8) var<storage, read_write> v: array<vec4<f32>>;
// w_k, then F_k (xyz), per phase and particle, m/s.
@group(0) @binding(9) var<storage, read_write> w: array<vec4<f32>>;
// s = sum_k c_k v_k and m = sum_k alphahat_k v_k (xyz), m/s.
@group(0) @binding(10) var<storage, read_write> s: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> m: array<vec4<f32>>;
// e_k (xyz) per phase and particle: grad p^pore_fk (Pa/m) or q_k,f (m/s);
// only read with extra_term.
@group(0) @binding(12) var<storage, read> extra: array<vec4<f32>>;

// Step 1 (kernels/src/drift.rs phase_velocity), every phase of particle i:
// v_k = tau_k (rho_k a - grad p_k) - sigma_k grad alpha_k / alpha_k (the
// diffusion part dropped where alphahat_k < 0.01) and
// w_k = alpha_k tau_k (rho_k a - grad p_k) - sigma_k grad alpha_k; all 0
// where alpha_f < 0.01. Gradients in difference form over fluid neighbours.
@compute @workgroup_size(64)
fn phase_velocity(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    let n = P.n;
    if (i >= n) {
        return;
    }
    let af = alpha_f[i];
    if (af < MIN_ALPHA_F) {
        for (var k = 0u; k < P.n_phases; k++) {
            v[k * n + i] = vec4<f32>(0.0);
            w[k * n + i] = vec4<f32>(0.0);
        }
        return;
    }
    let xi = pos[i];
    let uniform = P.uniform_volume > 0.0;
    let vi = select(xi.w, P.uniform_volume, uniform);
    let row = cell_row[i] * RANGES;
    let a = acc[i].xyz;
    let fraction = P.fraction_pressure != 0u;
    for (var k = 0u; k < P.n_phases; k++) {
        let ai = alpha[k * n + i];
        var pki = 0.0;
        if (fraction) {
            pki = ai * pf[i];
        }
        var ga = vec3<f32>(0.0);
        var gp = vec3<f32>(0.0);
        for (var c = 0u; c < RANGES; c++) {
            let r = ff_ranges[row + c];
            for (var j = r.x; j < r.y; j++) {
                let xj = pos[j];
                let g = pair_gradient(xi.xyz, xj.xyz, vi, select(xj.w, P.uniform_volume, uniform));
                let aj = alpha[k * n + j];
                ga += (aj - ai) * g;
                if (fraction) {
                    gp += (aj * pf[j] - pki) * g;
                }
            }
        }
        let ph = P.phase[k];
        let rho = ph.x;
        let tau = ph.y;
        let sigma = ph.z;
        let t = tau * (rho * a - gp);
        var vk = t;
        if (ai >= MIN_PHASE_FRACTION * af) {
            vk = t - sigma * ga / ai;
        }
        var wk = ai * t - sigma * ga;
        // P-Eq. 11's -phi (grad p^pore_fk - ...) or P-Eq. 12's -tau' q_k,f
        // (the sum over phases follows in mixture_velocity).
        if (P.extra_term != 0u) {
            let e = P.extra_scale * extra[k * n + i].xyz;
            vk += e;
            wk += ai * e;
        }
        v[k * n + i] = vec4<f32>(vk, 0.0);
        w[k * n + i] = vec4<f32>(wk, 0.0);
    }
}

// Step 2 (mixture_velocity): s = sum_k rho_k w_k / sum_k alpha_k rho_k and
// m = sum_k w_k / alpha_f; both 0 where alpha_f < 0.01 or the mass is 0.
@compute @workgroup_size(64)
fn mixture_velocity(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    let n = P.n;
    if (i >= n) {
        return;
    }
    let af = alpha_f[i];
    var mass = 0.0;
    for (var k = 0u; k < P.n_phases; k++) {
        mass += alpha[k * n + i] * P.phase[k].x;
    }
    if (af < MIN_ALPHA_F || mass <= 0.0) {
        s[i] = vec4<f32>(0.0);
        m[i] = vec4<f32>(0.0);
        return;
    }
    var ms = vec3<f32>(0.0);
    var mv = vec3<f32>(0.0);
    for (var k = 0u; k < P.n_phases; k++) {
        let wk = w[k * n + i].xyz;
        ms += P.phase[k].x * wk;
        mv += wk;
    }
    s[i] = vec4<f32>(ms / mass, 0.0);
    m[i] = vec4<f32>(mv / af, 0.0);
}

// Step 3 (drift_velocity), every phase: u_mk = v_k - s over v_k, and the
// phase flux over w_k: F_k = w_k - alpha_k m (conservative) or alpha_k u_mk.
@compute @workgroup_size(64)
fn drift_velocity(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_index(gid, nwg);
    let n = P.n;
    if (i >= n) {
        return;
    }
    let si = s[i].xyz;
    let mi = m[i].xyz;
    for (var k = 0u; k < P.n_phases; k++) {
        let a = alpha[k * n + i];
        let u = v[k * n + i].xyz - si;
        v[k * n + i] = vec4<f32>(u, 0.0);
        if (P.conservative != 0u) {
            w[k * n + i] = vec4<f32>(w[k * n + i].xyz - a * mi, 0.0);
        } else {
            w[k * n + i] = vec4<f32>(a * u, 0.0);
        }
    }
}
