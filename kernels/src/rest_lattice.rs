//! The rest pairs of bodies sampled on a lattice, as a stencil: the elastic
//! product (M A) v of PHYSICS.md §3.3 with SIMD lanes over particles.
//!
//! Every elastic body of a scene is sampled at rest on a lattice of
//! spacing d (boxes, spheres, cylinders, meshes filled cell by cell), so
//! the rest neighbours j of particle i lie at a fixed set of lattice
//! offsets. With each body's particles in the slots of its lattice box (x
//! fastest, empty where the body has no particle), the neighbour at offset
//! o of slot s is slot s + o: the product's two gathers over the pair list
//! (one particle at a time, one 16-byte register a pair) become loads of
//! [`LANES`] consecutive slots, [`LANES`] particles a register. w_ij is 0
//! where a particle has no rest neighbour at an offset (its surface, the
//! box's empty slots), and the empty slots hold 0, so every slot runs the
//! same loop.
//!
//! The w_ij are the pair list's 16-bit ones ([`RestState`]), in the same
//! unit, so the product is the pair list's to the rounding of the sums'
//! order (`elasticity::tests::lattice_apply_is_the_pair_apply_to_rounding`).
//! A scene with a body that is not on a lattice (or mostly empty in its
//! box) keeps the pair list's product for all bodies.
//!
//! Every slot loads every offset, so a NaN or infinity in one particle's v
//! reaches, through the products with w = 0, slots that are not its rest
//! neighbours (the pair list spreads it along pairs only). Either way the
//! solve's dot products take it to every particle at the next iteration,
//! and the step reports the non-finite velocities.

use crate::elasticity::{Lame, RestState, System};
use crate::lanes::{load, F, LANES};
use glam::Vec3;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use wide::{i16x16, i32x16};

/// A slot that holds no particle.
const EMPTY: u32 = u32::MAX;

/// A chunk of slots outside every box (the guards).
const NO_BOX: u32 = u32::MAX;

/// A chunk whose w are its box's template.
const TEMPLATE: u32 = u32::MAX;

/// The most offsets a body's stencil may have (26 on a lattice with the
/// support 2 d); a body with more is not treated as a lattice.
const MAX_OFFSETS: usize = 64;

/// A body's box of slots is at most this many times its particles.
const MAX_FILL_RATIO: usize = 4;

/// One body's lattice box.
#[derive(Clone, Debug)]
struct LatticeBox {
    /// Slot of the box's first cell (a multiple of [`LANES`]).
    first: usize,
    /// Slots of the box, rounded up to a multiple of [`LANES`].
    len: usize,
    /// Slot offsets of the rest neighbours, ascending.
    offsets: Vec<isize>,
    /// The box's most common w_ij pattern (3 K integers as f32, offset
    /// by offset): a chunk whose every slot has it reads it from here
    /// instead of from [`RestLattice::wq`] (the interior of a lattice body,
    /// where every particle has the same neighbours and volumes).
    template: Vec<f32>,
}

/// The solids' rest pairs as lattice stencils (module doc).
#[derive(Clone, Debug, Default)]
pub struct RestLattice {
    /// The particles of bodies without rest pairs (no slot).
    loose: Vec<u32>,
    /// Slot of each particle (0 for the loose ones).
    slot: Vec<u32>,
    /// Particle of each slot, [`EMPTY`] where there is none.
    particle: Vec<u32>,
    /// The box of each chunk of [`LANES`] slots, [`NO_BOX`] for the guards.
    chunk_box: Vec<u32>,
    /// Where each chunk's w starts in [`RestLattice::wq`], [`TEMPLATE`]
    /// for the chunks of their box's template.
    chunk_w: Vec<u32>,
    boxes: Vec<LatticeBox>,
    /// V_i0 w_ij in units of U (the pair list's integers) of the chunks
    /// that are not their box's template: offset k, component c and lane
    /// l of the chunk at `chunk_w + (3 k + c) LANES + l` (K offsets; a
    /// chunk's w in one stream: with a stream an offset and component, 78
    /// of them, the loads waited on memory); 0 where there is no pair.
    wq: Vec<i16>,
    /// s_i = sum_j w_ij of each slot's particle, one array a component.
    wsum: Vec<f32>,
    /// V_i0 of each slot's particle; 1 where empty (any finite value: an
    /// empty slot's sums are 0, and its unit U / V must be finite).
    volume: Vec<f32>,
    /// The unit U of the integers (w_ij = q_ij U / V_i0).
    w_scale: f32,
}

