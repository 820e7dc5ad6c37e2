#![allow(clippy::needless_range_loop)] // particle index i across per-phase arrays [k][i]
//! Contracts of the mixture kernels on random input (PHYSICS.md §4.1):
//! the conservative transport keeps every phase's volume, the partition of
//! unity and positivity; drift velocities have no mass-weighted mean; the
//! phase pair weights of the viscosity are exactly 1 for one phase.

use porosph_kernels::band::{Band, BandVel};
use porosph_kernels::blocks::BLOCK;
use porosph_kernels::drift::{self, PhaseVelocityInput};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph::{self, FluidRows, WallRows};
use porosph_kernels::kernel::Kernel;
use porosph_kernels::lanes::{pair_vectors, sum, Packed, F};
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, PairLists};
use porosph_kernels::phase_transport::{correct, correction_sums, transport, TransportScratch};
use porosph_kernels::phases::{join, PhaseConstants, PhaseVel};
use porosph_kernels::porous;
use porosph_kernels::soa::{Vel, VelMut};
use porosph_kernels::viscosity::{predict_velocity, predict_velocity_mixture, ViscosityInput};
use wide::Select;

struct Lcg(u64);
impl Lcg {
    /// Uniform in [0, 1).
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A jittered lattice of n^3 particles of spacing 1 (H = 2), Morton-sorted,
/// with its fluid-fluid pairs; the gradients are scaled by Vbar = 1.
struct Lattice {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    ff: PairLists,
}

fn lattice(n: usize, rng: &mut Lcg) -> Lattice {
    let mut pts = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let jit = |r: &mut Lcg| 0.2 * (r.next() - 0.5);
                pts.push([i as f32 + jit(rng), j as f32 + jit(rng), k as f32 + jit(rng)]);
            }
        }
    }
    let (x0, y0, z0): (Vec<f32>, Vec<f32>, Vec<f32>) =
        (pts.iter().map(|p| p[0]).collect(), pts.iter().map(|p| p[1]).collect(), pts.iter().map(|p| p[2]).collect());
    let h = 2.0;
    let mut keys = vec![0; x0.len()];
    compute_keys(&x0, &y0, &z0, 1.0 / h, &mut keys);
    let (mut s, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut s, &mut perm);
    let p = |v: &Vec<f32>| perm.iter().map(|&i| v[i as usize]).collect::<Vec<f32>>();
    let (x, y, z) = (p(&x0), p(&y0), p(&z0));
    let sk: Vec<u64> = s.iter().map(|&(k, _)| k).collect();
    let mut g = CellGrid::default();
    g.build(&sk, h);
    let mut ff = PairLists::default();
    let pt = Vel { x: &x, y: &y, z: &z };
    build_pairs(&mut ff, pt, pt, &g, None, &Kernel::new(h));
    Lattice { x, y, z, ff }
}

/// The lattice of 10^3 particles and random velocities in [-0.5, 0.5) m/s.
fn lattice_with_velocities(rng: &mut Lcg) -> (Lattice, Vec<Vec<f32>>) {
    let lat = lattice(10, rng);
    let n = lat.x.len();
    let u = (0..3).map(|_| (0..n).map(|_| rng.next() - 0.5).collect()).collect();
    (lat, u)
}

/// The viscosity pass's input on `lat` with velocities `u`, rest
/// densities `rho` and viscosities `mu`, nothing packed, mu read per pair.
fn viscosity_input<'a>(lat: &'a Lattice, u: &'a [Vec<f32>], rho: &'a [f32], mu: &'a [f32]) -> ViscosityInput<'a> {
    ViscosityInput {
        ff: &lat.ff,
        x: Vel { x: &lat.x, y: &lat.y, z: &lat.z },
        u: Vel { x: &u[0], y: &u[1], z: &u[2] },
        packed: None,
        rest_density: rho,
        mu,
        mu_uniform: false,
        phases: None,
        h: 1.0,
        gravity: [0.0, -9.81, 0.0],
        dt: 0.01,
    }
}

/// Random fractions (a partition of unity, a third of the particles pure
/// in one phase) for `np` phases.
fn fractions(n: usize, np: usize, rng: &mut Lcg) -> Vec<Vec<f32>> {
    let mut a = vec![vec![0.0f32; n]; np];
    for i in 0..n {
        if rng.next() < 0.33 {
            a[((rng.next() * np as f32) as usize).min(np - 1)][i] = 1.0;
            continue;
        }
        let w: Vec<f32> = (0..np).map(|_| rng.next()).collect();
        let s: f32 = w.iter().sum();
        for k in 0..np {
            a[k][i] = w[k] / s;
        }
    }
    a
}

