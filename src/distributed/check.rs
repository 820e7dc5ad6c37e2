//! Self-checks of the communication layer (issue 19): the cases of the
//! in-process tests (`tests/distributed.rs`, over [`super::run_ranks`]) as
//! functions of a [`Communicator`], so that the same cases run under
//! `mpirun` over MPI (`examples/mpi_check.rs`, `scripts/test_mpi.sh`):
//! messages and collectives, the reproducible reduction, the dam break's
//! densities over a halo from the partitioner and, after a migration,
//! over a halo the ranks found, and the migration of a three-phase fluid.
//!
//! A check runs on every rank together. Every rank gathers what the ranks
//! computed and compares all of it with the single process (the
//! references below, which every process computes for itself), so every
//! rank returns the same [`Outcome`] or the same error; a failure seen by
//! one rank only (a message that came wrong) is shared by [`agree`]. The
//! [`Outcome::digest`] is an XXH64 of the gathered results (not of the
//! times): for one number of ranks it is the same over the virtual ranks
//! and over MPI.

use super::comm::{from_bytes, Communicator};
use super::migrate::{gather, migrate, range_of};
use super::{partition, reduce, HaloPlan, Kind, Partition};
use crate::builtin;
use crate::io::xxh64::Xxh64;
use crate::pipeline::{Params, Simulation};
use crate::scene::Scene;
use crate::store::{Column, FluidStore, Scratch, WallStore};
use porosph_kernels::blocks::{nblocks, sum_f64, BLOCK};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph;
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, PairLists};
use porosph_kernels::soa::Vel;
use std::time::Instant;

/// What a check found, the same on every rank.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// What it measured, for people (halo sizes, times).
    pub report: String,
    /// XXH64 of the results, gathered (module doc).
    pub digest: u64,
}

/// A check's outcome, or what failed (the same on every rank).
pub type Checked = Result<Outcome, String>;

/// `Err(what())` unless `ok`.
fn ensure(ok: bool, what: impl FnOnce() -> String) -> Result<(), String> {
    if ok {
        Ok(())
    } else {
        Err(what())
    }
}

/// Every rank's `local` result: the first failing rank's error on every
/// rank, or `Ok` on every rank.
pub fn agree(comm: &dyn Communicator, local: Result<(), String>) -> Result<(), String> {
    // An error is never empty here: "failed" stands for an empty message.
    let msg = match local {
        Ok(()) => String::new(),
        Err(e) if e.is_empty() => "failed".to_string(),
        Err(e) => e,
    };
    let all = comm.all_gather_bytes(msg.as_bytes());
    match all.iter().position(|m| !m.is_empty()) {
        Some(r) => Err(format!("rank {r} of {}: {}", comm.size(), String::from_utf8_lossy(&all[r]))),
        None => Ok(()),
    }
}

/// Values of 4 bytes each into a digest.
fn digest_words(h: &mut Xxh64, words: &[u32]) {
    h.update_words(words.len(), |i| words[i]);
}

