//! The communication layer of distributed runs (issue 19), on P virtual
//! ranks as threads (`distributed::run_ranks`), without MPI: messages and
//! collectives, halos, migration and reductions, and the proof on a real
//! pass: the dam break's densities computed rank by rank over owned + halo
//! particles are bitwise those of the single-process step, for P = 1 to 4.

mod common;

use common::store_bits;
use porosph::builtin;
use porosph::distributed::migrate::{concat, range_of};
use porosph::distributed::{migrate, partition, reduce, run_ranks, Communicator, HaloPlan, Kind, Partition};
use porosph::pipeline::{Params, Simulation};
use porosph::scene::Scene;
use porosph::store::{FluidStore, Scratch, WallStore};
use porosph_kernels::blocks::{nblocks, sum_f64, BLOCK};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph;
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, PairLists};
use porosph_kernels::soa::Vel;
use std::time::Instant;

#[test]
fn messages_arrive_in_order_per_sender_and_tag_and_collectives_agree() {
    for size in 1..=4 {
        let out = run_ranks(size, |comm: &dyn Communicator| {
            let me = comm.rank();
            assert_eq!(comm.size(), size);
            for to in (0..size).filter(|&r| r != me) {
                comm.send_u32(to, 1, &[me as u32, 1]);
                comm.send_f32(to, 2, &[me as f32 + 0.5]);
                comm.send_u32(to, 1, &[me as u32, 2]);
                comm.send_bytes(to, 3, &[]);
            }
            // Tag 2 first: the tag-1 messages wait, in order.
            for from in (0..size).filter(|&r| r != me) {
                assert_eq!(comm.recv_f32(from, 2), [from as f32 + 0.5]);
                assert!(comm.recv_bytes(from, 3).is_empty());
                assert_eq!(comm.recv_u32(from, 1), [from as u32, 1]);
                assert_eq!(comm.recv_u32(from, 1), [from as u32, 2]);
            }
            comm.barrier();
            // Every rank a different number of values.
            let local: Vec<f64> = (0..me).map(|i| (10 * me + i) as f64).collect();
            (comm.all_gather_f64(&local), comm.all_gather_u64(&[me as u64 * 3]))
        });
        let want: Vec<f64> = (0..size).flat_map(|r| (0..r).map(move |i| (10 * r + i) as f64)).collect();
        for (g, k) in &out {
            assert_eq!(g, &want, "{size} ranks");
            assert_eq!(k, &(0..size as u64).map(|r| 3 * r).collect::<Vec<_>>());
        }
    }
}

#[test]
fn a_rank_that_fails_stops_the_others_with_its_own_message() {
    let r = std::panic::catch_unwind(|| {
        run_ranks(3, |comm: &dyn Communicator| {
            if comm.rank() == 1 {
                panic!("rank 1 gives up");
            }
            comm.recv_u32(1, 7)
        })
    });
    let e = r.expect_err("the run fails");
    let msg = e.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| e.downcast_ref::<String>().cloned());
    assert_eq!(msg.as_deref(), Some("rank 1 gives up"));
}

/// The single process's cut of n particles on whole blocks among P ranks
/// (as `partition`).
fn cuts(n: usize, ranks: usize) -> Vec<std::ops::Range<usize>> {
    let nb = nblocks(n);
    let start = |r: usize| if r == ranks { n } else { (r * nb / ranks * BLOCK).min(n) };
    (0..ranks).map(|r| start(r)..start(r + 1)).collect()
}

