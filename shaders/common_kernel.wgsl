// Shared WGSL, prepended to the shaders that list it in SHADERS
// (src/backend/gpu/mod.rs; WGSL has no include): the kernel gradient
// (kernels/src/kernel.rs grad_over_r, both shapes) and the pair gradient
// g_ij = Vbar_ij grad W_ij recomputed from positions and current volumes.
//
// Convention: the shader that gets this file declares its uniform
// parameters as `P` with a field `kernel: KernelParams`, as IisphParams and
// DriftParams do (WGSL resolves module-scope names in any order). It must
// not declare KernelParams, the KERNEL_* constants, grad_over_r,
// harmonic_volumes or pair_gradient itself.

// The scene's kernel (src/backend/gpu/kernel.rs KernelParams, built from
// kernels/src/kernel.rs Kernel: the constants are computed there, once).
struct KernelParams {
    // KERNEL_CUBIC_SPLINE or KERNEL_WENDLAND_C2.
    shape: u32,
    // Support radius H, m; 1/H, 1/m.
    support: f32,
    inv_support: f32,
    // The gradient's constant l (Kernel::grad_scale), 1/m^4.
    grad_scale: f32,
}

const KERNEL_CUBIC_SPLINE: u32 = 0u;
const KERNEL_WENDLAND_C2: u32 = 1u;

// W'(r)/r, 1/m^5 (kernel.rs grad_over_r), of the scene's kernel shape.
fn grad_over_r(r: f32) -> f32 {
    let q = r * P.kernel.inv_support;
    let om = max(1.0 - q, 0.0);
    if (P.kernel.shape == KERNEL_WENDLAND_C2) {
        // kernel.rs wendland_grad_over_r: -l (1-q)^3.
        return -P.kernel.grad_scale * om * om * om;
    }
    // kernel.rs cubic_spline_grad_over_r: l (3q - 2) / H for q <= 1/2,
    // -l (1-q)^2 / r beyond (r >= H/2 > 0 there).
    let inner = P.kernel.grad_scale * (3.0 * q - 2.0) * P.kernel.inv_support;
    let outer = -P.kernel.grad_scale * om * om / max(r, 0.5 * P.kernel.support);
    return select(outer, inner, q <= 0.5);
}

// Harmonic pair volume Vbar_ij = 2 V_i V_j / (V_i + V_j), 0 if V_i V_j = 0.
fn harmonic_volumes(vi: f32, vj: f32) -> f32 {
    let prod = vi * vj;
    return select(0.0, 2.0 * prod / (vi + vj), prod > 0.0);
}

// g_ij = Vbar_ij grad W(x_i - x_j), or 0 outside the support.
fn pair_gradient(xi: vec3<f32>, xj: vec3<f32>, vi: f32, vj: f32) -> vec3<f32> {
    let d = xi - xj;
    let r2 = d.x * d.x + d.y * d.y + d.z * d.z;
    if (r2 >= P.kernel.support * P.kernel.support) {
        return vec3<f32>(0.0);
    }
    return (grad_over_r(sqrt(r2)) * d) * harmonic_volumes(vi, vj);
}