/// Messages: of one sender and one tag in the order sent, of other tags
/// in any order, all sends posted before any receive (one of 4 MiB, beyond
/// any eager limit), then a barrier and variable-length all-gathers.
pub fn messages(comm: &dyn Communicator) -> Checked {
    let (me, size) = (comm.rank(), comm.size());
    let big = |from: usize| -> Vec<u32> { (0..1u32 << 20).map(|i| i ^ (from as u32) << 24).collect() };
    for to in (0..size).filter(|&r| r != me) {
        comm.send_u32(to, 1, &[me as u32, 1]);
        comm.send_f32(to, 2, &[me as f32 + 0.5]);
        comm.send_u32(to, 1, &[me as u32, 2]);
        comm.send_bytes(to, 3, &[]);
        comm.send_u32(to, 4, &big(me));
    }
    let mut local = Ok(());
    // Tag 2 first: the tag-1 messages wait, in order; the big one last.
    for from in (0..size).filter(|&r| r != me) {
        let got = (comm.recv_f32(from, 2), comm.recv_bytes(from, 3), comm.recv_u32(from, 1), comm.recv_u32(from, 1));
        let ok =
            got.0 == [from as f32 + 0.5] && got.1.is_empty() && got.2 == [from as u32, 1] && got.3 == [from as u32, 2];
        let big_ok = comm.recv_u32(from, 4) == big(from);
        if local.is_ok() && !(ok && big_ok) {
            local = Err(format!("the messages from rank {from} came as {got:?} (the 4 MiB one right: {big_ok})"));
        }
    }
    comm.barrier();
    // Every rank a different number of values.
    let mine: Vec<f64> = (0..me).map(|i| (10 * me + i) as f64).collect();
    let (g, k) = (comm.all_gather_f64(&mine), comm.all_gather_u64(&[me as u64 * 3]));
    let want: Vec<f64> = (0..size).flat_map(|r| (0..r).map(move |i| (10 * r + i) as f64)).collect();
    if local.is_ok() && (g != want || k != (0..size as u64).map(|r| 3 * r).collect::<Vec<_>>()) {
        local = Err(format!("all-gathers gave {g:?} and {k:?}"));
    }
    agree(comm, local)?;
    let mut h = Xxh64::default();
    h.update(bytemuck::cast_slice(&g));
    h.update(bytemuck::cast_slice(&k));
    Ok(Outcome { report: format!("P = {size}: messages in order, {} values gathered", g.len()), digest: h.finish() })
}

/// The single process's cut of n particles on whole blocks among P ranks
/// (as `partition`).
pub fn cuts(n: usize, ranks: usize) -> Vec<std::ops::Range<usize>> {
    let nb = nblocks(n);
    let start = |r: usize| if r == ranks { n } else { (r * nb / ranks * BLOCK).min(n) };
    (0..ranks).map(|r| start(r)..start(r + 1)).collect()
}

/// What [`global_sum`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct GlobalSum {
    /// The digest is of the exact sum's bits and the rank-by-rank sum's.
    pub outcome: Outcome,
    /// Whether the sum rank by rank, then over the ranks, happened to give
    /// the single process's bits too (it should not for every P).
    pub naive_agrees: bool,
}

/// The reproducible reduction of density errors over 5 decades (as a
/// solve's rows have them), cut among the ranks on whole blocks: bitwise
/// the single process's `sum_f64`.
pub fn global_sum(comm: &dyn Communicator) -> Result<GlobalSum, String> {
    let n = 40 * BLOCK + 123;
    let err: Vec<f32> = (0..n as u64)
        .map(|i| (i.wrapping_mul(2654435761) % 1000 + 1) as f32 * 10f32.powi(-((i % 5) as i32) - 3))
        .collect();
    let mut parts = vec![0.0; nblocks(n)];
    let single = sum_f64(n, &mut parts, |i| f64::from(err[i]));
    let mine = &err[cuts(n, comm.size())[comm.rank()].clone()];
    let exact = reduce::global_sum(comm, &reduce::block_sums(mine.len(), |i| f64::from(mine[i])));
    // The rank's sum, then the ranks' sums: another order.
    let own: f64 = mine.iter().map(|&e| f64::from(e)).sum();
    let naive: f64 = comm.all_gather_f64(&[own]).iter().sum();
    let local = ensure(exact.to_bits() == single.to_bits(), || format!("the sum {exact:e}, single {single:e}"));
    agree(comm, local)?;
    let mut h = Xxh64::default();
    h.update(&exact.to_bits().to_le_bytes());
    h.update(&naive.to_bits().to_le_bytes());
    let report = format!("P = {}: sum {exact:e} (rank by rank {naive:e})", comm.size());
    Ok(GlobalSum { outcome: Outcome { report, digest: h.finish() }, naive_agrees: naive.to_bits() == single.to_bits() })
}

/// A scene set up, and its fluid store sorted as the first step's pass 0
/// sorts it (Morton key of the cell of size H, ties by index).
fn sorted(scene: Scene) -> (Simulation, FluidStore) {
    let sim = Simulation::new(scene);
    let mut s0 = sim.fluid.clone();
    resort(&mut s0, sim.params.kernel.support);
    (sim, s0)
}

