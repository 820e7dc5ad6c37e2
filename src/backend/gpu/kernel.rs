//! The smoothing kernel of the GPU passes (`shaders/common_kernel.wgsl`,
//! the twin of `grad_over_r` in `kernels/src/kernel.rs`): its shape and
//! constants, taken from the scene's [`Kernel`] (one source of truth), in
//! the uniform parameters of every shader that recomputes g_ij.

use bytemuck::{Pod, Zeroable};
use porosph_kernels::kernel::{Kernel, KernelShape};

/// `struct KernelParams` of `shaders/common_kernel.wgsl`, a field of the
/// uniform parameters of `iisph.wgsl` and `drift.wgsl`; a test checks that
/// the layouts match.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct KernelParams {
    /// The shape: [`CUBIC_SPLINE`] or [`WENDLAND_C2`].
    pub shape: u32,
    /// Support radius H, m.
    pub support: f32,
    /// 1 / H, 1/m.
    pub inv_support: f32,
    /// The gradient's constant l ([`Kernel::grad_scale`]), 1/m^4.
    pub grad_scale: f32,
}

/// `shape` of the cubic spline (`KERNEL_CUBIC_SPLINE` in the WGSL).
pub const CUBIC_SPLINE: u32 = 0;
/// `shape` of Wendland C2 (`KERNEL_WENDLAND_C2` in the WGSL).
pub const WENDLAND_C2: u32 = 1;

impl From<&Kernel> for KernelParams {
    fn from(kernel: &Kernel) -> Self {
        Self {
            shape: match kernel.shape {
                KernelShape::CubicSpline => CUBIC_SPLINE,
                KernelShape::WendlandC2 => WENDLAND_C2,
            },
            support: kernel.support,
            inv_support: kernel.inv_support(),
            grad_scale: kernel.grad_scale(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cubic spline's constants are bitwise those the GPU passes had
    /// when the host computed them itself (before issue 37), so spline runs
    /// on the GPU do not change; Wendland's are the kernels crate's.
    #[test]
    fn constants_come_from_the_kernel() {
        use std::f32::consts::PI;
        let h = 0.02f32;
        let p = KernelParams::from(&Kernel::new(h));
        let old = KernelParams {
            shape: CUBIC_SPLINE,
            support: h,
            inv_support: 1.0 / h,
            grad_scale: 48.0 / (PI * h * h * h * h),
        };
        assert_eq!(bytemuck::bytes_of(&p), bytemuck::bytes_of(&old));
        let w = Kernel::with_shape(KernelShape::WendlandC2, h);
        let p = KernelParams::from(&w);
        assert_eq!((p.shape, p.support, p.grad_scale), (WENDLAND_C2, h, w.grad_scale()));
        // -l (1-q)^3 at q = 1/2 is the CPU's grad_over_r there.
        assert_eq!(-p.grad_scale * 0.125, w.grad_over_r(0.5 * h));
    }
}
