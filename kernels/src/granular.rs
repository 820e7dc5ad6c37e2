//! The SPH elasto-plastic continuum of granular solids (issue 18): the stress of each particle evolves by the Jaumann rate of its
//! velocity gradient and is returned onto the Drucker-Prager cone
//! ([`DruckerPrager::stress_step`]); the momentum equation is the SPH
//! divergence of the stress (Bui et al. 2008, Eqs. 29-33; Monaghan's
//! artificial viscosity, their Eq. 34). Grains have no rest neighbours:
//! every sum runs over the current pairs of the same body and the walls,
//! so the material can flow without limit.
//!
//! With V = m / rho the particle volumes, for particle i of a granular body
//! and its current neighbours j in the same body and walls b:
//!
//!   L_i = sum_j V_j (v_j - v_i) (x) grad_i W_ij + sum_b V_b (v_b - v_i) (x) grad_i W_ib,
//!   m_i dv_i/dt = m_i g + sum_j V_i V_j (S_i + S_j) grad_i W_ij + sum_b V_i V_b (S_i + S_b) grad_i W_ib
//!                 - sum_{j,b} m_i m_j Pi_ij grad_i W_ij,
//!
//! S = sigma - eta p^pore I the total stress of the effective stress sigma
//! (P-Eq. 5's sign convention), Pi_ij = -alpha c h mu_ij / rho_ij for
//! approaching pairs with mu_ij = h v_ij . x_ij / (r^2 + 0.01 h^2).
//!
//! A wall particle is the mirror image of the particle it touches (a
//! ghost, [`Ghost`]): it has the grain's volume and mass, and carries its
//! stress and the mirrored velocity, M(v_i + L_i t_b) with t_b the wall
//! particle's offset along the wall (its mirror point on the grains' side
//! is x_i + t_b for a grain one layer from the wall) and M(u) = -u for a
//! wall without slip (whose friction is then the material's own: the
//! plastic return bounds the shear stress there), M(u) = R u with free
//! slip, R the reflection in the walls the ghost lies behind (the viscous
//! wall force then keeps only its part across them). L_i appears on both
//! sides; [`MIRROR_SWEEPS`] fixed-point sweeps solve for it. Without the
//! L_i t_b part (v_b = M(v_i)) the wall grains missed the walls' share of
//! dv_y/dy as the column settled, and so built up less stress: with the
//! stress mirror below, side-wall columns 0.925 and corners 0.770 against
//! 1.041 inside (7.7 % per particle), with it 0.934, 0.863 and 1.004
//! (6.1 %; both before the edges below). Its stress is the grain's,
//! reflected in the wall with free slip (R S_i R: the shear on the wall
//! changes sign, so the pair carries no tangential traction), plus the
//! weight of the material between them (a lithostatic mirror):
//!
//!   S_b = S_i - rho_i (g . (x_b - x_i)) g g / |g|^2   (R S_i R with free slip),
//!
//! the weight part bounded by the grain's own vertical stress S_vv =
//! g_hat . S_i g_hat: |rho_i g . (x_b - x_i)| <= max(-S_vv, 0), so that the
//! ghost's vertical stress lies between 0 and 2 S_vv. A grain that carries
//! no weight (alone, or at a free surface) gets none from the walls. The
//! upper end is a bound, not the lithostatic value: within two spacings of
//! a free surface a ghost deeper than the grain by more than the grain's
//! depth gets less weight than rho g (its depth) (the column test's top 3 d
//! beside the walls; below them it does not bind).
//! Unbounded, the term pushed every grain up at every wall particle above
//! or beside it (-rho_i (g . r_b)(g_hat . grad W_ib) >= 0 for each), about
//! 0.15 g beside a vertical wall and 0.5 g under a ceiling for a grain
//! without stress, and in Example 7 a grain thrown from the front with two
//! fluid particles rose along the back wall and stayed under the tank's
//! ceiling; bounded, none leaves the columns, and the column at rest below
//! reads 2.2 % instead of 3.6 % (its top layers beside the walls were
//! held up by their ghosts).
//!
//! Without the weight term (S_b = S_i, exact only for a uniform stress) the
//! ghosts carry no vertical stress gradient, so a grain next to a side
//! wall loses the wall's share of the gradient that holds up its weight:
//! measured on a column of sand at rest (d = 2 cm, 10 x 5 columns, 15
//! layers, 5 s) sigma_yy / (rho g depth) was 1.131 in the inner columns,
//! 1.021 next to a side wall and 0.939 in the corners (mean 1.067, 10.6 %
//! per particle): the wall grains hung on their inner neighbours' stress.
//! The floor's ghosts had no weight either, so the stress jumped by 2 rho g
//! d between the first two layers instead of rho g d. Extrapolating the
//! grains' stress onto each wall particle instead (Adami, Hu & Adams 2012,
//! a Shepard mean plus the weight term, with v_b = M(v_i)) left that
//! column moving: 55 mm/s at 5 s, 72 % per particle.
//!
//! Edges and corners. The walls used to be one mirror per grain, across
//! the plane normal to n (the direction of sum_b V0_b grad W_ib), with the
//! walls' rest volumes V0_b as the ghosts' volumes. Both were wrong where a
//! grain touches two walls. Evidence: the column above, its stress set to
//! the lithostatic state (sigma_yy = -rho g depth, sigma_xx = sigma_zz = 0.5
//! sigma_yy) and the step's force evaluated once: every grain away from the
//! edges accelerates by the cubic spline's gradient bias (+0.020 g, up),
//! but the bottom layer's side-wall grains by -3.5 g (down) and 2.8 g
//! (away from the wall), its corner grains by -4.1 g, and every corner
//! column's grains by 0.02-0.52 g into the walls (growing with depth). At a
//! floor edge n is diagonal, and R = I - 2 n n swaps sigma_xx and sigma_yy
//! in the ghost, so the floor carried 1.5 instead of 2 sigma_yy; and along
//! the edges V0_b is 0.85-1.4 h^3, so grains and ghosts did not sum to a
//! full neighbourhood and 2 S_i sum_b V0_b grad W_ib was not balanced. So
//! the released column settled with its wall columns hanging on the inner
//! ones (the 6.1 % above). Now each wall particle is its own ghost,
//! reflected in each wall it lies behind (a floor particle in the floor, an
//! edge particle in both), with the grain's volume: the same lithostatic
//! state then accelerates every grain by the +0.020 g bias (to 0.07 g
//! sideways in the bottom layer's corners; the force evaluated by a copy
//! of these terms, mirrored axis by axis). Measured on that column after
//! 5 s: released from zero stress, 3.6 % per particle (mean 0.967; inside
//! 0.974, side wall 0.964, corner 0.936; max speed 3.0e-4 m/s), and
//! started lithostatic, 2.2 % (0.978 in every column class, the spline's
//! bias: the discrete equilibrium is rho g depth / 1.02); with the weight
//! part bounded as above, 2.2 % released (0.981 / 0.976 / 0.971) and 1.5 %
//! started lithostatic (1 s). The collapse runouts moved from 0.565 /
//! 3.249 to 0.590 / 3.35 (a = 0.5 / 2), bounded 0.561 / 3.175.
//!
//! Tried and not kept, before the edges and corners were mirrored as
//! above: the ghost stress continued along the wall with the
//! grains' own stress gradient, like the velocity, M_S(S_i + (t_b . grad)
//! S) (grad S over grains and ghosts, the same sweeps), and the weight term
//! across the wall only. The column at rest then read 1.007 inside, 0.961
//! at a side wall, 0.949 in the corners (4.4 % per particle at d = 2 cm),
//! but settled more slowly (8.6e-4 m/s at 5 s; its mean ratio swung from
//! 1.30 at 1 s to 0.91 at 3 s and 1.02 at 4 s), 8.7 % at d = 1 cm (mean
//! 0.914, 1.0e-3 m/s at 5 s: not settled), the a = 2 collapse was still
//! at 8.1 mm/s at 1.5 s, and in Example 7 a grain left its tank through a
//! smooth side wall (5.8 mm past its face at 2 s). An extrapolated ghost
//! stress can be tensile, which pulls grains into the wall. Returning it
//! onto the material's cone first (the ghost can carry no more than the
//! grain could): 4.2 % at d = 2 cm (1.017 / 0.968 / 0.957, mean 0.991,
//! 4.2e-4 m/s at 5 s), Example 7 kept its grains in their tanks (fronts
//! 0.175 and 0.205 m), collapse runouts 0.598 (a = 0.5) and 3.103 (a = 2),
//! but the a = 2 column still moved at 19 mm/s at 1.5 s (the collapse
//! test asks under 10 mm/s; 0.1 mm/s with the walls of that time).
//!
//! Slip can be chosen per axis (the smooth side walls of a channel with a
//! rough floor): a ghost behind walls of which one does not slip is the
//! no-slip ghost. Walls are taken to face the coordinate axes, as the
//! per-axis slip already assumed: a slanted wall (a mesh) is mirrored in
//! the axes its normal has a large part along, exact without slip. The mirror velocity, not v_b = 0, is
//! what makes the wall terms of L and of the force adjoint, so that the
//! walls do no work on the grains beyond the stress power: with v_b = 0
//! (measured on a column of sand at rest in a box, d = 2 cm) the column
//! never settled, at an RMS speed of 5-10 mm/s that only the artificial
//! viscosity held down (60 mm/s at alpha = 0.1, 2-3 mm/s at 2), most of it
//! next to the walls; with the mirror it comes to rest (< 1e-5 m/s).
//!
//! A porous granular body's cohesion follows its saturation
//! ([`suction_shape`]): dry and saturated sand hold together by the dry
//! cohesion alone, damp sand by more.
//!
//! Both passes read only the last pass's values and run over the cache
//! blocks of the pair lists, so they are deterministic for any thread count.