/// The single process's pass 0 on a moved store: sorted by key, ties by
/// index.
pub fn resort(s: &mut FluidStore, support: f32) {
    let mut keys = vec![0u64; s.len()];
    compute_keys(&s.x, &s.y, &s.z, 1.0 / support, &mut keys);
    let (mut scratch, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut scratch, &mut perm);
    s.reorder(&perm, &mut Scratch::default());
}

fn positions(x: &[f32], y: &[f32], z: &[f32]) -> [Vec<f32>; 3] {
    [x.to_vec(), y.to_vec(), z.to_vec()]
}

fn vel(p: &[Vec<f32>; 3]) -> Vel<'_> {
    Vel { x: &p[0], y: &p[1], z: &p[2] }
}

fn dam_break_scene() -> Scene {
    let b = builtin::find("dam_break").expect("the built-in dam break");
    Scene::from_toml_str(b.text, "<built-in>").unwrap_or_else(|e| panic!("{e}"))
}

fn step(sim: &mut Simulation) {
    sim.step().unwrap_or_else(|e| panic!("{e}"));
}

/// The built-in dam break's first step in the single process.
pub struct DamBreak {
    /// The scene's parameters (support radius, phase densities).
    pub params: Params,
    /// The fluid as the step's pass 0 sorts it.
    pub sorted: FluidStore,
    /// The walls.
    pub walls: WallStore,
    /// The densities the step's pass 4a writes (at the positions of
    /// `sorted`).
    pub density: Vec<f32>,
}

impl DamBreak {
    /// Sets the dam break up and runs its first step.
    pub fn new() -> Self {
        let (mut sim, sorted) = sorted(dam_break_scene());
        let (params, walls) = (sim.params.clone(), sim.walls.clone());
        step(&mut sim);
        assert_eq!(sim.fluid.id, sorted.id, "the step's sort is the one of `sorted`");
        DamBreak { params, sorted, walls, density: sim.fluid.density }
    }
}

impl Default for DamBreak {
    fn default() -> Self {
        Self::new()
    }
}

/// The dam break's densities on the ranks of `comm`, each over its owned
/// and halo particles (the halo from the partitioner): bitwise the single
/// process's, and the error sum its `sum_f64`.
pub fn dam_break_densities(comm: &dyn Communicator, db: &DamBreak) -> Checked {
    let (r, support) = (comm.rank(), db.params.kernel.support);
    let (s0, walls) = (&db.sorted, &db.walls);
    let (fluid_pos, wall_pos, none) =
        (positions(&s0.x, &s0.y, &s0.z), positions(&walls.x, &walls.y, &walls.z), positions(&[], &[], &[]));
    let part = partition([vel(&fluid_pos), vel(&wall_pos), vel(&none)], support, comm.size())
        .map_err(|e| format!("partition: {e}"))?;
    // The partition's fluid order is the sorted store's.
    ensure(part.order[0].iter().enumerate().all(|(i, &o)| i as u32 == o), || {
        "the fluid order is not the store's".into()
    })?;
    let plan = HaloPlan::new(&part, r);
    // What the rank holds at the start of the step: its own rows.
    let fluid = range_of(s0, part.ranks[r].owned[0].clone());
    let [wx, wy, wz, wv] = owned_walls(&part, r, walls);
    let out = density_pass(comm, &plan, &db.params, &fluid, [&wx, &wy, &wz, &wv]);
    check_densities(comm, &out, &db.density, &mut Xxh64::default())
}

/// The dam break's steps 50 and 51 in the single process.
pub struct DamBreak51 {
    /// The scene's parameters.
    pub params: Params,
    /// The walls (they never move).
    pub walls: WallStore,
    /// The fluid in step 50's pass 0 order (the ranks' cut).
    pub cut: FluidStore,
    /// The fluid after step 50, in that order (what the ranks hold).
    pub moved: FluidStore,
    /// Step 51's densities.
    pub density: Vec<f32>,
    /// Particles whose place in the order changes from step 50 to 51.
    pub changed: usize,
}