impl RestLattice {
    /// The stencils of `rest`'s pairs, `body` the body of each particle;
    /// `None` unless every body with rest pairs lies on a lattice: its
    /// rest positions within a quarter of its spacing (the smallest
    /// rest-pair distance) of the lattice points counted from its first
    /// particle, no two at one point, at most [`MAX_OFFSETS`] distinct
    /// pair offsets and a box at most [`MAX_FILL_RATIO`] times its
    /// particles. The product does not depend on the positions beyond
    /// that (any distinct slots give the same sums); the lattice only
    /// keeps the offsets few and the boxes full. The quarter leaves room
    /// for the f32 rounding of the spacing, which grows with the distance
    /// from the first particle (about 1.6e-3 of d at 200 spacings). Bodies
    /// without rest pairs (a granular particle, its own group) get no box:
    /// their rows are m_i v_i.
    pub fn new(rest: &RestState, body: &[u32]) -> Option<RestLattice> {
        let n = rest.len();
        if n == 0 || body.len() != n {
            return None;
        }
        let x0 = rest.x0();
        let mut members: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        for (i, &b) in body.iter().enumerate() {
            members.entry(b).or_default().push(i as u32);
        }
        // Lattice coordinates of every particle, the boxes' shapes.
        let mut cell = vec![[0i64; 3]; n];
        let mut shapes = Vec::new();
        let mut loose = Vec::new();
        members.retain(|_, list| {
            let paired = list.iter().any(|&i| !rest.range(i as usize).is_empty());
            if !paired {
                loose.extend_from_slice(list);
            }
            paired
        });
        for list in members.values() {
            let d = list
                .iter()
                .flat_map(|&i| rest.range(i as usize).map(move |p| (i as usize, rest.j()[p] as usize)))
                .map(|(i, j)| (x0[j] - x0[i]).length())
                .fold(f32::INFINITY, f32::min);
            if !(d.is_finite() && d > 0.0) {
                return None;
            }
            let origin = x0[list[0] as usize].as_dvec3();
            let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
            for &i in list {
                let f = (x0[i as usize].as_dvec3() - origin) / f64::from(d);
                let c = f.round();
                if (f - c).abs().max_element() > 0.25 {
                    return None;
                }
                let c = [c.x as i64, c.y as i64, c.z as i64];
                for a in 0..3 {
                    lo[a] = lo[a].min(c[a]);
                    hi[a] = hi[a].max(c[a]);
                }
                cell[i as usize] = c;
            }
            let dims: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a] + 1) as usize);
            let cells = dims[0].checked_mul(dims[1])?.checked_mul(dims[2])?;
            if cells > MAX_FILL_RATIO * list.len() + 64 {
                return None;
            }
            shapes.push((lo, dims, cells));
        }
        let local = |c: [i64; 3], lo: [i64; 3], dims: [usize; 3]| -> usize {
            (c[0] - lo[0]) as usize + dims[0] * ((c[1] - lo[1]) as usize + dims[1] * (c[2] - lo[2]) as usize)
        };
        let offset = |dc: [i64; 3], dims: [usize; 3]| -> isize {
            dc[0] as isize + dims[0] as isize * (dc[1] as isize + dims[1] as isize * dc[2] as isize)
        };
        // Each box's offsets; the guard in front of and behind all boxes
        // covers the largest, so every load s + o stays in the slots.
        let mut offsets_of = Vec::new();
        let mut guard = 0usize;
        for (list, &(_, dims, _)) in members.values().zip(&shapes) {
            let mut set = BTreeSet::new();
            for &i in list {
                for p in rest.range(i as usize) {
                    let (ci, cj) = (cell[i as usize], cell[rest.j()[p] as usize]);
                    set.insert(offset(std::array::from_fn(|a| cj[a] - ci[a]), dims));
                }
            }
            if set.len() > MAX_OFFSETS {
                return None;
            }
            guard = guard.max(set.iter().map(|o| o.unsigned_abs()).max().unwrap_or(0));
            offsets_of.push(set.into_iter().collect::<Vec<isize>>());
        }
        let guard = guard.next_multiple_of(LANES);
        let mut boxes = Vec::new();
        let mut first = guard;
        for (offsets, &(_, _, cells)) in offsets_of.into_iter().zip(&shapes) {
            let len = cells.next_multiple_of(LANES);
            boxes.push(LatticeBox { first, len, offsets, template: Vec::new() });
            first += len;
        }
        let slots = first + guard;
        let mut lat = RestLattice {
            loose,
            slot: vec![0; n],
            particle: vec![EMPTY; slots],
            chunk_box: vec![NO_BOX; slots / LANES],
            chunk_w: vec![TEMPLATE; slots / LANES],
            wq: Vec::new(),
            wsum: vec![0.0; 3 * slots],
            volume: vec![1.0; slots],
            w_scale: rest.w_scale(),
            boxes: Vec::new(),
        };
        // Each particle's position in its body's list.
        let mut pos = vec![0usize; n];
        for list in members.values() {
            for (k, &i) in list.iter().enumerate() {
                pos[i as usize] = k;
            }
        }
        for (b, ((list, &(lo, dims, _)), bx)) in members.values().zip(&shapes).zip(&mut boxes).enumerate() {
            for q in bx.first / LANES..(bx.first + bx.len) / LANES {
                lat.chunk_box[q] = b as u32;
            }
            let kk = bx.offsets.len();
            // The body's w_ij by particle and offset (3 K integers a
            // particle, 0 where it has no pair at an offset).
            let mut pattern = vec![0i16; 3 * kk * list.len()];
            for &i in list {
                let i = i as usize;
                let s = bx.first + local(cell[i], lo, dims);
                if lat.particle[s] != EMPTY {
                    return None;
                }
                lat.particle[s] = i as u32;
                lat.slot[i] = s as u32;
                lat.volume[s] = rest.volume[i];
                for c in 0..3 {
                    lat.wsum[c * slots + s] = rest.wsum[i][c];
                }
                let w = &mut pattern[3 * kk * pos[i]..3 * kk * (pos[i] + 1)];
                for p in rest.range(i) {
                    let cj = cell[rest.j()[p] as usize];
                    let o = offset(std::array::from_fn(|a| cj[a] - cell[i][a]), dims);
                    let k = bx.offsets.binary_search(&o).expect("every pair's offset is in its box's set");
                    w[3 * k..3 * k + 3].copy_from_slice(&rest.w_integers(p));
                }
            }
            let mut count: HashMap<&[i16], usize> = HashMap::new();
            for w in pattern.chunks_exact(3 * kk.max(1)) {
                *count.entry(w).or_default() += 1;
            }
            // The most common pattern (the smallest of equally common ones:
            // the same whatever the map's order).
            let template = count.into_iter().max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(a.0))).map(|(w, _)| w.to_vec());
            let template = template.unwrap_or_default();
            for q in bx.first / LANES..(bx.first + bx.len) / LANES {
                let of = |s: usize| match lat.particle[s] {
                    EMPTY => None,
                    p => Some(&pattern[3 * kk * pos[p as usize]..3 * kk * (pos[p as usize] + 1)]),
                };
                if (q * LANES..(q + 1) * LANES).all(|s| of(s) == Some(&template[..])) {
                    continue;
                }
                lat.chunk_w[q] = lat.wq.len() as u32;
                let start = lat.wq.len();
                lat.wq.resize(start + 3 * kk * LANES, 0);
                for l in 0..LANES {
                    if let Some(w) = of(q * LANES + l) {
                        for (kc, &x) in w.iter().enumerate() {
                            lat.wq[start + kc * LANES + l] = x;
                        }
                    }
                }
            }
            bx.template = template.iter().map(|&x| f32::from(x)).collect();
        }
        if lat.wq.len() > u32::MAX as usize {
            return None;
        }
        lat.boxes = boxes;
        Some(lat)
    }

    /// U / V_i0 of the chunk of slots from `s0` (as [`RestState`]'s
    /// per-particle unit).
    #[inline(always)]
    fn unit(&self, s0: usize) -> F {
        F::splat(self.w_scale) / load(&self.volume, s0)
    }

    /// Number of slots, guards included.
    pub fn slots(&self) -> usize {
        self.particle.len()
    }

    /// The chunks that read their box's template, and all the boxes'
    /// chunks.
    pub fn template_chunks(&self) -> (usize, usize) {
        let boxed = self.chunk_box.iter().filter(|&&b| b != NO_BOX).count();
        let template =
            self.chunk_box.iter().zip(&self.chunk_w).filter(|&(&b, &w)| b != NO_BOX && w == TEMPLATE).count();
        (template, boxed)
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * (self.loose.capacity()
            + self.slot.capacity()
            + self.particle.capacity()
            + self.chunk_box.capacity()
            + self.chunk_w.capacity())
            + 4 * (self.wsum.capacity() + self.volume.capacity())
            + 2 * self.wq.capacity()
            + self.boxes.iter().map(|b| 8 * b.offsets.capacity() + 4 * b.template.capacity() + 56).sum::<usize>()
    }

    /// out = (M A) v of `sys` (whose rest state is the one this was built
    /// from), as [`System::apply`] with the pair list: T^_i from the strain
    /// increment G_i = sum_j (v_j - v_i) (x) w_ij, then f^_i / V_i0 =
    /// T^_i s_i + sum_j T^_j w_ij.
    pub(crate) fn apply(&self, sys: &System, v: &[Vec3], s: &mut LatticeScratch, out: &mut [Vec3]) {
        let ns = self.slots();
        let chunks = ns / LANES;
        s.v.resize(3 * ns, 0.0);
        s.t.resize(9 * ns, 0.0);
        // v in slots, one array a component; 0 in empty slots.
        s.v.par_chunks_mut(LANES).enumerate().for_each(|(q, dst)| {
            let (c, s0) = (q / chunks, (q % chunks) * LANES);
            for (l, d) in dst.iter_mut().enumerate() {
                let p = self.particle[s0 + l];
                *d = if p == EMPTY { 0.0 } else { v[p as usize][c] };
            }
        });
        let vs = [&s.v[..ns], &s.v[ns..2 * ns], &s.v[2 * ns..]];
        let t_out = Writes(s.t.as_mut_ptr());
        let dt = sys.dt;
        // T^ of each slot, one array a component (column-major, 3 col +
        // row); 0 in empty slots and the guards.
        (0..chunks).into_par_iter().for_each(|q| {
            let s0 = q * LANES;
            let mut tq = [[0.0f32; LANES]; 9];
            if let Some(bx) = self.boxes.get(self.chunk_box[q] as usize) {
                let g = match self.chunk_w[q] {
                    TEMPLATE => strain_sum(vs, s0, &bx.offsets, |kc| F::splat(bx.template[kc])),
                    at => {
                        let wq = &self.wq[at as usize..][..3 * bx.offsets.len() * LANES];
                        strain_sum(vs, s0, &bx.offsets, |kc| load_i16(wq, kc * LANES))
                    }
                };
                let u = self.unit(s0);
                let g = g.map(|gc| gc.map(|x| x * u));
                // Each lane's RL and Lamé parameters, read particle by
                // particle (the records are consecutive in store order; a
                // hardware gather of them waited on memory): an empty slot
                // takes zeros, and its G is 0, so its T^ is 0.
                let (mut rl, mut mu, mut lambda) = ([[0.0f32; LANES]; 9], [0.0f32; LANES], [0.0f32; LANES]);
                for l in 0..LANES {
                    let p = self.particle[s0 + l];
                    if p != EMPTY {
                        let m = sys.def[p as usize].rl.to_cols_array();
                        for c in 0..9 {
                            rl[c][l] = m[c];
                        }
                        let Lame { mu: a, lambda: b } = sys.lame[p as usize];
                        (mu[l], lambda[l]) = (a, b);
                    }
                }
                let t = increment_stress_lanes(&g, &rl.map(F::from), F::from(mu), F::from(lambda), dt);
                for (c, tc) in t.iter().enumerate() {
                    tq[c] = tc.to_array();
                }
            }
            for (c, tc) in tq.iter().enumerate() {
                // SAFETY: chunk q writes slots s0..s0 + LANES of each of the
                // nine component arrays of `s.t` (9 ns long), which no other
                // chunk writes and nothing reads in this loop.
                unsafe { t_out.put_lanes(c * ns + s0, tc) };
            }
        });
        let ts: [&[f32]; 9] = std::array::from_fn(|c| &s.t[c * ns..(c + 1) * ns]);
        // f^_i / V_i0 = T^_i s_i + sum_j T^_j w_ij, and out_i = m_i v_i -
        // dt V_i0 f^_i / V_i0 written to each slot's particle.
        assert_eq!(out.len(), self.slot.len(), "one output a particle");
        // Particles without rest pairs: G = 0, s_i = 0, so f^_i = 0.
        for &i in &self.loose {
            out[i as usize] = sys.mass[i as usize] * v[i as usize];
        }
        let out_at = Writes(out.as_mut_ptr());
        (0..chunks).into_par_iter().for_each(|q| {
            let Some(bx) = self.boxes.get(self.chunk_box[q] as usize) else {
                return;
            };
            let s0 = q * LANES;
            let a = match self.chunk_w[q] {
                TEMPLATE => stress_sum(&ts, s0, &bx.offsets, |kc| F::splat(bx.template[kc])),
                at => {
                    let wq = &self.wq[at as usize..][..3 * bx.offsets.len() * LANES];
                    stress_sum(&ts, s0, &bx.offsets, |kc| load_i16(wq, kc * LANES))
                }
            };
            let u = self.unit(s0);
            let ti: [F; 9] = std::array::from_fn(|c| load(ts[c], s0));
            let si: [F; 3] = std::array::from_fn(|c| load(&self.wsum[c * ns..(c + 1) * ns], s0));
            let dt_v = load(&self.volume, s0) * F::splat(dt);
            let f: [[f32; LANES]; 3] = std::array::from_fn(|r| {
                let own = ti[r] * si[0] + ti[3 + r] * si[1] + ti[6 + r] * si[2];
                ((own + (a[0][r] + a[1][r] + a[2][r]) * u) * dt_v).to_array()
            });
            for (l, &p) in self.particle[s0..s0 + LANES].iter().enumerate() {
                if p == EMPTY {
                    continue;
                }
                let p = p as usize;
                let mut o = sys.mass[p] * v[p];
                if sys.fixed[p] == 0 {
                    o -= Vec3::new(f[0][l], f[1][l], f[2][l]);
                }
                // SAFETY: p < out.len() (asserted above: a slot's particle
                // is below the particle count), and each particle has one
                // slot, so no other chunk writes out[p]; nothing reads out.
                unsafe { out_at.put(p, o) };
            }
        });
    }
}

