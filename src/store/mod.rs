//! The particle store: struct of arrays, fluid and wall particles apart.
//!
//! Every array that persists across steps lives here and is declared once in
//! a `soa!` block, which also generates the field registry
//! ([`FluidStore::for_each_column_mut`] and friends). The Morton sort's one
//! [`FluidStore::reorder`] moves every registered array, and checkpoints save
//! every registered array, so a field added later is sorted and saved with
//! no extra code. Scratch that lives for one step comes from the pipeline's
//! arena, not from here.

mod reorder;

pub use reorder::Scratch;

/// A registered column, read-only.
pub enum Column<'a> {
    F32(&'a [f32]),
    U32(&'a [u32]),
    /// One array per phase k (component-major: `[k][i]`).
    PerPhase(&'a [Vec<f32>]),
}

/// A registered column, mutable.
pub enum ColumnMut<'a> {
    F32(&'a mut Vec<f32>),
    U32(&'a mut Vec<u32>),
    PerPhase(&'a mut Vec<Vec<f32>>),
}

macro_rules! soa {
    ($(#[$m:meta])* pub struct $name:ident { $( $(#[$fm:meta])* $f:ident : $t:ty [$unit:literal] ),* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct $name { $( $(#[$fm])* pub $f: $t, )* }

        impl $name {
            /// Visits every registered array with its name and unit.
            pub fn for_each_column(&self, mut f: impl FnMut(&'static str, &'static str, Column<'_>)) {
                $( f(stringify!($f), $unit, soa!(@col &self.$f)); )*
            }

            /// Visits every registered array mutably with its name and unit.
            pub fn for_each_column_mut(&mut self, mut f: impl FnMut(&'static str, &'static str, ColumnMut<'_>)) {
                $( f(stringify!($f), $unit, soa!(@colmut &mut self.$f)); )*
            }

            /// Number of particles (every store has positions `x`).
            pub fn len(&self) -> usize {
                self.x.len()
            }

            /// Whether the store is empty.
            pub fn is_empty(&self) -> bool {
                self.x.is_empty()
            }

            /// Moves every registered array by `perm` (`new[i] = old[perm[i]]`).
            pub fn reorder(&mut self, perm: &[u32], scratch: &mut Scratch) {
                self.for_each_column_mut(|_, _, c| scratch.permute(c, perm));
            }

            /// Bytes held by the registered arrays.
            pub fn bytes(&self) -> usize {
                let mut b = 0;
                self.for_each_column(|_, _, c| b += column_bytes(&c));
                b
            }
        }
    };
    (@col $e:expr) => { IntoColumn::column($e) };
    (@colmut $e:expr) => { IntoColumn::column_mut($e) };
}

/// The column view of a field type.
pub trait IntoColumn {
    fn column(&self) -> Column<'_>;
    fn column_mut(&mut self) -> ColumnMut<'_>;
}

impl IntoColumn for Vec<f32> {
    fn column(&self) -> Column<'_> {
        Column::F32(self)
    }
    fn column_mut(&mut self) -> ColumnMut<'_> {
        ColumnMut::F32(self)
    }
}

impl IntoColumn for Vec<u32> {
    fn column(&self) -> Column<'_> {
        Column::U32(self)
    }
    fn column_mut(&mut self) -> ColumnMut<'_> {
        ColumnMut::U32(self)
    }
}

impl IntoColumn for Vec<Vec<f32>> {
    fn column(&self) -> Column<'_> {
        Column::PerPhase(self)
    }
    fn column_mut(&mut self) -> ColumnMut<'_> {
        ColumnMut::PerPhase(self)
    }
}

soa! {
    /// Persistent state of the fluid (mixture) particles, in Morton order.
    pub struct FluidStore {
        /// Position x, m.
        x: Vec<f32> ["m"],
        /// Position y, m.
        y: Vec<f32> ["m"],
        /// Position z, m.
        z: Vec<f32> ["m"],
        /// Mixture velocity u_m, x, m/s.
        ux: Vec<f32> ["m/s"],
        /// Mixture velocity u_m, y, m/s.
        uy: Vec<f32> ["m/s"],
        /// Mixture velocity u_m, z, m/s.
        uz: Vec<f32> ["m/s"],
        /// IISPH pressure p, Pa (the next step warm-starts from half of it, or
        /// from that and half a hydrostatic estimate,
        /// `porosph_kernels::hydrostatic`).
        pressure: Vec<f32> ["Pa"],
        /// Density m / V of the last step, kg/m^3 (output only).
        density: Vec<f32> ["kg/m^3"],
        /// Outer volume fraction alpha_k of each phase (P-Eq. 6).
        alpha: Vec<Vec<f32>> [""],
        /// Inner volume fraction beta_k of each phase, the part of the
        /// particle inside a porous solid (P-Eq. 7); sum_k (alpha_k +
        /// beta_k) = 1.
        beta: Vec<Vec<f32>> [""],
        /// The part of each alpha_k that f32 cannot hold: the fraction is
        /// alpha_k + alpha_lo_k (`porosph_kernels::phases::join`, which says
        /// why); every pass reads alpha_k, the passes that move fractions
        /// keep both.
        alpha_lo: Vec<Vec<f32>> [""],
        /// The same for beta_k.
        beta_lo: Vec<Vec<f32>> [""],
        /// Stable particle id.
        id: Vec<u32> [""],
    }
}

impl FluidStore {
    /// Outer and inner volume of each phase, `cell` times the sums over the
    /// particles of alpha_k + alpha_lo_k and of beta_k + beta_lo_k (f64, in
    /// particle order), m^3 for `cell` = h^3.
    pub fn phase_volumes(&self, cell: f64) -> (Vec<f64>, Vec<f64>) {
        let sum = |(hi, lo): (&Vec<f32>, &Vec<f32>)| {
            cell * hi.iter().zip(lo).map(|(&h, &l)| f64::from(h) + f64::from(l)).sum::<f64>()
        };
        (
            self.alpha.iter().zip(&self.alpha_lo).map(sum).collect(),
            self.beta.iter().zip(&self.beta_lo).map(sum).collect(),
        )
    }
}

soa! {
    /// Static wall (boundary) particles, in Morton order. Walls take part in
    /// the pressure solve (pressure boundaries, PHYSICS.md §2.3).
    pub struct WallStore {
        /// Position x, m.
        x: Vec<f32> ["m"],
        /// Position y, m.
        y: Vec<f32> ["m"],
        /// Position z, m.
        z: Vec<f32> ["m"],
        /// Rest volume V0_b, m^3.
        rest_volume: Vec<f32> ["m^3"],
        /// sum over wall neighbours b' (incl. self) of V0_b' W_bb'; constant.
        sigma_static: Vec<f32> [""],
        /// Pressure p_b of the pressure boundary, Pa (0 where no fluid is near).
        pressure: Vec<f32> ["Pa"],
        /// rho_ref V0/V, the density seen at the wall, kg/m^3 (output only).
        density: Vec<f32> ["kg/m^3"],
        /// Stable particle id (after the fluid ids).
        id: Vec<u32> [""],
    }
}

soa! {
    /// Elastic solid particles (PHYSICS.md §3), in the order they were
    /// sampled (body by body, lattice order). Solids are not reordered: their
    /// rest neighbourhoods (SS0) are fixed lists over this order, and the
    /// pressure solve reads them through a sorted copy (the pipeline's
    /// workspace).
    pub struct SolidStore {
        /// Position x, m.
        x: Vec<f32> ["m"],
        /// Position y, m.
        y: Vec<f32> ["m"],
        /// Position z, m.
        z: Vec<f32> ["m"],
        /// Velocity v, x, m/s.
        vx: Vec<f32> ["m/s"],
        /// Velocity v, y, m/s.
        vy: Vec<f32> ["m/s"],
        /// Velocity v, z, m/s.
        vz: Vec<f32> ["m/s"],
        /// Rest position x0, x, m.
        x0: Vec<f32> ["m"],
        /// Rest position x0, y, m.
        y0: Vec<f32> ["m"],
        /// Rest position x0, z, m.
        z0: Vec<f32> ["m"],
        /// Mass m_s, kg.
        mass: Vec<f32> ["kg"],
        /// Index of the body (`[[solid]]` entry).
        body: Vec<u32> [""],
        /// 1 where the velocity is prescribed (the body's `fixed` shape).
        fixed: Vec<u32> [""],
        /// Rotation R_i as a unit quaternion (x), the warm start of the next
        /// rotation extraction (PHYSICS.md §3.2).
        qx: Vec<f32> [""],
        /// Rotation quaternion, y.
        qy: Vec<f32> [""],
        /// Rotation quaternion, z.
        qz: Vec<f32> [""],
        /// Rotation quaternion, w.
        qw: Vec<f32> [""],
        /// Pressure p_s of the pressure boundary, Pa (the next step
        /// warm-starts from half of it).
        pressure: Vec<f32> ["Pa"],
        /// Von Mises stress of the last step, Pa (output only).
        stress: Vec<f32> ["Pa"],
        /// tr(eps) of the corotated strain of the last step (output only).
        strain_trace: Vec<f32> [""],
        /// sum_k phi_sk, the absorbed volume ratio of the last step (P-Eq. 15;
        /// output only).
        saturation: Vec<f32> [""],
        /// Pore pressure p^pore of the last step, Pa (P-Eq. 9; output only).
        pore_pressure: Vec<f32> ["Pa"],
        /// Effective Cauchy stress of a granular particle, xx (tension
        /// positive; its state, which the next step continues; 0 on
        /// elastic particles), Pa.
        sxx: Vec<f32> ["Pa"],
        /// Granular stress, yy, Pa.
        syy: Vec<f32> ["Pa"],
        /// Granular stress, zz, Pa.
        szz: Vec<f32> ["Pa"],
        /// Granular stress, xy, Pa.
        sxy: Vec<f32> ["Pa"],
        /// Granular stress, xz, Pa.
        sxz: Vec<f32> ["Pa"],
        /// Granular stress, yz, Pa.
        syz: Vec<f32> ["Pa"],
        /// Accumulated plastic shear strain of a granular particle, the sum
        /// of its plastic multipliers (0 on elastic particles).
        plastic_strain: Vec<f32> [""],
        /// Stable particle id (after the fluid and wall ids).
        id: Vec<u32> [""],
    }
}

impl SolidStore {
    /// The granular stress of particle `i` (symmetric), Pa.
    pub fn granular_stress(&self, i: usize) -> glam::Mat3 {
        let (xy, xz, yz) = (self.sxy[i], self.sxz[i], self.syz[i]);
        glam::Mat3::from_cols(
            glam::Vec3::new(self.sxx[i], xy, xz),
            glam::Vec3::new(xy, self.syy[i], yz),
            glam::Vec3::new(xz, yz, self.szz[i]),
        )
    }

    /// Sets the granular stress of particle `i` from a symmetric `sigma`.
    pub fn set_granular_stress(&mut self, i: usize, sigma: glam::Mat3) {
        (self.sxx[i], self.syy[i], self.szz[i]) = (sigma.x_axis.x, sigma.y_axis.y, sigma.z_axis.z);
        (self.sxy[i], self.sxz[i], self.syz[i]) = (sigma.x_axis.y, sigma.x_axis.z, sigma.y_axis.z);
    }
}

fn column_bytes(c: &Column) -> usize {
    match c {
        Column::F32(v) => 4 * v.len(),
        Column::U32(v) => 4 * v.len(),
        Column::PerPhase(v) => v.iter().map(|a| 4 * a.len()).sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reorder_moves_every_registered_array() {
        let mut s = FluidStore {
            x: vec![0.0, 1.0, 2.0],
            y: vec![10.0, 11.0, 12.0],
            alpha: vec![vec![0.1, 0.2, 0.3], vec![0.9, 0.8, 0.7]],
            beta: vec![vec![0.0; 3], vec![0.0; 3]],
            alpha_lo: vec![vec![1e-9, 2e-9, 3e-9], vec![0.0; 3]],
            beta_lo: vec![vec![0.0; 3], vec![0.0; 3]],
            id: vec![5, 6, 7],
            ..Default::default()
        };
        // Fill the rest so every column has 3 entries.
        s.for_each_column_mut(|_, _, c| {
            if let ColumnMut::F32(v) = c {
                if v.is_empty() {
                    v.extend([100.0, 101.0, 102.0]);
                }
            }
        });
        let mut scratch = Scratch::default();
        s.reorder(&[2, 0, 1], &mut scratch);
        assert_eq!(s.x, vec![2.0, 0.0, 1.0]);
        assert_eq!(s.y, vec![12.0, 10.0, 11.0]);
        assert_eq!(s.alpha[1], vec![0.7, 0.9, 0.8]);
        assert_eq!(s.alpha_lo[0], vec![3e-9, 1e-9, 2e-9]);
        assert_eq!(s.id, vec![7, 5, 6]);
        assert_eq!(s.pressure, vec![102.0, 100.0, 101.0]);
        let mut names = Vec::new();
        s.for_each_column(|n, _, _| names.push(n));
        assert!(names.contains(&"pressure") && names.contains(&"alpha") && names.len() == 13);
    }
}