impl DamBreak51 {
    /// Runs the dam break's first 51 steps.
    pub fn new() -> Self {
        let mut sim = Simulation::new(dam_break_scene());
        let (params, walls) = (sim.params.clone(), sim.walls.clone());
        let support = params.kernel.support;
        for _ in 0..49 {
            step(&mut sim);
        }
        // Step 50 cuts the order of its pass 0 and moves the particles.
        let mut cut = sim.fluid.clone();
        resort(&mut cut, support);
        step(&mut sim);
        assert_eq!(sim.fluid.id, cut.id);
        let moved = sim.fluid.clone();
        // Step 51: its pass 0 sorts `moved`, its pass 4a gives the densities.
        let mut sorted51 = moved.clone();
        resort(&mut sorted51, support);
        step(&mut sim);
        assert_eq!(sim.fluid.id, sorted51.id);
        let changed = (0..moved.len()).filter(|&i| moved.id[i] != sorted51.id[i]).count();
        assert!(changed > 0, "nothing moved across the order");
        DamBreak51 { params, walls, cut, moved, density: sim.fluid.density, changed }
    }
}

impl Default for DamBreak51 {
    fn default() -> Self {
        Self::new()
    }
}

/// Step 51 of the dam break on the ranks: the fluid that step 50 moved,
/// migrated to its new owners, the halo found by the ranks, and the
/// densities over it: bitwise the single process's.
pub fn dam_break_step_51(comm: &dyn Communicator, d: &DamBreak51) -> Checked {
    let (r, size, support) = (comm.rank(), comm.size(), d.params.kernel.support);
    let cut_pos = positions(&d.cut.x, &d.cut.y, &d.cut.z);
    let wall_pos = positions(&d.walls.x, &d.walls.y, &d.walls.z);
    let none = positions(&[], &[], &[]);
    let part =
        partition([vel(&cut_pos), vel(&wall_pos), vel(&none)], support, size).map_err(|e| format!("partition: {e}"))?;
    let first_keys: Vec<u64> = part.ranks.iter().map(|r| r.first_key).collect();
    // The rank's rows after step 50's move, migrated (step 51's pass 0);
    // the walls stay where step 50's cut put them.
    let own = part.ranks[r].owned[0].clone();
    let mut fluid = range_of(&d.moved, own.clone());
    comm.barrier();
    let t = Instant::now();
    let m = migrate(comm, &mut fluid, own.start, &first_keys, support).map_err(|e| format!("migrate: {e}"))?;
    let ms_migrate = t.elapsed().as_secs_f64() * 1e3;
    let fidx: Vec<u32> = m.ranges[r].clone().map(|g| g as u32).collect();
    let widx: Vec<u32> = part.ranks[r].owned[1].clone().map(|g| part.order[1][g]).collect();
    let [wx, wy, wz, wv] = owned_walls(&part, r, &d.walls);
    let fp = positions(&fluid.x, &fluid.y, &fluid.z);
    let wp = [wx.clone(), wy.clone(), wz.clone()];
    let t = Instant::now();
    let plan = HaloPlan::discover(comm, support, [vel(&fp), vel(&wp), vel(&none)], [&fidx, &widx, &[]]);
    let ms_discover = t.elapsed().as_secs_f64() * 1e3;
    let out = density_pass(comm, &plan, &d.params, &fluid, [&wx, &wy, &wz, &wv]);
    let moves = comm.all_gather_u64(&[m.routed as u64, m.recut as u64]);
    let ms = comm.all_gather_f64(&[ms_migrate, ms_discover]);
    ensure(size == 1 || moves.iter().any(|&c| c > 0), || "no particle changed rank".into())?;
    let mut h = Xxh64::default();
    h.update(bytemuck::cast_slice(&moves));
    let densities = check_densities(comm, &out, &d.density, &mut h)?;
    let rows: Vec<String> = (0..size)
        .map(|q| {
            format!(
                "{}+{} in {:.2} ms, halo found in {:.2} ms",
                moves[2 * q],
                moves[2 * q + 1],
                ms[2 * q],
                ms[2 * q + 1]
            )
        })
        .collect();
    let report = format!(
        "P = {size}: {} of {} particles change place; migrated (by key + across the new cut) {}\n{}",
        d.changed,
        d.moved.len(),
        rows.join("; "),
        densities.report
    );
    Ok(Outcome { report, digest: densities.digest })
}