use crate::blocks::BLOCK;
use crate::drucker_prager::DruckerPrager;
use crate::neighbors::PairLists;
use glam::{Mat3, Vec3};
use rayon::prelude::*;

/// Fixed-point sweeps of the walls' share of the velocity gradient (their
/// mirror velocity changes along the wall with L itself, module doc); each
/// sweep multiplies the error by the walls' share of the kernel gradient,
/// about 0.14 at a flat wall.
const MIRROR_SWEEPS: usize = 2;

/// `material` of a particle that is not granular.
pub const NOT_GRANULAR: u32 = u32::MAX;

/// A granular material: the cone and the elastic moduli.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub cone: DruckerPrager,
    /// Shear modulus G, Pa.
    pub shear: f32,
    /// Bulk modulus K = lambda + 2 G / 3, Pa.
    pub bulk: f32,
    /// Per axis x, y, z: the walls facing it are frictionless for this
    /// material (else no slip).
    pub free_slip: [bool; 3],
    /// The k_c of the wet cohesion at its largest, Pa (0: no wet cohesion).
    pub wet_k_c: f32,
    /// van Genuchten's n of the wet cohesion law (> 2).
    pub suction_n: f32,
}

/// The wet cohesion law, normalised: the suction stress of Lu & Likos
/// (2006, "Suction stress characteristic curve for unsaturated soil", J.
/// Geotech. Geoenviron. Eng. 132, Eq. 18 with van Genuchten's retention
/// curve), sigma_s = -(S / a) (S^(-n/(n-1)) - 1)^(1/n), divided by its
/// largest value, for the saturation S in [0, 1] (no residual water). With
/// m = n / (n - 1) its largest value is at S* = (1 - m/n)^(1/m) =
/// ((n - 2) / (n - 1))^((n - 1)/n) and is S* (n - 2)^(-1/n) / a. It is 0 for
/// dry (S^(1 - 1/(n-1)) -> 0, which needs n > 2) and saturated (S = 1)
/// pores: no menisci, no suction. The apparent cohesion of the suction
/// stress is -sigma_s tan(phi) (Lu & Likos); a scene gives its largest
/// value, `wet_cohesion`, which folds the retention curve's 1/a and tan(phi)
/// into one number.
pub fn suction_shape(s: f32, n: f32) -> f32 {
    if !(s > 0.0 && s < 1.0) {
        return 0.0;
    }
    let (s, n) = (f64::from(s), f64::from(n));
    let m = n / (n - 1.0);
    let g = |s: f64| s * (s.powf(-m) - 1.0).powf(1.0 / n);
    let s_star = (1.0 - m / n).powf(1.0 / m);
    (g(s) / (s_star * (n - 2.0).powf(-1.0 / n))) as f32
}