/// "The conservative transport conserves each phase's volume, keeps
/// sum_k alpha_k = 1 and alpha >= 0, for any fluxes that add up to 0 over
/// the phases" — with random fluxes large enough that the positivity
/// limiter acts on most particles (dt |F| / h up to 2). Tolerances are f32
/// rounding of sums over ~50 pairs: 1e-5 per particle, 1e-6 relative in
/// the totals.
#[test]
fn conservative_transport_conserves_and_stays_positive() {
    let mut rng = Lcg(11);
    let lat = lattice(12, &mut rng);
    let n = lat.x.len();
    for np in [2usize, 3] {
        let alpha = fractions(n, np, &mut rng);
        // Fluxes F_k = alpha_k (v_k - sum alpha v): add up to 0 per particle.
        let v: Vec<[Vec<f32>; 3]> =
            (0..np).map(|_| std::array::from_fn(|_| (0..n).map(|_| 4.0 * rng.next() - 2.0).collect())).collect();
        let mut f: Vec<[Vec<f32>; 3]> = (0..np).map(|_| std::array::from_fn(|_| vec![0.0; n])).collect();
        for i in 0..n {
            for c in 0..3 {
                let m: f32 = (0..np).map(|k| alpha[k][i] * v[k][c][i]).sum();
                for k in 0..np {
                    f[k][c][i] = alpha[k][i] * (v[k][c][i] - m);
                }
            }
        }
        let fx: Vec<&[f32]> = f.iter().map(|f| f[0].as_slice()).collect();
        let fy: Vec<&[f32]> = f.iter().map(|f| f[1].as_slice()).collect();
        let fz: Vec<&[f32]> = f.iter().map(|f| f[2].as_slice()).collect();
        let flux = PhaseVel { x: &fx, y: &fy, z: &fz };
        let dt = 0.5;
        let next = transport_all(&lat.ff, &alpha, &flux, dt);
        let limited = reference_transport(&lat.ff, &alpha, &flux, dt).1;
        let moved: f64 =
            (0..np).map(|k| (0..n).map(|i| (next[k][i] - f64::from(alpha[k][i])).abs()).sum::<f64>()).sum();
        // Each pair flux leaves one particle and enters the other: the
        // volume changes only by the f32 rounding of each particle's sum
        // of pair fluxes (about 1e-8 of its gross flux), not by the
        // rounding of the stored fraction (the f64 result).
        let mut worst = 0.0f64;
        for k in 0..np {
            let (a, b): (f64, f64) = (alpha[k].iter().map(|&x| f64::from(x)).sum(), next[k].iter().sum());
            worst = worst.max(((b - a) / a).abs());
        }
        assert!(worst < 1e-8, "{np} phases: largest relative volume change {worst:e}");
        for i in 0..n {
            let s: f64 = (0..np).map(|k| next[k][i]).sum();
            assert!((s - 1.0).abs() < 1e-5, "particle {i}: sum {s}");
            for (k, a) in next.iter().enumerate() {
                assert!(a[i] >= -1e-5, "particle {i}, phase {k}: {}", a[i]);
            }
        }
        // The correction then only removes rounding.
        let nref: Vec<&[f64]> = next.iter().map(|a| a.as_slice()).collect();
        let (mut total, mut largest) = (vec![0.0; n], vec![0u32; n]);
        correction_sums(&nref, &mut total, &mut largest);
        let mut fixed = vec![vec![0.0f32; n]; np];
        let mut fixed_lo = vec![vec![0.0f32; n]; np];
        for (k, (out, lo)) in fixed.iter_mut().zip(fixed_lo.iter_mut()).enumerate() {
            correct(&next[k], &total, &largest, k, out, lo);
        }
        for i in 0..n {
            let s: f64 = (0..np).map(|k| join(fixed[k][i], fixed_lo[k][i])).sum();
            assert!((s - 1.0).abs() < 1e-12 && (0..np).all(|k| fixed[k][i] >= 0.0), "particle {i}: sum {s}");
        }
        println!(
            "{np} phases, {n} particles: {limited} particle-phase limits < 1, total |change| {moved:.1} (fractions), \
             largest relative volume change {worst:.2e}"
        );
        assert!(limited > n / 10, "the limiter was not exercised");
        assert!(moved > n as f64 / 10.0, "nothing moved");
    }
}

/// The correction: negatives clamped, the rest renormalised; all <= 0
/// gives the phase that was largest before clamping.
#[test]
fn correction_clamps_renormalises_and_falls_back() {
    let a0 = [0.6f64, -0.2, -0.5];
    let a1 = [0.6f64, -0.1, -0.1];
    let a2 = [0.0f64, 0.5, 0.0];
    let next: [&[f64]; 3] = [&a0, &a1, &a2];
    let (mut total, mut largest) = (vec![0.0; 3], vec![0u32; 3]);
    correction_sums(&next, &mut total, &mut largest);
    let out: Vec<Vec<f32>> = (0..3)
        .map(|k| {
            let (mut o, mut lo) = (vec![0.0; 3], vec![0.0; 3]);
            correct(next[k], &total, &largest, k, &mut o, &mut lo);
            o
        })
        .collect();
    // Particle 0: (0.6, 0.6, 0) -> (0.5, 0.5, 0); particle 1: (0, 0, 0.5) -> (0, 0, 1);
    // particle 2: (-0.5, -0.1, 0) all <= 0 -> the largest, phase 2 (0.0).
    assert_eq!([out[0][0], out[1][0], out[2][0]], [0.5, 0.5, 0.0]);
    assert_eq!([out[0][1], out[1][1], out[2][1]], [0.0, 0.0, 1.0]);
    assert_eq!([out[0][2], out[1][2], out[2][2]], [0.0, 0.0, 1.0]);
}