/// What one rank of the dam break's density pass gives back.
struct RankDensity {
    density: Vec<f32>,
    sigma: Vec<f32>,
    error_sum: f64,
    halo: [usize; 2],
    sent: [usize; 2],
    exchange_ms: f64,
}

/// The owned walls of rank `r` in `part`: x, y, z and rest volume.
fn owned_walls(part: &Partition, r: usize, walls: &WallStore) -> [Vec<f32>; 4] {
    let pick = |v: &[f32]| part.ranks[r].owned[1].clone().map(|g| v[part.order[1][g] as usize]).collect();
    [pick(&walls.x), pick(&walls.y), pick(&walls.z), pick(&walls.rest_volume)]
}

/// One rank's passes up to the densities, over its owned and halo
/// particles with the single process's kernels: pass 1's phase
/// bookkeeping on the owned fluid `fluid` (rows in the plan's owned
/// order), the halo exchange (fluid positions and V0; wall positions and
/// rest volumes, `walls` = x, y, z, V0 of the owned walls), pass 0's pairs,
/// pass 2's sigma and pass 4a's output density of the owned fluid, and a
/// reduction as the solve's error test (the sum of |sigma - 1|).
fn density_pass(
    comm: &dyn Communicator,
    plan: &HaloPlan,
    p: &Params,
    fluid: &FluidStore,
    walls: [&[f32]; 4],
) -> RankDensity {
    let support = p.kernel.support;
    let (fp, wp) = (&plan.kinds[Kind::Fluid as usize], &plan.kinds[Kind::Wall as usize]);
    // Pass 1 as `pipeline::phases`: alpha_f and V0 = w(alpha_f) alpha_f h^3.
    let cell = p.cell_volume();
    let (mut alpha_f, mut v0) = (Vec::new(), Vec::new());
    for i in 0..fluid.len() {
        let mut a = 0.0f32;
        for al in &fluid.alpha {
            a += al[i];
        }
        alpha_f.push(a);
        v0.push(iisph::row_weight(a) * a * cell);
    }
    // The halo, timed from when all ranks are ready, the fastest of 5.
    let mut exchange_ms = f64::INFINITY;
    let mut exchange = || {
        comm.barrier();
        let t = Instant::now();
        let x = [&fluid.x, &fluid.y, &fluid.z].map(|c| plan.exchange(comm, Kind::Fluid, 1, c));
        let v0_local = plan.exchange(comm, Kind::Fluid, 2, &v0);
        let wx = [walls[0], walls[1], walls[2]].map(|c| plan.exchange(comm, Kind::Wall, 3, c));
        let rest = plan.exchange(comm, Kind::Wall, 4, walls[3]);
        exchange_ms = exchange_ms.min(t.elapsed().as_secs_f64() * 1e3);
        (x, v0_local, wx, rest)
    };
    let (x, v0_local, wx, rest) = (0..5).map(|_| exchange()).last().expect("5 exchanges");
    // Pass 0's pairs: FF, and FW with the walls' near-cell set.
    let (mut fgrid, mut wgrid, mut near) = (CellGrid::default(), CellGrid::default(), CellGrid::default());
    fgrid.build(&fp.keys, support);
    wgrid.build(&wp.keys, support);
    near.build(&wgrid.dilated_keys(), support);
    let (mut ff, mut fb) = (PairLists::default(), PairLists::default());
    build_pairs(&mut ff, vel(&x), vel(&x), &fgrid, None, &p.kernel);
    build_pairs(&mut fb, vel(&x), vel(&wx), &wgrid, Some(&near), &p.kernel);
    // Pass 2 for every local row (the halo's rows lack neighbours and are
    // dropped), then pass 4a's output density as `pipeline::volumes`.
    let nl = fp.local_len();
    let (mut sigma, mut vol) = (vec![0.0f32; nl], vec![0.0f32; nl]);
    iisph::fluid_volumes(iisph::FluidSums::Pairs(&ff), &fb, None, &v0_local, &rest, &mut sigma, &mut vol);
    let sigma = plan.owned_of(Kind::Fluid, &sigma);
    let density: Vec<f32> = (0..fluid.len())
        .map(|i| {
            let mut outer = 0.0f32;
            for (al, rho) in fluid.alpha.iter().zip(&p.phase_density) {
                outer += al[i] * rho;
            }
            assert!(alpha_f[i] > 0.0);
            outer / alpha_f[i] * sigma[i]
        })
        .collect();
    let parts = reduce::block_sums(sigma.len(), |i| f64::from((sigma[i] - 1.0).abs()));
    let error_sum = reduce::global_sum(comm, &parts);
    RankDensity {
        density,
        sigma,
        error_sum,
        halo: [fp.halo_len(), wp.halo_len()],
        sent: [fp.sent_len(), wp.sent_len()],
        exchange_ms,
    }
}