#[test]
fn a_global_sum_is_bitwise_the_single_process_sum_for_any_rank_count() {
    // Density errors over 5 decades, as a solve's rows have them.
    let n = 40 * BLOCK + 123;
    let err: Vec<f32> = (0..n as u64)
        .map(|i| (i.wrapping_mul(2654435761) % 1000 + 1) as f32 * 10f32.powi(-((i % 5) as i32) - 3))
        .collect();
    let mut parts = vec![0.0; nblocks(n)];
    let single = sum_f64(n, &mut parts, |i| f64::from(err[i]));
    let mut naive_differs = false;
    for ranks in 1..=4 {
        let ranges = cuts(n, ranks);
        let sums = run_ranks(ranks, |comm: &dyn Communicator| {
            let mine = &err[ranges[comm.rank()].clone()];
            let exact = reduce::global_sum(comm, &reduce::block_sums(mine.len(), |i| f64::from(mine[i])));
            // The rank's sum, then the ranks' sums: another order.
            let own: f64 = mine.iter().map(|&e| f64::from(e)).sum();
            (exact, comm.all_gather_f64(&[own]).iter().sum::<f64>())
        });
        for (exact, naive) in sums {
            assert_eq!(exact.to_bits(), single.to_bits(), "{ranks} ranks");
            naive_differs |= naive.to_bits() != single.to_bits();
        }
    }
    // The order matters: summing rank by rank does not give these bits.
    assert!(naive_differs, "per-rank sums happened to agree; pick values that show the order");
}

/// A scene set up, and its fluid store sorted as the first step's pass 0
/// sorts it (Morton key of the cell of size H, ties by index).
fn sorted(scene: Scene) -> (Simulation, FluidStore) {
    let sim = Simulation::new(scene);
    let mut keys = vec![0u64; sim.fluid.len()];
    let f = &sim.fluid;
    compute_keys(&f.x, &f.y, &f.z, 1.0 / sim.params.kernel.support, &mut keys);
    let (mut scratch, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut scratch, &mut perm);
    let mut s0 = sim.fluid.clone();
    s0.reorder(&perm, &mut Scratch::default());
    (sim, s0)
}

fn positions(x: &[f32], y: &[f32], z: &[f32]) -> [Vec<f32>; 3] {
    [x.to_vec(), y.to_vec(), z.to_vec()]
}

fn vel(p: &[Vec<f32>; 3]) -> Vel<'_> {
    Vel { x: &p[0], y: &p[1], z: &p[2] }
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

/// The ranks' densities in rank order against the single process's, bit
/// for bit, and their error sums against its `sum_f64`; prints the halo.
fn check_densities(ranks: usize, out: &[RankDensity], reference: &[f32], ms: f64) {
    let n = reference.len();
    let density: Vec<f32> = out.iter().flat_map(|r| r.density.iter().copied()).collect();
    let sigma: Vec<f32> = out.iter().flat_map(|r| r.sigma.iter().copied()).collect();
    assert_eq!(density.len(), n);
    let differ = density.iter().zip(reference).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{ranks} ranks: {differ} of {n} densities differ from the single process");
    // The reduction: the single process's sum_f64 over the gathered
    // values (the same sigma bits: one phase, rho / 1 * sigma), on every
    // rank.
    let mut parts = vec![0.0; nblocks(n)];
    let single = sum_f64(n, &mut parts, |i| f64::from((sigma[i] - 1.0).abs()));
    assert!(single > 0.0);
    for r in out {
        assert_eq!(r.error_sum.to_bits(), single.to_bits(), "{ranks} ranks: the error sum");
    }
    let rows: Vec<String> = out
        .iter()
        .map(|r| {
            let bytes = 16 * (r.sent[0] + r.sent[1]);
            format!("{}/{}, {}/{}, {bytes} B, {:.2}", r.halo[0], r.halo[1], r.sent[0], r.sent[1], r.exchange_ms)
        })
        .collect();
    eprintln!("P = {ranks}: {} ({ms:.0} ms in all)", rows.join("; "));
}

fn dam_break() -> (Simulation, FluidStore) {
    let b = builtin::find("dam_break").expect("built-in dam break");
    sorted(Scene::from_toml_str(b.text, "<built-in>").unwrap_or_else(|e| panic!("{e}")))
}