/// Drift velocities of random fields: sum_k c_k u_mk = 0 wherever no
/// guard acts (every alphahat_k >= 0.01), the volume fluxes add up to 0
/// everywhere, and a single phase has no drift at all.
#[test]
fn drift_has_no_mass_weighted_mean_and_fluxes_add_up_to_zero() {
    let mut rng = Lcg(5);
    let lat = lattice(10, &mut rng);
    let n = lat.x.len();
    let np = 3;
    let alpha = fractions(n, np, &mut rng);
    let density = [850.0f32, 1000.0, 1300.0];
    let alpha_f = vec![1.0f32; n];
    let p: Vec<f32> = (0..n).map(|_| 1000.0 * rng.next()).collect();
    let mut pf = vec![0.0; n];
    drift::pressure_per_fraction(&p, &alpha_f, &mut pf);
    let field = |r: &mut Lcg, s: f32| -> Vec<f32> { (0..n).map(|_| s * (r.next() - 0.5)).collect() };
    let (avx, avy, avz) = (field(&mut rng, 2.0), field(&mut rng, 2.0), field(&mut rng, 2.0));
    let (apx, apy, apz) = (field(&mut rng, 20.0), field(&mut rng, 20.0), field(&mut rng, 20.0));
    for fraction_pressure in [false, true] {
        let inp = PhaseVelocityInput {
            ff: &lat.ff,
            alpha_f: &alpha_f,
            p_per_fraction: if fraction_pressure { Some(&pf) } else { None },
            a_visc: Vel { x: &avx, y: &avy, z: &avz },
            a_p: Vel { x: &apx, y: &apy, z: &apz },
            packed: None,
        };
        let mut u: Vec<[Vec<f32>; 3]> = (0..np).map(|_| std::array::from_fn(|_| vec![0.0; n])).collect();
        let mut w: Vec<[Vec<f32>; 3]> = (0..np).map(|_| std::array::from_fn(|_| vec![0.0; n])).collect();
        for k in 0..np {
            let phase = PhaseConstants { density: density[k], tau: 1e-5, sigma: 1e-3 };
            let [ux, uy, uz] = &mut u[k];
            let [wx, wy, wz] = &mut w[k];
            drift::phase_velocity(
                &inp,
                &alpha[k],
                phase,
                VelMut { x: ux, y: uy, z: uz },
                VelMut { x: wx, y: wy, z: wz },
            );
        }
        let (s, m) = {
            let wx: Vec<&[f32]> = w.iter().map(|w| w[0].as_slice()).collect();
            let wy: Vec<&[f32]> = w.iter().map(|w| w[1].as_slice()).collect();
            let wz: Vec<&[f32]> = w.iter().map(|w| w[2].as_slice()).collect();
            let aref: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
            mixture_means(&aref, &alpha_f, &density, PhaseVel { x: &wx, y: &wy, z: &wz })
        };
        let sv = Vel { x: &s[0], y: &s[1], z: &s[2] };
        let mv = Vel { x: &m[0], y: &m[1], z: &m[2] };
        for k in 0..np {
            let [ux, uy, uz] = &mut u[k];
            let [wx, wy, wz] = &mut w[k];
            drift::drift_velocity(
                &alpha[k],
                sv,
                Some(mv),
                VelMut { x: ux, y: uy, z: uz },
                VelMut { x: wx, y: wy, z: wz },
            );
        }
        // f32 rounding of sums of a few terms, relative to the largest flux
        // and drift of the field.
        let fscale = w.iter().flat_map(|w| w.iter().flatten()).fold(0.0f32, |a, &b| a.max(b.abs()));
        let uscale = u.iter().flat_map(|u| u.iter().flatten()).fold(0.0f32, |a, &b| a.max(b.abs()));
        let (mut checked, mut scale) = (0, 0.0f32);
        for i in 0..n {
            let mass: f32 = (0..np).map(|k| alpha[k][i] * density[k]).sum();
            for c in 0..3 {
                let fsum: f32 = (0..np).map(|k| w[k][c][i]).sum();
                assert!(fsum.abs() <= 1e-5 * fscale, "particle {i}: fluxes add up to {fsum} (scale {fscale})");
                if (0..np).all(|k| alpha[k][i] >= 0.01) {
                    let cu: f32 = (0..np).map(|k| alpha[k][i] * density[k] / mass * u[k][c][i]).sum();
                    let umax = (0..np).map(|k| u[k][c][i].abs()).fold(0.0, f32::max);
                    assert!(cu.abs() <= 1e-5 * uscale, "particle {i}: sum c u = {cu} (scale {uscale})");
                    scale = scale.max(umax);
                    checked += 1;
                }
            }
        }
        assert!(checked > n && scale > 1e-3, "checked {checked}, |u| up to {scale}");
    }
}

/// With one phase of fraction 1 the phase pair weight is exactly 1, so the
/// mixture viscosity is bitwise the one-phase viscosity (PHYSICS.md §5);
/// and reading a uniform mu without its gather, or x and u packed,
/// changes nothing.
#[test]
fn mixture_viscosity_with_one_phase_is_the_one_phase_viscosity() {
    let mut rng = Lcg(3);
    let lat = lattice(10, &mut rng);
    let n = lat.x.len();
    // The viscosity pass uses unscaled gradients; a fresh list would have
    // them, but scaling by Vbar = 1 leaves them exact anyway.
    let u: Vec<Vec<f32>> = (0..3).map(|_| (0..n).map(|_| rng.next() - 0.5).collect()).collect();
    let rho = vec![1000.0f32; n];
    let mu = vec![0.5f32; n];
    let inp = viscosity_input(&lat, &u, &rho, &mu);
    let mut a: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut b: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut av: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    {
        let [ax, ay, az] = &mut a;
        predict_velocity(&inp, ax, ay, az);
    }
    let one = vec![1.0f32; n];
    let alpha: [&[f32]; 1] = [&one];
    {
        let [bx, by, bz] = &mut b;
        let [vx, vy, vz] = &mut av;
        predict_velocity_mixture(&inp, &alpha, VelMut { x: bx, y: by, z: bz }, VelMut { x: vx, y: vy, z: vz });
    }
    // The same viscosity read without the mu gather (`mu_uniform`).
    let mut u1: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    {
        let [x, y, z] = &mut u1;
        predict_velocity(&ViscosityInput { mu_uniform: true, ..inp }, x, y, z);
    }
    // x and u packed, one phase and mixture.
    let xp: Vec<Packed> = (0..n).map(|i| [lat.x[i], lat.y[i], lat.z[i], 0.0]).collect();
    let up: Vec<Packed> = (0..n).map(|i| [u[0][i], u[1][i], u[2][i], 0.0]).collect();
    let packed = ViscosityInput { packed: Some([&xp, &up]), ..inp };
    let mut u2: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut b2: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut av2: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    {
        let [x, y, z] = &mut u2;
        predict_velocity(&packed, x, y, z);
        let [bx, by, bz] = &mut b2;
        let [vx, vy, vz] = &mut av2;
        predict_velocity_mixture(&packed, &alpha, VelMut { x: bx, y: by, z: bz }, VelMut { x: vx, y: vy, z: vz });
    }
    for c in 0..3 {
        assert!(a[c].iter().zip(&b[c]).all(|(p, q)| p.to_bits() == q.to_bits()), "component {c}");
        assert!(a[c].iter().zip(&u1[c]).all(|(p, q)| p.to_bits() == q.to_bits()), "component {c}, uniform mu");
        assert!(a[c].iter().zip(&u2[c]).all(|(p, q)| p.to_bits() == q.to_bits()), "component {c}, packed");
        assert!(b[c].iter().zip(&b2[c]).all(|(p, q)| p.to_bits() == q.to_bits()), "component {c}, packed mixture");
        assert!(av[c].iter().zip(&av2[c]).all(|(p, q)| p.to_bits() == q.to_bits()), "a^visc {c}, packed");
    }
    assert!(av[0].iter().any(|&x| x != 0.0));
    assert_eq!(n.div_ceil(BLOCK), lat.ff.used().len());
}