/// Every rank's `f32` values in rank order, on every rank.
fn gather_f32(comm: &dyn Communicator, v: &[f32]) -> Vec<f32> {
    comm.all_gather_bytes(bytemuck::cast_slice(v)).iter().flat_map(|b| from_bytes::<f32>(b)).collect()
}

/// The ranks' densities in rank order against the single process's, bit
/// for bit, and their error sums against its `sum_f64`; the report is the
/// halo's size and exchange time per rank. `h` takes the results.
fn check_densities(comm: &dyn Communicator, out: &RankDensity, reference: &[f32], h: &mut Xxh64) -> Checked {
    let (n, ranks) = (reference.len(), comm.size());
    let density = gather_f32(comm, &out.density);
    let sigma = gather_f32(comm, &out.sigma);
    let sums = comm.all_gather_u64(&[out.error_sum.to_bits()]);
    let counts = comm.all_gather_u64(&[out.halo[0], out.halo[1], out.sent[0], out.sent[1]].map(|c| c as u64));
    let ms = comm.all_gather_f64(&[out.exchange_ms]);
    ensure(density.len() == n, || format!("{} densities of {n}", density.len()))?;
    let differ = density.iter().zip(reference).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    ensure(differ == 0, || format!("{differ} of {n} densities differ from the single process"))?;
    // The reduction: the single process's sum_f64 over the gathered values
    // (the same sigma bits: one phase, rho / 1 * sigma), on every rank.
    let mut parts = vec![0.0; nblocks(n)];
    let single = sum_f64(n, &mut parts, |i| f64::from((sigma[i] - 1.0).abs()));
    ensure(single > 0.0, || "the error sum is zero".into())?;
    for (r, &s) in sums.iter().enumerate() {
        ensure(s == single.to_bits(), || format!("rank {r}'s error sum {:e}, single {single:e}", f64::from_bits(s)))?;
    }
    digest_words(h, bytemuck::cast_slice(&density));
    h.update(bytemuck::cast_slice(&sums));
    h.update(bytemuck::cast_slice(&counts));
    let rows: Vec<String> = (0..ranks)
        .map(|q| {
            let c = &counts[4 * q..4 * q + 4];
            let bytes = 16 * (c[2] + c[3]);
            format!("{}/{}, {}/{}, {bytes} B, {:.2}", c[0], c[1], c[2], c[3], ms[q])
        })
        .collect();
    let report = format!(
        "P = {ranks}: {n} fluid; per rank halo fluid/wall, sent fluid/wall, bytes sent, exchange ms: {}",
        rows.join("; ")
    );
    Ok(Outcome { report, digest: h.finish() })
}

/// Moves every particle: a shear in x and z with height, and every fifth
/// particle up by 0.25 m (far across the ranks' ranges).
pub fn shake(s: &mut FluidStore) {
    for i in 0..s.len() {
        let (x, y) = (s.x[i], s.y[i]);
        s.x[i] = x + 0.3 * y;
        s.z[i] -= 0.2 * x;
        if s.id[i].is_multiple_of(5) {
            s.y[i] = y + 0.25;
        }
    }
}