impl Material {
    /// The cone at saturation `s` (the wet cohesion law,
    /// [`suction_shape`]).
    #[inline(always)]
    fn cone_at(&self, s: f32) -> DruckerPrager {
        let mut cone = self.cone;
        if self.wet_k_c > 0.0 {
            cone.k_c += self.wet_k_c * suction_shape(s, self.suction_n);
        }
        cone
    }
}

/// The solid particles in the sorted order of the solid pair lists.
#[derive(Clone, Copy)]
pub struct Grains<'a> {
    /// Positions, m.
    pub x: [&'a [f32]; 3],
    /// Body of each particle (sums run within a body).
    pub body: &'a [u32],
    /// Index into the materials, or [`NOT_GRANULAR`].
    pub material: &'a [u32],
    /// Mass, kg.
    pub mass: &'a [f32],
    /// Volume V, m^3.
    pub volume: &'a [f32],
    /// eta p^pore, the pore stress, Pa (0 without).
    pub pore: &'a [f32],
    /// Saturation S = sum_k phi_sk / porosity in [0, 1] (0 without pores).
    pub saturation: &'a [f32],
}

/// The walls the grains touch: their particles' positions, m. Each wall
/// particle near a grain stands for the grain's mirror image (module doc),
/// with the grain's volume, not the wall's rest volume V0_b: V0_b is
/// calibrated for the fluid's density sum (0.85-1.4 h^3 along a
/// container's faces, edges and corners), and with it the grains' and
/// ghosts' gradient sum sum_j V_j grad W_ij + sum_b V_b grad W_ib is not 0
/// at rest, so the mirror term 2 S_i sum_b V_b grad W_ib left a force
/// proportional to the stress (module doc, "Edges and corners").
#[derive(Clone, Copy)]
pub struct Walls<'a> {
    pub x: [&'a [f32]; 3],
}