/// The owned walls of rank `r` in `part`: x, y, z and rest volume.
fn owned_walls(part: &Partition, r: usize, walls: &WallStore) -> [Vec<f32>; 4] {
    let pick = |v: &[f32]| part.ranks[r].owned[1].clone().map(|g| v[part.order[1][g] as usize]).collect();
    [pick(&walls.x), pick(&walls.y), pick(&walls.z), pick(&walls.rest_volume)]
}

#[test]
fn dam_break_densities_on_1_to_4_ranks_are_the_single_process_pass_bit_for_bit() {
    let (mut sim, s0) = dam_break();
    let walls: WallStore = sim.walls.clone();
    let (p, support) = (sim.params.clone(), sim.params.kernel.support);
    // The single process: one step; its pass 4a writes the densities at
    // the positions of `s0` (pass 0 sorts the store as `sorted` did).
    sim.step().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sim.fluid.id, s0.id, "the step's sort is the one of `sorted`");
    let fluid_pos = positions(&s0.x, &s0.y, &s0.z);
    let wall_pos = positions(&walls.x, &walls.y, &walls.z);
    let none = positions(&[], &[], &[]);
    eprintln!(
        "dam break, {} fluid + {} wall, halo from the partitioner; per rank: halo fluid/wall, sent fluid/wall, \
         bytes sent, exchange ms",
        s0.len(),
        walls.len()
    );
    for ranks in 1..=4 {
        let part: Partition = partition([vel(&fluid_pos), vel(&wall_pos), vel(&none)], support, ranks).expect("split");
        // The partition's fluid order is the sorted store's; the walls'
        // is rank by rank (the store is in key order).
        assert!(part.order[0].iter().enumerate().all(|(i, &o)| i as u32 == o));
        let t = Instant::now();
        let out = run_ranks(ranks, |comm: &dyn Communicator| {
            let r = comm.rank();
            let plan = HaloPlan::new(&part, r);
            // What the rank holds at the start of the step: its own rows.
            let fluid = range_of(&s0, part.ranks[r].owned[0].clone());
            let [wx, wy, wz, wv] = owned_walls(&part, r, &walls);
            density_pass(comm, &plan, &p, &fluid, [&wx, &wy, &wz, &wv])
        });
        check_densities(ranks, &out, &sim.fluid.density, t.elapsed().as_secs_f64() * 1e3);
    }
}