/// Every registered column of a fluid store as raw bits, by name
/// (per-phase columns one entry per phase).
pub fn column_bits(s: &FluidStore) -> Vec<(String, Vec<u32>)> {
    let mut out = Vec::new();
    s.for_each_column(|name, _, c| match c {
        Column::F32(v) => out.push((name.to_string(), v.iter().map(|x| x.to_bits()).collect())),
        Column::U32(v) => out.push((name.to_string(), v.to_vec())),
        Column::PerPhase(vs) => {
            for (k, v) in vs.iter().enumerate() {
                out.push((format!("{name}[{k}]"), v.iter().map(|x| x.to_bits()).collect()));
            }
        }
    });
    out
}

/// A three-phase fluid moved twice (by [`shake`]) in the single process.
pub struct ThreePhase {
    /// The support radius H, m.
    pub support: f32,
    /// The fluid as the first step's pass 0 sorts it.
    pub sorted: FluidStore,
    /// After one and two moves, each sorted by pass 0.
    pub moved: [FluidStore; 2],
    /// Every phase's volume (the sum of its alpha by `sum_f64`) after each
    /// move, as bits.
    pub volumes: [Vec<u64>; 2],
}

impl ThreePhase {
    /// From a scene of three phases and at least 8 cache blocks of fluid
    /// (`scenes/three_phase_separation.toml`).
    pub fn new(scene: Scene) -> Self {
        let (sim, sorted) = sorted(scene);
        let support = sim.params.kernel.support;
        let (n, phases) = (sorted.len(), sorted.alpha.len());
        assert!(phases == 3 && nblocks(n) >= 8, "{n} particles, {phases} phases");
        let mut once = sorted.clone();
        shake(&mut once);
        resort(&mut once, support);
        let mut twice = once.clone();
        shake(&mut twice);
        resort(&mut twice, support);
        let volumes = |s: &FluidStore| -> Vec<u64> {
            let mut parts = vec![0.0; nblocks(s.len())];
            (0..phases).map(|k| sum_f64(s.len(), &mut parts, |i| f64::from(s.alpha[k][i])).to_bits()).collect()
        };
        let volumes = [volumes(&once), volumes(&twice)];
        ThreePhase { support, sorted, moved: [once, twice], volumes }
    }
}