/// [`transport`] into per-phase vectors (zero low parts).
fn transport_all(ff: &PairLists, alpha: &[Vec<f32>], flux: &PhaseVel, dt: f32) -> Vec<Vec<f64>> {
    let (np, n) = (alpha.len(), alpha[0].len());
    let (mut limit, mut net, mut least, mut packed) =
        (vec![0.0f32; np * n], vec![0.0f32; np * n], vec![0.0f32; n], vec![[0.0f32; 4]; np * n]);
    let mut near = vec![false; n];
    let scratch =
        TransportScratch { limit: &mut limit, net: &mut net, least: &mut least, flux: &mut packed, near: &mut near };
    let frac: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
    let zero = vec![0.0f32; n];
    let lo: Vec<&[f32]> = (0..np).map(|_| zero.as_slice()).collect();
    let mut out = vec![0.0f64; np * n];
    transport(ff, &frac, &lo, PhaseVel { x: flux.x, y: flux.y, z: flux.z }, dt, scratch, &mut out);
    out.chunks(n).map(|c| c.to_vec()).collect()
}

/// The conservative transport in the three passes it had until
/// 2026-12-05 (each phase's pair fluxes phi_k,ij stored per pair, then the
/// pair limits Lambda_ij stored per pair, then each phase's sum of
/// Lambda phi): the reference that [`transport`], one pass over the pairs
/// for all phases without stored pair fluxes, must equal bit for bit.
/// Returns the new fractions and the number of outflow limits below 1.
fn reference_transport(ff: &PairLists, alpha: &[Vec<f32>], flux: &PhaseVel, dt: f32) -> (Vec<Vec<f64>>, usize) {
    let (np, n, nb) = (alpha.len(), alpha[0].len(), ff.used().len());
    let mut lambda = vec![vec![0.0f32; n]; np];
    let mut phi = vec![vec![Vec::new(); nb]; np];
    for k in 0..np {
        let f = flux.phase(k);
        for (b, blk) in ff.used().iter().enumerate() {
            let out = &mut phi[k][b];
            out.resize(blk.len(), 0.0);
            for q in 0..blk.start.len() - 1 {
                let i = b * BLOCK + q;
                let (fxi, fyi, fzi) = (F::splat(f.x[i]), F::splat(f.y[i]), F::splat(f.z[i]));
                let mut acc = F::ZERO;
                for pv in pair_vectors(&blk.j, blk.range(q)) {
                    let v = (pv.gather(f.x) + fxi) * pv.load(&blk.gx)
                        + (pv.gather(f.y) + fyi) * pv.load(&blk.gy)
                        + (pv.gather(f.z) + fzi) * pv.load(&blk.gz);
                    pv.store(out, v);
                    acc += v.max(F::ZERO);
                }
                let leaving = dt * sum(acc);
                let a = alpha[k][i];
                lambda[k][i] = if leaving > a { a.max(0.0) / leaving } else { 1.0 };
            }
        }
    }
    let mut next = vec![vec![0.0f64; n]; np];
    for (b, blk) in ff.used().iter().enumerate() {
        let mut lim = vec![1.0f32; blk.len()];
        for q in 0..blk.start.len() - 1 {
            let i = b * BLOCK + q;
            for pv in pair_vectors(&blk.j, blk.range(q)) {
                let mut lam = F::splat(1.0);
                for k in 0..np {
                    let v = pv.load(&phi[k][b]);
                    let from_j = Select::select(v.simd_lt(F::ZERO), pv.gather(&lambda[k]), F::splat(1.0));
                    lam = lam.min(Select::select(v.simd_gt(F::ZERO), F::splat(lambda[k][i]), from_j));
                }
                pv.store(&mut lim, lam);
            }
        }
        for k in 0..np {
            for q in 0..blk.start.len() - 1 {
                let i = b * BLOCK + q;
                let mut acc = F::ZERO;
                for pv in pair_vectors(&blk.j, blk.range(q)) {
                    acc += pv.load(&phi[k][b]) * pv.load(&lim);
                }
                next[k][i] = f64::from(alpha[k][i]) - f64::from(dt) * f64::from(sum(acc));
            }
        }
    }
    let limited = lambda.iter().flatten().filter(|&&l| l < 1.0).count();
    (next, limited)
}