#[test]
fn dam_break_step_51_on_migrated_ranks_with_a_discovered_halo_is_the_single_process_pass() {
    let (mut sim, _) = dam_break();
    let walls: WallStore = sim.walls.clone();
    let (p, support) = (sim.params.clone(), sim.params.kernel.support);
    for _ in 0..49 {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
    }
    // Step 50 cuts the order of its pass 0 and moves the particles.
    let mut cut = sim.fluid.clone();
    resort(&mut cut, support);
    sim.step().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sim.fluid.id, cut.id);
    let moved = sim.fluid.clone();
    // Step 51: its pass 0 sorts `moved`, its pass 4a gives the densities.
    let mut sorted51 = moved.clone();
    resort(&mut sorted51, support);
    sim.step().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sim.fluid.id, sorted51.id);
    let changed = (0..moved.len()).filter(|&i| moved.id[i] != sorted51.id[i]).count();
    eprintln!("dam break, steps 50-51: {changed} of {} fluid particles change place in the order", moved.len());
    assert!(changed > 0, "nothing moved across the order");
    let cut_pos = positions(&cut.x, &cut.y, &cut.z);
    let wall_pos = positions(&walls.x, &walls.y, &walls.z);
    let none = positions(&[], &[], &[]);
    for ranks in 1..=4 {
        let part = partition([vel(&cut_pos), vel(&wall_pos), vel(&none)], support, ranks).expect("split");
        let first_keys: Vec<u64> = part.ranks.iter().map(|r| r.first_key).collect();
        let t = Instant::now();
        let out = run_ranks(ranks, |comm: &dyn Communicator| {
            let r = comm.rank();
            // The rank's rows after step 50's move, migrated (step 51's
            // pass 0); the walls stay where step 50's cut put them.
            let own = part.ranks[r].owned[0].clone();
            let mut fluid = range_of(&moved, own.clone());
            comm.barrier();
            let t = Instant::now();
            let m = migrate(comm, &mut fluid, own.start, &first_keys, support).expect("migrate");
            let ms_migrate = t.elapsed().as_secs_f64() * 1e3;
            let fidx: Vec<u32> = m.ranges[r].clone().map(|g| g as u32).collect();
            let widx: Vec<u32> = part.ranks[r].owned[1].clone().map(|g| part.order[1][g]).collect();
            let [wx, wy, wz, wv] = owned_walls(&part, r, &walls);
            let fp = positions(&fluid.x, &fluid.y, &fluid.z);
            let wp = [wx.clone(), wy.clone(), wz.clone()];
            let t = Instant::now();
            let plan = HaloPlan::discover(comm, support, [vel(&fp), vel(&wp), vel(&none)], [&fidx, &widx, &[]]);
            let ms_discover = t.elapsed().as_secs_f64() * 1e3;
            let moves = (m.routed, m.recut, ms_migrate, ms_discover);
            (density_pass(comm, &plan, &p, &fluid, [&wx, &wy, &wz, &wv]), moves)
        });
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let moves: Vec<String> =
            out.iter().map(|(_, m)| format!("{}+{} in {:.2} ms, halo found in {:.2} ms", m.0, m.1, m.2, m.3)).collect();
        eprintln!("P = {ranks}: migrated (by key + across the new cut) {}", moves.join("; "));
        if ranks > 1 {
            assert!(out.iter().any(|(_, m)| m.0 + m.1 > 0), "no particle changed rank");
        }
        let out: Vec<RankDensity> = out.into_iter().map(|o| o.0).collect();
        check_densities(ranks, &out, &sim.fluid.density, ms);
    }
}

/// Moves every particle: a shear in x and z with height, and every fifth
/// particle up by 0.25 m (far across the ranks' ranges).
fn shake(s: &mut FluidStore) {
    for i in 0..s.len() {
        let (x, y) = (s.x[i], s.y[i]);
        s.x[i] = x + 0.3 * y;
        s.z[i] -= 0.2 * x;
        if s.id[i].is_multiple_of(5) {
            s.y[i] = y + 0.25;
        }
    }
}

/// The single process's pass 0 on a moved store: sorted by key, ties by
/// index.
fn resort(s: &mut FluidStore, support: f32) {
    let mut keys = vec![0u64; s.len()];
    compute_keys(&s.x, &s.y, &s.z, 1.0 / support, &mut keys);
    let (mut scratch, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut scratch, &mut perm);
    s.reorder(&perm, &mut Scratch::default());
}