/// g[c][r] = sum_j (v_j - v_i)_r (w_ij)_c for the chunk of slots from
/// `s0` (`vs`: v by component; `w(3 k + c)`: component c of the chunk's
/// w at offset k).
#[inline(always)]
fn strain_sum(vs: [&[f32]; 3], s0: usize, offsets: &[isize], w: impl Fn(usize) -> F) -> [[F; 3]; 3] {
    assert!(in_reach(vs.iter().map(|v| v.len()).min().unwrap_or(0), s0, offsets), "strain_sum: loads out of the slots");
    let vi = [load(vs[0], s0), load(vs[1], s0), load(vs[2], s0)];
    let mut g = [[F::ZERO; 3]; 3];
    for (k, &o) in offsets.iter().enumerate() {
        let sj = (s0 as isize + o) as usize;
        // SAFETY: sj + LANES <= the arrays' length (asserted above).
        let vj = |c: usize| unsafe { load_unchecked(vs[c], sj) };
        let d = [vj(0) - vi[0], vj(1) - vi[1], vj(2) - vi[2]];
        for (c, gc) in g.iter_mut().enumerate() {
            let wc = w(3 * k + c);
            for r in 0..3 {
                gc[r] = d[r].mul_add(wc, gc[r]);
            }
        }
    }
    g
}