/// The one-pass transport is the three-pass reference bit for bit, where
/// the limiter acts on most particles (dt = 0.5), on some (0.05), and on
/// none (0), for 1, 2, 3 and 10 phases (more than one group of phases).
#[test]
fn one_pass_transport_is_the_three_pass_form_bit_for_bit() {
    let mut rng = Lcg(23);
    let lat = lattice(9, &mut rng);
    let n = lat.x.len();
    for np in [1usize, 2, 3, 10] {
        let alpha = fractions(n, np, &mut rng);
        let f: Vec<[Vec<f32>; 3]> = (0..np)
            .map(|k| std::array::from_fn(|_| (0..n).map(|i| alpha[k][i] * (4.0 * rng.next() - 2.0)).collect()))
            .collect();
        let fx: Vec<&[f32]> = f.iter().map(|f| f[0].as_slice()).collect();
        let fy: Vec<&[f32]> = f.iter().map(|f| f[1].as_slice()).collect();
        let fz: Vec<&[f32]> = f.iter().map(|f| f[2].as_slice()).collect();
        let flux = PhaseVel { x: &fx, y: &fy, z: &fz };
        for dt in [0.5f32, 0.05, 0.0] {
            let (want, limited) = reference_transport(&lat.ff, &alpha, &flux, dt);
            let got = transport_all(&lat.ff, &alpha, &flux, dt);
            for k in 0..np {
                for i in 0..n {
                    assert_eq!(
                        got[k][i].to_bits(),
                        want[k][i].to_bits(),
                        "{np} phases, dt {dt}, phase {k}, particle {i}: {} vs {}",
                        got[k][i],
                        want[k][i]
                    );
                }
            }
            println!("{np} phases, dt {dt}: {limited} of {} outflow limits < 1, equal bit for bit", np * n);
            if dt == 0.5 && np > 1 {
                assert!(limited > n / 10, "the limiter was not exercised");
            }
        }
    }
}

/// The drift momentum term in its tensor form (T_i = sum_k rho_k alpha_k
/// u_mk (x) u_mk per particle, six gathers a pair) against the module
/// doc's sum over pairs and phases written out in f64: equal to f32
/// rounding (1e-5 of the largest |a^Dm|), with 3 phases of random
/// fractions and drift velocities.
#[test]
fn drift_momentum_tensor_form_is_the_sum_over_phases() {
    use porosph_kernels::drift_momentum::{drift_momentum, DriftMomentumInput};
    let mut rng = Lcg(23);
    let lat = lattice(10, &mut rng);
    let n = lat.x.len();
    let np = 3;
    let alpha = fractions(n, np, &mut rng);
    let density = [850.0f32, 1000.0, 1300.0];
    let rest: Vec<f32> = (0..n).map(|i| (0..np).map(|k| alpha[k][i] * density[k]).sum()).collect();
    let field = |r: &mut Lcg| -> Vec<f32> { (0..n).map(|_| 4.0 * (r.next() - 0.5)).collect() };
    let u: Vec<[Vec<f32>; 3]> = (0..np).map(|_| [field(&mut rng), field(&mut rng), field(&mut rng)]).collect();
    let ux: Vec<&[f32]> = u.iter().map(|v| v[0].as_slice()).collect();
    let uy: Vec<&[f32]> = u.iter().map(|v| v[1].as_slice()).collect();
    let uz: Vec<&[f32]> = u.iter().map(|v| v[2].as_slice()).collect();
    let aref: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
    let inp = DriftMomentumInput {
        ff: &lat.ff,
        alpha: &aref,
        u_drift: PhaseVel { x: &ux, y: &uy, z: &uz },
        density: &density,
        rest_density: &rest,
        sign: -1.0,
    };
    let mut out: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut t: [Vec<Packed>; 2] = std::array::from_fn(|_| vec![[0.0; 4]; n]);
    {
        let [ox, oy, oz] = &mut out;
        let [a, b] = &mut t;
        drift_momentum(&inp, VelMut { x: ox, y: oy, z: oz }, [a, b]);
    }
    let mut worst = 0.0f64;
    let mut scale = 0.0f64;
    for (b, blk) in lat.ff.used().iter().enumerate() {
        for q in 0..blk.start.len() - 1 {
            let i = b * BLOCK + q;
            if i >= n {
                break;
            }
            let mut a = [0.0f64; 3];
            for p in blk.range(q) {
                let j = blk.j[p] as usize;
                let g = [blk.gx[p], blk.gy[p], blk.gz[p]].map(f64::from);
                for k in 0..np {
                    for (m, w) in [i, j].into_iter().map(|m| (m, f64::from(density[k]) * f64::from(alpha[k][m]))) {
                        let v = [u[k][0][m], u[k][1][m], u[k][2][m]].map(f64::from);
                        let ug = v[0] * g[0] + v[1] * g[1] + v[2] * g[2];
                        for c in 0..3 {
                            a[c] += w * v[c] * ug;
                        }
                    }
                }
            }
            let c = -1.0 / f64::from(rest[i]);
            for d in 0..3 {
                let expected = c * a[d];
                scale = scale.max(expected.abs());
                worst = worst.max((f64::from(out[d][i]) - expected).abs());
            }
        }
    }
    assert!(scale > 1.0, "the field gives |a^Dm| up to {scale}");
    assert!(worst <= 1e-5 * scale, "largest difference {worst} against |a^Dm| up to {scale}");
}