/// Two migrations of the three-phase fluid after [`shake`]: every
/// particle on one rank, each bit as in the single process's sorted store
/// and in its order, the ranges the partitioner's cut on whole blocks, the
/// halo the ranks find the partitioner's, and every phase's volume the
/// single process's bits on every rank.
pub fn migration(comm: &dyn Communicator, t: &ThreePhase) -> Checked {
    let (me, size, support) = (comm.rank(), comm.size(), t.support);
    let n = t.sorted.len();
    let none = positions(&[], &[], &[]);
    let fluid_pos = positions(&t.sorted.x, &t.sorted.y, &t.sorted.z);
    let part = partition([vel(&fluid_pos), vel(&none), vel(&none)], support, size).map_err(|e| format!("{e}"))?;
    let own = part.ranks[me].owned[0].clone();
    let mut store = range_of(&t.sorted, own.clone());
    let (mut offset, mut keys): (usize, Vec<u64>) = (own.start, part.ranks.iter().map(|r| r.first_key).collect());
    let mut h = Xxh64::default();
    let mut report = Vec::new();
    for (round, single) in t.moved.iter().enumerate() {
        let mv = round + 1;
        shake(&mut store);
        let m = migrate(comm, &mut store, offset, &keys, support).map_err(|e| format!("migrate: {e}"))?;
        let vols: Vec<u64> = (0..store.alpha.len())
            .map(|k| {
                let a = &store.alpha[k];
                reduce::global_sum(comm, &reduce::block_sums(a.len(), |i| f64::from(a[i]))).to_bits()
            })
            .collect();
        // The halo of the new owners, found by the ranks.
        let range = m.ranges[me].clone();
        let index: Vec<u32> = range.clone().map(|g| g as u32).collect();
        let fp = positions(&store.x, &store.y, &store.z);
        let plan = HaloPlan::discover(comm, support, [vel(&fp), vel(&none), vel(&none)], [&index, &[], &[]]);
        let mut halo: Vec<u32> =
            plan.kinds[0].index.iter().copied().filter(|&g| !range.contains(&(g as usize))).collect();
        halo.sort_unstable();
        (offset, keys) = (range.start, m.first_keys.clone());
        // Every particle on one rank, none lost, each bit the same, in the
        // single process's order.
        let all = gather(comm, &store);
        let (got, want) = (column_bits(&all), column_bits(single));
        ensure(got.len() == want.len(), || "other columns".into())?;
        for ((name, a), (_, b)) in got.iter().zip(&want) {
            ensure(a == b, || format!("move {mv}: {name} differs from the single process"))?;
        }
        let mut ids = all.id.clone();
        ids.sort_unstable();
        ids.dedup();
        ensure(ids.len() == n, || format!("move {mv}: a particle lost or on two ranks"))?;
        // Whole blocks, the partitioner's cut of the new order.
        let moved = positions(&single.x, &single.y, &single.z);
        let cut = partition([vel(&moved), vel(&none), vel(&none)], support, size).map_err(|e| format!("{e}"))?;
        for (r, rp) in cut.ranks.iter().enumerate() {
            ensure(
                m.ranges[r] == rp.owned[0] && m.first_keys[r] == rp.first_key && rp.owned[0].start % BLOCK == 0,
                || format!("move {mv}: rank {r}'s range {:?} (cut {:?})", m.ranges[r], rp.owned[0]),
            )?;
        }
        // The halo the ranks found is the partitioner's, every phase's
        // volume the single process's bits.
        let local = ensure(halo == cut.ranks[me].halo[0], || format!("move {mv}: the discovered halo"))
            .and_then(|()| ensure(vols == t.volumes[round], || format!("move {mv}: phase volumes")));
        agree(comm, local)?;
        let moves = comm.all_gather_u64(&[m.routed as u64, m.recut as u64]);
        let routed: Vec<u64> = moves.iter().step_by(2).copied().collect();
        let recut: Vec<u64> = moves.iter().skip(1).step_by(2).copied().collect();
        ensure(size == 1 || routed.iter().sum::<u64>() > n as u64 / 10, || "the move should cross ranges".into())?;
        for (_, bits) in &got {
            digest_words(&mut h, bits);
        }
        h.update(bytemuck::cast_slice(&moves));
        h.update(bytemuck::cast_slice(&vols));
        report.push(format!("P = {size}, move {mv}: routed {routed:?}, across the new cut {recut:?}"));
    }
    Ok(Outcome { report: report.join("\n"), digest: h.finish() })
}

/// The single-process references of every check, computed once per
/// process.
pub struct References {
    pub dam_break: DamBreak,
    pub step_51: DamBreak51,
    pub three_phase: ThreePhase,
}

impl References {
    /// `three_phase`: `scenes/three_phase_separation.toml`.
    pub fn new(three_phase: Scene) -> Self {
        References { dam_break: DamBreak::new(), step_51: DamBreak51::new(), three_phase: ThreePhase::new(three_phase) }
    }
}

/// Every check in turn, by name, on every rank together; stops at the
/// first that fails (on every rank).
pub fn self_check(comm: &dyn Communicator, refs: &References) -> Result<Vec<(&'static str, Outcome)>, String> {
    let named = |name: &'static str, c: Checked| c.map(|o| (name, o)).map_err(|e| format!("{name}: {e}"));
    Ok(vec![
        named("messages", messages(comm))?,
        named("global_sum", global_sum(comm).map(|g| g.outcome))?,
        named("dam_break_densities", dam_break_densities(comm, &refs.dam_break))?,
        named("dam_break_step_51", dam_break_step_51(comm, &refs.step_51))?,
        named("migration", migration(comm, &refs.three_phase))?,
    ])
}