/// a[c][r] = sum_j (T^_j)_rc (w_ij)_c, column c of T^_j times w_c, for the
/// chunk of slots from `s0` (`ts`: T^ by component, column-major; `w` as
/// in [`strain_sum`]).
#[inline(always)]
fn stress_sum(ts: &[&[f32]; 9], s0: usize, offsets: &[isize], w: impl Fn(usize) -> F) -> [[F; 3]; 3] {
    assert!(in_reach(ts.iter().map(|t| t.len()).min().unwrap_or(0), s0, offsets), "stress_sum: loads out of the slots");
    let mut a = [[F::ZERO; 3]; 3];
    for (k, &o) in offsets.iter().enumerate() {
        let sj = (s0 as isize + o) as usize;
        for (c, ac) in a.iter_mut().enumerate() {
            let wc = w(3 * k + c);
            for r in 0..3 {
                // SAFETY: sj + LANES <= the arrays' length (asserted above).
                ac[r] = unsafe { load_unchecked(ts[3 * c + r], sj) }.mul_add(wc, ac[r]);
            }
        }
    }
    a
}

/// T^ = (2 mu eps^ + lambda tr(eps^) I) RL_i with eps^ = dt sym(G RL_i^T)
/// (PHYSICS.md §3.3, as [`System::apply`] computes it) for [`LANES`]
/// particles: `g[c][r]` = G_rc, `rl[3 c + r]` = (RL)_rc (column-major);
/// returns T^ column-major.
#[inline(always)]
fn increment_stress_lanes(g: &[[F; 3]; 3], rl: &[F; 9], mu: F, lambda: F, dt: f32) -> [F; 9] {
    let rl = |r: usize, c: usize| rl[3 * c + r];
    // a = G RL^T: a_rc = sum_m G_rm RL_cm.
    let a = |r: usize, c: usize| g[0][r] * rl(c, 0) + g[1][r] * rl(c, 1) + g[2][r] * rl(c, 2);
    let a: [[F; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| a(r, c)));
    // eps^ = dt sym(a); S = 2 mu eps^ + lambda tr(eps^) I.
    let half_dt = F::splat(0.5 * dt);
    let eps = |r: usize, c: usize| (a[r][c] + a[c][r]) * half_dt;
    let tr = lambda * (eps(0, 0) + eps(1, 1) + eps(2, 2));
    let two_mu = mu + mu;
    let s = |r: usize, c: usize| if r == c { two_mu * eps(r, c) + tr } else { two_mu * eps(r, c) };
    let s: [[F; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| s(r, c)));
    // T^ = S RL, column-major.
    std::array::from_fn(|k| {
        let (r, c) = (k % 3, k / 3);
        s[r][0] * rl(0, c) + s[r][1] * rl(1, c) + s[r][2] * rl(2, c)
    })
}