/// "The one-pass drift of all phases is the per-phase drift bit for bit":
/// `drift::phase_velocities` (one pass over the pairs for every phase, in
/// groups of four) against `drift::phase_velocity` phase by phase, for 1 to
/// 6 phases (groups of 1, 2, 3, 4 and 4 + 1, 4 + 2), with the shared and
/// the per-fraction pressure, alpha_f below the 0.01 guard on some
/// particles and phases absent from some.
#[test]
fn one_pass_phase_velocities_are_the_per_phase_ones_bit_for_bit() {
    let mut rng = Lcg(11);
    let lat = lattice(9, &mut rng);
    let n = lat.x.len();
    let field = |r: &mut Lcg, s: f32| -> Vec<f32> { (0..n).map(|_| s * (r.next() - 0.5)).collect() };
    let (avx, avy, avz) = (field(&mut rng, 2.0), field(&mut rng, 2.0), field(&mut rng, 2.0));
    let (apx, apy, apz) = (field(&mut rng, 20.0), field(&mut rng, 20.0), field(&mut rng, 20.0));
    let p: Vec<f32> = (0..n).map(|_| 1000.0 * rng.next()).collect();
    for np in 1..=6 {
        let (alpha_f, alpha) = outer_fractions(n, np, &mut rng);
        let phases = drifting_phases(np);
        let mut pf = vec![0.0; n];
        drift::pressure_per_fraction(&p, &alpha_f, &mut pf);
        for fraction_pressure in [false, true] {
            let inp = PhaseVelocityInput {
                ff: &lat.ff,
                alpha_f: &alpha_f,
                p_per_fraction: if fraction_pressure { Some(&pf) } else { None },
                a_visc: Vel { x: &avx, y: &avy, z: &avz },
                a_p: Vel { x: &apx, y: &apy, z: &apz },
                packed: None,
            };
            let mut one: [Vec<f32>; 6] = std::array::from_fn(|_| vec![f32::NAN; np * n]);
            let a: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
            {
                let [vx, vy, vz, wx, wy, wz] = &mut one;
                let v = VelMut { x: vx, y: vy, z: vz };
                let w = VelMut { x: wx, y: wy, z: wz };
                drift::phase_velocities(&inp, &a, &phases, v, w);
            }
            // With the fractions packed (up to three phases): the same bits.
            let mut store = vec![[0.0f32; 4]; n];
            let pk = drift::pack_fractions(&a, inp.p_per_fraction, &mut store);
            assert_eq!(pk.is_some(), np <= drift::PACKED_PHASES);
            if let Some(pk) = pk {
                let mut packed: [Vec<f32>; 6] = std::array::from_fn(|_| vec![f32::NAN; np * n]);
                let [vx, vy, vz, wx, wy, wz] = &mut packed;
                let (v, w) = (VelMut { x: vx, y: vy, z: vz }, VelMut { x: wx, y: wy, z: wz });
                drift::phase_velocities(&PhaseVelocityInput { packed: Some(pk), ..inp }, &a, &phases, v, w);
                for (c, (o, e)) in one.iter().zip(&packed).enumerate() {
                    assert!(
                        o.iter().zip(e).all(|(o, e)| o.to_bits() == e.to_bits()),
                        "{np} phases, output {c}, packed"
                    );
                }
            }
            for k in 0..np {
                let mut each: [Vec<f32>; 6] = std::array::from_fn(|_| vec![f32::NAN; n]);
                let [vx, vy, vz, wx, wy, wz] = &mut each;
                let v = VelMut { x: vx, y: vy, z: vz };
                let w = VelMut { x: wx, y: wy, z: wz };
                drift::phase_velocity(&inp, &alpha[k], phases[k], v, w);
                for (c, (o, e)) in one.iter().zip(&each).enumerate() {
                    for i in 0..n {
                        assert_eq!(
                            o[k * n + i].to_bits(),
                            e[i].to_bits(),
                            "{np} phases, pressure per fraction {fraction_pressure}: phase {k}, output {c}, particle {i}: {} against {}",
                            o[k * n + i],
                            e[i]
                        );
                    }
                }
            }
        }
    }
}