/// Pairs of the grains: `ss` solid-solid (targets sorted solids), `sb`
/// solid-wall (targets wall indices), both with queries in sorted order.
#[derive(Clone, Copy)]
pub struct Pairs<'a> {
    pub ss: &'a PairLists,
    pub sb: &'a PairLists,
}

/// The unit wall normal at block query `q`, the direction of sum_b grad_i
/// W_ib over its wall pairs (it points into the walls; 0 away from walls).
#[inline(always)]
fn wall_normal(blk: &crate::neighbors::PairBlock, q: usize) -> Vec3 {
    let sum: Vec3 = blk.range(q).map(|p| Vec3::new(blk.gx[p], blk.gy[p], blk.gz[p])).sum();
    sum.normalize_or_zero()
}

/// A component of the wall normal at least this large makes the walls
/// facing that axis a mirror of the grain (a face: one axis; an edge of a
/// box: two; a corner: three).
const FACING: f32 = 0.3;

/// The mirror image of a grain in one wall particle (module doc): reflected
/// across the planes of the walls that the particle lies behind, seen from
/// the grain. Walls are taken to face the coordinate axes (containers and
/// boxes; the per-axis `free_slip` assumes the same): a wall particle at
/// offset r = x_b - x_i lies behind the walls facing axis a if the wall
/// normal n has a component along a of at least [`FACING`] and r reaches
/// more than h/2 past the grain along it. Behind one face the ghost is the
/// grain reflected in that face; behind an edge or corner, reflected in
/// each of its faces.
#[derive(Clone, Copy)]
struct Ghost {
    /// The axes it is reflected across.
    axes: [bool; 3],
    /// Whether every wall it is reflected in slips (else it is the no-slip
    /// ghost, whose velocity is -v_i and whose stress is S_i).
    slips: bool,
}

impl Ghost {
    /// The ghost's class: bit a set if it is reflected across axis a, for
    /// a wall particle at offset `r` from a grain with wall normal `n`.
    #[inline(always)]
    fn class(n: Vec3, r: Vec3, h: f32) -> usize {
        (0..3).filter(|&a| n[a].abs() >= FACING && r[a] * n[a].signum() > 0.5 * h).map(|a| 1 << a).sum()
    }

    /// The ghost of class `c` ([`Self::class`]) of material `m`.
    #[inline(always)]
    fn of(c: usize, m: &Material) -> Self {
        let axes = [0, 1, 2].map(|a| c & (1 << a) != 0);
        let slips = (0..3).all(|a| !axes[a] || m.free_slip[a]);
        Ghost { axes, slips }
    }