#[test]
fn migration_leaves_each_particle_on_one_rank_and_the_store_the_single_process_sort() {
    let (sim, s0) = sorted(common::scene_file("three_phase_separation.toml"));
    let support = sim.params.kernel.support;
    let (n, phases) = (s0.len(), s0.alpha.len());
    assert!(phases == 3 && nblocks(n) >= 8, "{n} particles, {phases} phases");
    // The single process, two moves.
    let mut once = s0.clone();
    shake(&mut once);
    resort(&mut once, support);
    let mut twice = once.clone();
    shake(&mut twice);
    resort(&mut twice, support);
    let volumes = |s: &FluidStore| -> Vec<u64> {
        let mut parts = vec![0.0; nblocks(s.len())];
        (0..phases).map(|k| sum_f64(s.len(), &mut parts, |i| f64::from(s.alpha[k][i])).to_bits()).collect()
    };
    let want = [volumes(&once), volumes(&twice)];
    let none = positions(&[], &[], &[]);
    for ranks in 1..=4 {
        let fluid_pos = positions(&s0.x, &s0.y, &s0.z);
        let part = partition([vel(&fluid_pos), vel(&none), vel(&none)], support, ranks).expect("split");
        let first_keys: Vec<u64> = part.ranks.iter().map(|r| r.first_key).collect();
        let out = run_ranks(ranks, |comm: &dyn Communicator| {
            let own = part.ranks[comm.rank()].owned[0].clone();
            let mut store = range_of(&s0, own.clone());
            let mut rounds = Vec::new();
            let (mut offset, mut keys) = (own.start, first_keys.clone());
            for _ in 0..2 {
                shake(&mut store);
                let m = migrate(comm, &mut store, offset, &keys, support).expect("migrate");
                let vols: Vec<u64> = (0..phases)
                    .map(|k| {
                        let a = &store.alpha[k];
                        reduce::global_sum(comm, &reduce::block_sums(a.len(), |i| f64::from(a[i]))).to_bits()
                    })
                    .collect();
                // The halo of the new owners, found by the ranks.
                let range = m.ranges[comm.rank()].clone();
                let index: Vec<u32> = range.clone().map(|g| g as u32).collect();
                let fp = positions(&store.x, &store.y, &store.z);
                let plan = HaloPlan::discover(comm, support, [vel(&fp), vel(&none), vel(&none)], [&index, &[], &[]]);
                let mut halo: Vec<u32> =
                    plan.kinds[0].index.iter().copied().filter(|&g| !range.contains(&(g as usize))).collect();
                halo.sort_unstable();
                (offset, keys) = (range.start, m.first_keys.clone());
                rounds.push((store.clone(), m, vols, halo));
            }
            rounds
        });
        for (round, single) in [&once, &twice].into_iter().enumerate() {
            let stores: Vec<FluidStore> = out.iter().map(|r| r[round].0.clone()).collect();
            // Every particle on one rank, none lost, each bit the same, in
            // the single process's order.
            let all = concat(&stores);
            let (got, want_bits) = (store_bits(&all, &WallStore::default()), store_bits(single, &WallStore::default()));
            assert_eq!(got.len(), want_bits.len());
            for ((name, a), (_, b)) in got.iter().zip(&want_bits) {
                assert!(a == b, "{ranks} ranks, move {}: {name} differs from the single process", round + 1);
            }
            let mut ids = all.id.clone();
            ids.sort_unstable();
            ids.dedup();
            assert_eq!(ids.len(), n, "{ranks} ranks: a particle lost or on two ranks");
            // Whole blocks, the partitioner's cut of the new order.
            let moved = positions(&single.x, &single.y, &single.z);
            let cut = partition([vel(&moved), vel(&none), vel(&none)], support, ranks).expect("split");
            let m = &out[0][round].1;
            for (r, (s, rp)) in stores.iter().zip(&cut.ranks).enumerate() {
                assert_eq!(m.ranges[r], rp.owned[0], "{ranks} ranks, rank {r}");
                assert_eq!(s.len(), rp.owned[0].len());
                assert_eq!(m.first_keys[r], rp.first_key, "{ranks} ranks, rank {r}");
                assert_eq!(rp.owned[0].start % BLOCK, 0);
            }
            // The halo the ranks found is the partitioner's.
            for (r, rp) in cut.ranks.iter().enumerate() {
                assert_eq!(out[r][round].3, rp.halo[0], "{ranks} ranks, rank {r}: the discovered halo");
            }
            // Every phase's volume: the single process's bits on every rank.
            for r in &out {
                assert_eq!(r[round].2, want[round], "{ranks} ranks, move {}: phase volumes", round + 1);
            }
            let routed: Vec<usize> = out.iter().map(|r| r[round].1.routed).collect();
            let recut: Vec<usize> = out.iter().map(|r| r[round].1.recut).collect();
            if ranks > 1 {
                assert!(routed.iter().sum::<usize>() > n / 10, "{ranks} ranks: the move should cross ranges");
            }
            eprintln!("P = {ranks}, move {}: routed {routed:?}, across the new cut {recut:?}", round + 1);
        }
    }
}