/// "The drift's one pass is the sequence of passes bit for bit":
/// `drift::drift_velocities` (the phase velocities, P-Eq. 11's porous term,
/// the mixture sums, the drift velocities and fluxes and the largest drift
/// speed, per particle after its pair loop) against `phase_velocities`,
/// `porous::add_phase_term` per phase, `mixture_velocity`, `drift_velocity`
/// per phase and `max_drift_speed`, for 1 to 6 phases, with and without the
/// porous term (on a band of every third particle), the conservative and
/// the reference fluxes, the shared and the per-fraction pressure, packed
/// fractions where they apply, and alpha_f below the 0.01 guard on some
/// particles.
#[test]
fn the_fused_drift_is_the_sequence_of_passes_bit_for_bit() {
    let mut rng = Lcg(13);
    let lat = lattice(9, &mut rng);
    let n = lat.x.len();
    let arena = bumpalo::Bump::new();
    let field = |r: &mut Lcg, s: f32, len: usize| -> Vec<f32> { (0..len).map(|_| s * (r.next() - 0.5)).collect() };
    let (avx, avy, avz) = (field(&mut rng, 2.0, n), field(&mut rng, 2.0, n), field(&mut rng, 2.0, n));
    let (apx, apy, apz) = (field(&mut rng, 20.0, n), field(&mut rng, 20.0, n), field(&mut rng, 20.0, n));
    let p: Vec<f32> = (0..n).map(|_| 1000.0 * rng.next()).collect();
    let band = Band::new(&arena, n, |i| i % 3 == 0);
    let mut checked = 0;
    for np in 1..=6 {
        let (alpha_f, alpha) = outer_fractions(n, np, &mut rng);
        let a: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
        let phases = drifting_phases(np);
        let density: Vec<f32> = phases.iter().map(|c| c.density).collect();
        let m = band.len() * np;
        let (ex, ey, ez) = (field(&mut rng, 1e5, m), field(&mut rng, 1e5, m), field(&mut rng, 1e5, m));
        let e = BandVel { band, x: &ex, y: &ey, z: &ez };
        let mut pf = vec![0.0; n];
        drift::pressure_per_fraction(&p, &alpha_f, &mut pf);
        let mut store = vec![[0.0f32; 4]; n];
        for (fraction_pressure, porous, conservative) in
            (0..8).map(|c| (c & 1 != 0, (c & 2 != 0).then_some((e, -3e-6f32)), c & 4 != 0))
        {
            let pk = drift::pack_fractions(&a, fraction_pressure.then_some(pf.as_slice()), &mut store);
            let inp = PhaseVelocityInput {
                ff: &lat.ff,
                alpha_f: &alpha_f,
                p_per_fraction: if fraction_pressure { Some(&pf) } else { None },
                a_visc: Vel { x: &avx, y: &avy, z: &avz },
                a_p: Vel { x: &apx, y: &apy, z: &apz },
                packed: pk,
            };
            // The sequence of passes.
            let mut seq: [Vec<f32>; 6] = std::array::from_fn(|_| vec![f32::NAN; np * n]);
            let largest_seq = {
                let [vx, vy, vz, wx, wy, wz] = &mut seq;
                drift::phase_velocities(
                    &inp,
                    &a,
                    &phases,
                    VelMut { x: vx, y: vy, z: vz },
                    VelMut { x: wx, y: wy, z: wz },
                );
                if let Some((e, scale)) = porous {
                    for k in 0..np {
                        let r = k * n..(k + 1) * n;
                        let v = VelMut { x: &mut vx[r.clone()], y: &mut vy[r.clone()], z: &mut vz[r.clone()] };
                        let w = VelMut { x: &mut wx[r.clone()], y: &mut wy[r.clone()], z: &mut wz[r.clone()] };
                        porous::add_phase_term(&alpha[k], &alpha_f, e, k, scale, v, w);
                    }
                }
                let (s3, m3) = {
                    let (cx, cy, cz) = (phase_slices(wx, n), phase_slices(wy, n), phase_slices(wz, n));
                    mixture_means(&a, &alpha_f, &density, PhaseVel { x: &cx, y: &cy, z: &cz })
                };
                let sv = Vel { x: &s3[0], y: &s3[1], z: &s3[2] };
                let mv = Vel { x: &m3[0], y: &m3[1], z: &m3[2] };
                for k in 0..np {
                    let r = k * n..(k + 1) * n;
                    let v = VelMut { x: &mut vx[r.clone()], y: &mut vy[r.clone()], z: &mut vz[r.clone()] };
                    let w = VelMut { x: &mut wx[r.clone()], y: &mut wy[r.clone()], z: &mut wz[r.clone()] };
                    drift::drift_velocity(&alpha[k], sv, conservative.then_some(mv), v, w);
                }
                let (ux, uy, uz) = (phase_slices(vx, n), phase_slices(vy, n), phase_slices(vz, n));
                drift::max_drift_speed(PhaseVel { x: &ux, y: &uy, z: &uz }, n)
            };
            // The one pass.
            let mut one: [Vec<f32>; 6] = std::array::from_fn(|_| vec![f32::NAN; np * n]);
            let sums = drift::DriftSums { density: &density, porous, conservative };
            let largest_one = {
                let [vx, vy, vz, wx, wy, wz] = &mut one;
                let (u, f) = (VelMut { x: vx, y: vy, z: vz }, VelMut { x: wx, y: wy, z: wz });
                drift::drift_velocities(&inp, &a, &phases, &sums, u, f)
            };
            let case = format!(
                "{np} phases, fraction pressure {fraction_pressure}, porous {}, conservative {conservative}",
                porous.is_some()
            );
            assert_eq!(largest_one.to_bits(), largest_seq.to_bits(), "{case}: largest drift speed");
            assert!(largest_one > 0.0, "{case}: no drift");
            for (c, (o, e)) in one.iter().zip(&seq).enumerate() {
                for (j, (o, e)) in o.iter().zip(e).enumerate() {
                    assert_eq!(o.to_bits(), e.to_bits(), "{case}: output {c}, entry {j}: {o} against {e}");
                }
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 48);
}

/// Outer fractions of `np` phases summing to alpha_f < 1 (inner fluid),
/// alpha_f below the 0.01 guard on about a tenth of the `n` particles:
/// `(alpha_f, alpha)`.
fn outer_fractions(n: usize, np: usize, rng: &mut Lcg) -> (Vec<f32>, Vec<Vec<f32>>) {
    let alpha_f: Vec<f32> = (0..n).map(|_| if rng.next() < 0.1 { 0.005 } else { 0.5 + 0.5 * rng.next() }).collect();
    let alpha =
        fractions(n, np, rng).into_iter().map(|a| a.iter().zip(&alpha_f).map(|(a, f)| a * f).collect()).collect();
    (alpha_f, alpha)
}

/// `np` phases with their own densities and drift taus.
fn drifting_phases(np: usize) -> Vec<PhaseConstants> {
    (0..np)
        .map(|k| PhaseConstants { density: 800.0 + 150.0 * k as f32, tau: 1e-5 * (1.0 + k as f32), sigma: 1e-3 })
        .collect()
}

/// `drift::mixture_velocity` into new vectors: the mass- and
/// volume-weighted mean phase velocities s and m.
fn mixture_means(alpha: &[&[f32]], alpha_f: &[f32], density: &[f32], w: PhaseVel) -> ([Vec<f32>; 3], [Vec<f32>; 3]) {
    let n = alpha_f.len();
    let (mut s, mut m): ([Vec<f32>; 3], [Vec<f32>; 3]) =
        (std::array::from_fn(|_| vec![0.0; n]), std::array::from_fn(|_| vec![0.0; n]));
    let [sx, sy, sz] = &mut s;
    let [mx, my, mz] = &mut m;
    drift::mixture_velocity(alpha, alpha_f, density, w, VelMut { x: sx, y: sy, z: sz }, VelMut { x: mx, y: my, z: mz });
    (s, m)
}

/// Phase k's n values of `v` at `[k n, (k + 1) n)`, as a list.
fn phase_slices(v: &[f32], n: usize) -> Vec<&[f32]> {
    v.chunks(n).collect()
}

/// The pressure rows (pass 4c) read u* and V/m at the fluid pairs' targets
/// packed ([`FluidRows::packed`], [`WallRows::packed`]) or gathered: the
/// same sources, diagonals and scaled pairs, bit for bit.
#[test]
fn pressure_rows_read_packed_u_star_and_vm_bitwise() {
    let mut rng = Lcg(11);
    let (lat, u) = lattice_with_velocities(&mut rng);
    let n = lat.x.len();
    let vol: Vec<f32> = (0..n).map(|_| 0.9 + 0.2 * rng.next()).collect();
    let vm: Vec<f32> = (0..n).map(|_| 1e-3 * (0.9 + 0.2 * rng.next())).collect();
    let sigma: Vec<f32> = (0..n).map(|_| 0.95 + 0.1 * rng.next()).collect();
    let alpha_f = vec![1.0f32; n];
    let packed: Vec<Packed> = (0..n).map(|i| [u[0][i], u[1][i], u[2][i], vm[i]]).collect();
    // Walls: a plane of points below the lattice, querying the fluid.
    let (wx, wy, wz): (Vec<f32>, Vec<f32>, Vec<f32>) =
        (0..100).map(|k| ((k % 10) as f32, -0.8, (k / 10) as f32)).fold((vec![], vec![], vec![]), |mut a, p| {
            a.0.push(p.0);
            a.1.push(p.1);
            a.2.push(p.2);
            a
        });
    let h = 2.0;
    let mut keys = vec![0; n];
    compute_keys(&lat.x, &lat.y, &lat.z, 1.0 / h, &mut keys);
    let mut g = CellGrid::default();
    g.build(&keys, h);
    let mut bf = PairLists::default();
    let fp = Vel { x: &lat.x, y: &lat.y, z: &lat.z };
    build_pairs(&mut bf, Vel { x: &wx, y: &wy, z: &wz }, fp, &g, None, &Kernel::new(h));
    assert!(bf.pairs() > 0);
    let nw = wx.len();
    let vol_b = vec![1.0f32; nw];
    let sigma_b = vec![0.98f32; nw];
    let run = |pk: Option<&[Packed]>| {
        let (mut ff, mut fb, mut bf) = (lat.ff.clone(), PairLists::default(), bf.clone());
        fb.clear_to(n);
        let u_star = Vel { x: &u[0], y: &u[1], z: &u[2] };
        let rows = FluidRows {
            u_star,
            vol: &vol,
            vm: &vm,
            packed: pk,
            alpha_f: &alpha_f,
            sigma: &sigma,
            vol_wall: &vol_b,
            vol_solid: &[],
            u_solid: Vel { x: &[], y: &[], z: &[] },
            mobility_solid: &[],
        };
        let (mut src, mut diag) = (vec![0.0; n], vec![0.0; n]);
        iisph::fluid_setup(&mut ff, &mut fb, None, rows, 1e-3, &mut src, &mut diag);
        let rows = WallRows {
            vol: &vol_b,
            sigma: &sigma_b,
            u_star,
            vm_fluid: &vm,
            packed: pk,
            vol_fluid: &vol,
            fluid_wall_gradient: None,
        };
        let (mut src_b, mut diag_b) = (vec![0.0; nw], vec![0.0; nw]);
        iisph::wall_setup(&mut bf, rows, 1e-3, &mut src_b, &mut diag_b);
        let gx: Vec<f32> = ff.used().iter().flat_map(|b| b.gx.iter().copied()).collect();
        [src, diag, src_b, diag_b, gx]
    };
    let (a, b) = (run(None), run(Some(&packed)));
    for (k, (a, b)) in a.iter().zip(&b).enumerate() {
        assert!(a.iter().any(|&v| v != 0.0), "output {k} is all zero");
        assert!(a.iter().zip(b).all(|(p, q)| p.to_bits() == q.to_bits()), "output {k}");
    }
}

/// The mixture viscosity with its phase fractions and mu read packed
/// (`ViscosityInput::phases`, one load a pair) is bit for bit the one with
/// a gather per phase and for mu: one to three phases of random fractions
/// (some pure particles, whose weights with other phases are 0), a mu
/// that differs from particle to particle, x and u packed or not.
#[test]
fn mixture_viscosity_with_packed_phases_is_the_gathered_one_bit_for_bit() {
    let mut rng = Lcg(11);
    let (lat, u) = lattice_with_velocities(&mut rng);
    let n = lat.x.len();
    let rho: Vec<f32> = (0..n).map(|_| 800.0 + 400.0 * rng.next()).collect();
    let mu: Vec<f32> = (0..n).map(|_| 0.01 + rng.next()).collect();
    let xp: Vec<Packed> = (0..n).map(|i| [lat.x[i], lat.y[i], lat.z[i], 0.0]).collect();
    let up: Vec<Packed> = (0..n).map(|i| [u[0][i], u[1][i], u[2][i], 0.0]).collect();
    for np in 1..=3 {
        let mut alpha = fractions(n, np, &mut rng);
        for i in (0..n).step_by(7) {
            for (k, a) in alpha.iter_mut().enumerate() {
                a[i] = if k == i % np { 1.0 } else { 0.0 };
            }
        }
        let alpha: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
        let mut pk = vec![[0.0f32; 4]; n];
        let phases = drift::pack_fractions(&alpha, Some(&mu), &mut pk);
        assert!(phases.is_some());
        for packed in [None, Some([&xp[..], &up[..]])] {
            let inp = ViscosityInput { packed, ..viscosity_input(&lat, &u, &rho, &mu) };
            let run = |inp: &ViscosityInput| {
                let (mut s, mut a): ([Vec<f32>; 3], [Vec<f32>; 3]) =
                    (std::array::from_fn(|_| vec![0.0; n]), std::array::from_fn(|_| vec![0.0; n]));
                let ([sx, sy, sz], [ax, ay, az]) = (&mut s, &mut a);
                predict_velocity_mixture(inp, &alpha, VelMut { x: sx, y: sy, z: sz }, VelMut { x: ax, y: ay, z: az });
                (s, a)
            };
            let (s0, a0) = run(&inp);
            let (s1, a1) = run(&ViscosityInput { phases, ..inp });
            for c in 0..3 {
                let same = |p: &[f32], q: &[f32]| p.iter().zip(q).all(|(p, q)| p.to_bits() == q.to_bits());
                assert!(same(&s0[c], &s1[c]) && same(&a0[c], &a1[c]), "{np} phases, component {c}");
            }
            assert!(a0[0].iter().any(|&x| x != 0.0));
        }
    }
}