    /// [`Self::velocity`] as a matrix.
    #[inline(always)]
    fn velocity_map(&self) -> Mat3 {
        if self.slips {
            Mat3::from_diagonal(self.signs())
        } else {
            -Mat3::IDENTITY
        }
    }

    /// [`Self::along`] as a matrix.
    #[inline(always)]
    fn along_map(&self) -> Mat3 {
        Mat3::from_diagonal(self.along(Vec3::ONE))
    }

    /// +-1 per axis: -1 on the axes it is reflected across.
    #[inline(always)]
    fn signs(&self) -> Vec3 {
        Vec3::from_array(self.axes.map(|on| if on { -1.0 } else { 1.0 }))
    }

    /// The mirror of a velocity (or a velocity difference): -u without slip,
    /// u with its components across the reflecting walls negated with slip.
    #[inline(always)]
    fn velocity(&self, u: Vec3) -> Vec3 {
        if self.slips {
            u * self.signs()
        } else {
            -u
        }
    }

    /// The mirror of a stress: R S R with R the reflections (the shear on
    /// each reflecting wall changes sign, so the pair carries no tangential
    /// traction there), S itself without slip.
    #[inline(always)]
    fn stress(&self, s: Mat3) -> Mat3 {
        if self.slips {
            let r = self.signs();
            Mat3::from_cols(s.x_axis * r * r.x, s.y_axis * r * r.y, s.z_axis * r * r.z)
        } else {
            s
        }
    }

    /// The part of `r` along the reflecting walls (its offset along them).
    #[inline(always)]
    fn along(&self, r: Vec3) -> Vec3 {
        Vec3::from_array([0, 1, 2].map(|a| if self.axes[a] { 0.0 } else { r[a] }))
    }

    /// The part of `f` across the reflecting walls (what a slipping wall
    /// can exert).
    #[inline(always)]
    fn across(&self, f: Vec3) -> Vec3 {
        f - self.along(f)
    }
}

#[inline(always)]
fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The stress of every granular particle advanced by `dt` from its velocity
/// gradient at the velocities `v` (Jaumann rate and return,
/// [`DruckerPrager::stress_step`]); `plastic` accumulates the plastic
/// multipliers (the plastic shear strain). Others are left alone.
#[allow(clippy::too_many_arguments)]
pub fn stress_update(
    pairs: Pairs,
    grains: Grains,
    walls: Walls,
    materials: &[Material],
    v: &[Vec3],
    sigma: &mut [Mat3],
    plastic: &mut [f32],
    dt: f32,
) {
    let (ss, sb) = (pairs.ss.used(), pairs.sb.used());
    sigma.par_chunks_mut(BLOCK).zip(plastic.par_chunks_mut(BLOCK)).enumerate().for_each(|(b, (sig, pl))| {
        for (q, (s, ep)) in sig.iter_mut().zip(pl.iter_mut()).enumerate() {
            let i = b * BLOCK + q;
            let Some(m) = materials.get(grains.material[i] as usize) else { continue };
            let mut l = Mat3::ZERO;
            let blk = &ss[b];
            for p in blk.range(q) {
                let j = blk.j[p] as usize;
                if j != i && grains.body[j] == grains.body[i] {
                    let g = Vec3::new(blk.gx[p], blk.gy[p], blk.gz[p]);
                    l += outer(grains.volume[j] * (v[j] - v[i]), g);
                }
            }
            // The walls' mirror velocity (module doc): the ghost's
            // velocity M(v_i), plus the mirrored change of v along the
            // wall, M(L t_b); the ghost has the grain's volume.
            let blk = &sb[b];
            if !walls.x[0].is_empty() && !blk.range(q).is_empty() {
                let vol = grains.volume[i];
                let h = vol.cbrt();
                let n = wall_normal(blk, q);
                let xi = Vec3::new(grains.x[0][i], grains.x[1][i], grains.x[2][i]);
                // The wall pairs summed by ghost class: sum_b grad W_ib
                // and sum_b r_b (x) grad W_ib, r_b = x_b - x_i, so that
                // the sweeps below need no pass over the pairs
                // (sum_b M(L t_b) (x) grad W_ib = M L P sum_b r_b (x) grad
                // W_ib, with M and P the class's mirror and projection
                // along the walls).
                let mut gsum = [Vec3::ZERO; 8];
                let mut rg = [Mat3::ZERO; 8];
                for p in blk.range(q) {
                    let k = blk.j[p] as usize;
                    let r = Vec3::new(walls.x[0][k], walls.x[1][k], walls.x[2][k]) - xi;
                    let g = Vec3::new(blk.gx[p], blk.gy[p], blk.gz[p]);
                    let c = Ghost::class(n, r, h);
                    gsum[c] += g;
                    rg[c] += outer(r, g);
                }
                let mut maps = [(Mat3::ZERO, Mat3::ZERO); 8];
                for c in (0..8).filter(|&c| gsum[c] != Vec3::ZERO || rg[c] != Mat3::ZERO) {
                    let gh = Ghost::of(c, m);
                    l += outer(vol * (gh.velocity(v[i]) - v[i]), gsum[c]);
                    maps[c] = (vol * gh.velocity_map(), gh.along_map() * rg[c]);
                }
                let l_mirror = l;
                let mut lt = l;
                for _ in 0..MIRROR_SWEEPS {
                    let mut extra = Mat3::ZERO;
                    for c in (0..8).filter(|&c| rg[c] != Mat3::ZERO) {
                        let (mv, pr) = maps[c];
                        extra += mv * lt * pr;
                    }
                    lt = l_mirror + extra;
                }
                l = lt;
            }
            let (next, d_lambda, _) = m.cone_at(grains.saturation[i]).stress_step(*s, l, dt, m.shear, m.bulk);
            *s = next;
            *ep += d_lambda;
        }
    });
}