/// Whether the loads of `s0 + o .. s0 + o + LANES` for every offset o of
/// `offsets` (ascending) lie in `0..len`.
#[inline(always)]
fn in_reach(len: usize, s0: usize, offsets: &[isize]) -> bool {
    match (offsets.first(), offsets.last()) {
        (Some(&lo), Some(&hi)) => s0 as isize + lo >= 0 && s0 as isize + hi + LANES as isize <= len as isize,
        _ => true,
    }
}

/// `s[k..k + LANES]` without a bounds check (the stencil sums check their
/// reach once a chunk: a check a load was a fifth of their instructions).
///
/// # Safety
/// `k + LANES <= s.len()`.
#[inline(always)]
unsafe fn load_unchecked(s: &[f32], k: usize) -> F {
    F::from(std::ptr::read_unaligned(s.as_ptr().add(k) as *const [f32; LANES]))
}

/// `wq[k..k + LANES]` as f32 (exact: integers below 2^15).
#[inline(always)]
fn load_i16(wq: &[i16], k: usize) -> F {
    let a: [i16; LANES] = wq[k..k + LANES].try_into().expect("a whole vector");
    i32x16::from_i16x16(i16x16::from(a)).round_float()
}

/// The lattice product's slot buffers ([`RestLattice::apply`]), kept across
/// calls for their capacity.
#[derive(Clone, Debug, Default)]
pub struct LatticeScratch {
    /// v of each slot, one array a component.
    v: Vec<f32>,
    /// T^ of each slot, one array a component.
    t: Vec<f32>,
}

impl LatticeScratch {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * (self.v.capacity() + self.t.capacity())
    }
}

/// Where the chunks of [`RestLattice::apply`] write: T^ of their own
/// slots, the product of their slots' particles.
#[derive(Clone, Copy)]
struct Writes<T>(*mut T);

// SAFETY: the parallel loops write each index from one chunk only.
unsafe impl<T> Send for Writes<T> {}
unsafe impl<T> Sync for Writes<T> {}

impl<T: Copy> Writes<T> {
    /// Writes `v` at `k`.
    ///
    /// # Safety
    /// `k` is within the buffer the pointer came from, which outlives the
    /// loop, and no other thread reads or writes index `k` during it.
    #[inline(always)]
    unsafe fn put(&self, k: usize, v: T) {
        self.0.add(k).write(v);
    }

    /// Writes `v` at `k..k + LANES`.
    ///
    /// # Safety
    /// As [`Writes::put`] for each of the indices.
    #[inline(always)]
    unsafe fn put_lanes(&self, k: usize, v: &[T; LANES]) {
        std::ptr::copy_nonoverlapping(v.as_ptr(), self.0.add(k), LANES);
    }
}
