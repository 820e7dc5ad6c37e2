// Shared WGSL, prepended to the shaders that list it in SHADERS
// (src/backend/gpu/mod.rs; WGSL has no include): the cubic spline gradient
// (kernels/src/kernel.rs) and the pair gradient g_ij = Vbar_ij grad W_ij
// recomputed from positions and current volumes.
//
// Convention: the shader that gets this file declares its uniform
// parameters as `P` with the kernel fields `support` (H, m), `inv_support`
// (1/H, 1/m) and `kernel_l` (48 / (pi H^4), 1/m^4), as IisphParams and
// DriftParams do (WGSL resolves module-scope names in any order). It must
// not declare grad_over_r, harmonic_volumes or pair_gradient itself.

// W'(r)/r of the cubic spline, 1/m^5 (kernel.rs grad_over_r, the cubic spline shape; the GPU passes run only with it).
fn grad_over_r(r: f32) -> f32 {
    let q = r * P.inv_support;
    let inner = P.kernel_l * (3.0 * q - 2.0) * P.inv_support;
    let om = max(1.0 - q, 0.0);
    let outer = -P.kernel_l * om * om / max(r, 0.5 * P.support);
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
    if (r2 >= P.support * P.support) {
        return vec3<f32>(0.0);
    }
    return (grad_over_r(sqrt(r2)) * d) * harmonic_volumes(vi, vj);
}