/// Monaghan's viscous term m_i m_j Pi_ij for a pair at `xij` = x_i - x_j with
/// relative velocity `vij`, `c` the sound speed, `rho` the pair's mean
/// density (0 for receding pairs).
#[inline(always)]
fn viscous(alpha: f32, c: f32, h: f32, rho: f32, xij: Vec3, vij: Vec3) -> f32 {
    let vx = vij.dot(xij);
    if vx >= 0.0 {
        return 0.0;
    }
    let mu = h * vx / (xij.length_squared() + 0.01 * h * h);
    -alpha * c * mu / rho
}

/// Artificial viscosity of the granular momentum equation: alpha (Bui et
/// al. 2008 use 0.1 to 1) and the sound speed of each material.
#[derive(Clone, Copy, Debug)]
pub struct Viscosity<'a> {
    pub alpha: f32,
    /// sqrt((K + 4 G / 3) / rho) of each material, m/s.
    pub sound_speed: &'a [f32],
    /// Smoothing length h of the pair term (the particle spacing), m.
    pub h: f32,
}

/// The velocities `v_out` after `dt` of every granular particle that is not
/// `fixed`, from `v` under gravity `g`, the stress divergence and the
/// artificial viscosity (module doc); other particles copy `v`.
#[allow(clippy::too_many_arguments)]
pub fn accelerate(
    pairs: Pairs,
    grains: Grains,
    walls: Walls,
    fixed: &[u32],
    materials: &[Material],
    sigma: &[Mat3],
    visc: Viscosity,
    v: &[Vec3],
    v_out: &mut [Vec3],
    g: Vec3,
    dt: f32,
) {
    let (ss, sb) = (pairs.ss.used(), pairs.sb.used());
    let pos = |x: [&[f32]; 3], i: usize| Vec3::new(x[0][i], x[1][i], x[2][i]);
    let g_hat = g.normalize_or_zero();
    v_out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
        for (q, o) in out.iter_mut().enumerate() {
            let i = b * BLOCK + q;
            *o = v[i];
            let mat = grains.material[i] as usize;
            if mat >= visc.sound_speed.len() || fixed[i] != 0 {
                continue;
            }
            let c = visc.sound_speed[mat];
            let (mi, vi, xi) = (grains.mass[i], grains.volume[i], pos(grains.x, i));
            let rho_i = mi / vi;
            let si = sigma[i] - Mat3::from_diagonal(Vec3::splat(grains.pore[i]));
            let mut f = Vec3::ZERO;
            let blk = &ss[b];
            for p in blk.range(q) {
                let j = blk.j[p] as usize;
                if j == i || grains.body[j] != grains.body[i] {
                    continue;
                }
                let gw = Vec3::new(blk.gx[p], blk.gy[p], blk.gz[p]);
                let sj = sigma[j] - Mat3::from_diagonal(Vec3::splat(grains.pore[j]));
                f += vi * grains.volume[j] * ((si + sj) * gw);
                let rho = 0.5 * (rho_i + grains.mass[j] / grains.volume[j]);
                let pi = viscous(visc.alpha, c, visc.h, rho, xi - pos(grains.x, j), v[i] - v[j]);
                f -= mi * grains.mass[j] * pi * gw;
            }
            // The walls are the particle's lithostatic mirror (module doc),
            // with the grain's volume and mass; their mirror velocity enters
            // the viscosity (with slip: its part across the wall only).
            let blk = &sb[b];
            let (mut fw, mut fv) = (Vec3::ZERO, Vec3::ZERO);
            if !walls.x[0].is_empty() && !blk.range(q).is_empty() {
                let n = wall_normal(blk, q);
                let m = &materials[mat];
                // S_b = M(S_i) - rho_i (g . (x_b - x_i)) g g / |g|^2: the
                // weight part per pair, the mirror part by ghost class. The
                // weight part is bounded by the grain's own vertical stress
                // (module doc): the ghost's lies between 0 and twice it.
                let mut gsum = [Vec3::ZERO; 8];
                let mut weight = 0.0;
                let cap = (-g_hat.dot(si * g_hat)).max(0.0);
                for p in blk.range(q) {
                    let k = blk.j[p] as usize;
                    let gw = Vec3::new(blk.gx[p], blk.gy[p], blk.gz[p]);
                    let xb = pos(walls.x, k);
                    let cls = Ghost::class(n, xb - xi, visc.h);
                    let gh = Ghost::of(cls, m);
                    gsum[cls] += gw;
                    weight += (-rho_i * g.dot(xb - xi)).clamp(-cap, cap) * g_hat.dot(gw);
                    let pi = viscous(visc.alpha, c, visc.h, rho_i, xi - xb, v[i] - gh.velocity(v[i]));
                    let fk = -mi * mi * pi * gw;
                    fv += if gh.slips { gh.across(fk) } else { fk };
                }
                for (cls, gw) in gsum.iter().enumerate().filter(|(_, gw)| **gw != Vec3::ZERO) {
                    fw += (si + Ghost::of(cls, m).stress(si)) * *gw;
                }
                fw = vi * vi * (fw + weight * g_hat);
            }
            *o = v[i] + dt * (g + (f + fw + fv) / mi);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::suction_shape;

    /// The wet cohesion law against Lu & Likos' closed form: 0 when dry and
    /// when saturated, 1 at its peak S* = ((n - 2) / (n - 1))^((n - 1) / n)
    /// and below 1 elsewhere; at other S the ratio of their Eq. 18 to its
    /// peak, computed here independently (f64, a fine scan for the peak).
    #[test]
    fn suction_shape_is_lu_and_likos_normalised() {
        for n in [2.5f64, 4.0, 8.0] {
            let sigma_s = |s: f64| s * (s.powf(-n / (n - 1.0)) - 1.0).powf(1.0 / n);
            let peak = (1..100_000).map(|k| sigma_s(k as f64 / 100_000.0)).fold(0.0, f64::max);
            let s_star = ((n - 2.0) / (n - 1.0)).powf((n - 1.0) / n);
            assert!((f64::from(suction_shape(s_star as f32, n as f32)) - 1.0).abs() < 1e-5, "n {n}");
            for s in [0.05, 0.2, 0.5, 0.9, 0.99] {
                let want = sigma_s(s) / peak;
                let got = f64::from(suction_shape(s as f32, n as f32));
                assert!((got - want).abs() < 1e-5, "n {n}, S {s}: {got} vs {want}");
                assert!(got < 1.0);
            }
            assert_eq!(suction_shape(0.0, n as f32), 0.0);
            assert_eq!(suction_shape(1.0, n as f32), 0.0);
            assert!(suction_shape(1e-6, n as f32) < 0.05, "dry: {}", suction_shape(1e-6, n as f32));
        }
    }
}
