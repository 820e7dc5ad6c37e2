//! The partitioner of distributed runs (issue 19) and its dry run
//! `porosph partition`: every particle owned exactly once, cuts on whole
//! cache blocks, the halo equal to a brute-force O(n^2) search, the
//! imbalance within one block, and the command's table and refusals.

mod common;

use common::{porosph, text};
use porosph::builtin;
use porosph::distributed::{partition, Kind, Partition, PartitionError, MAX_RANKS};
use porosph::pipeline::Simulation;
use porosph::scene::Scene;
use porosph_kernels::blocks::{nblocks, BLOCK};
use porosph_kernels::soa::Vel;

/// The built-in default scene (fluid, walls and a porous solid), set up.
fn wave_block() -> Simulation {
    let b = builtin::find(builtin::DEFAULT).expect("default scene");
    Simulation::new(Scene::from_toml_str(b.text, "<built-in>").unwrap_or_else(|e| panic!("{e}")))
}

fn split(sim: &Simulation, ranks: usize) -> Result<Partition, PartitionError> {
    let (f, w, s) = (&sim.fluid, &sim.walls, &sim.solids);
    let points =
        [Vel { x: &f.x, y: &f.y, z: &f.z }, Vel { x: &w.x, y: &w.y, z: &w.z }, Vel { x: &s.x, y: &s.y, z: &s.z }];
    partition(points, sim.params.kernel.support, ranks)
}

/// The positions of kind `k` in the partition's sorted order.
fn sorted_positions(sim: &Simulation, part: &Partition, k: Kind) -> Vec<[f32; 3]> {
    let (x, y, z) = match k {
        Kind::Fluid => (&sim.fluid.x, &sim.fluid.y, &sim.fluid.z),
        Kind::Wall => (&sim.walls.x, &sim.walls.y, &sim.walls.z),
        Kind::Solid => (&sim.solids.x, &sim.solids.y, &sim.solids.z),
    };
    part.order[k as usize].iter().map(|&i| [x[i as usize], y[i as usize], z[i as usize]]).collect()
}

#[test]
fn every_particle_is_owned_once_on_whole_blocks_within_one_block_of_the_mean() {
    let sim = wave_block();
    let nf = sim.fluid.len();
    assert!(nblocks(nf) >= 11 && !sim.solids.is_empty() && !sim.walls.is_empty());
    for ranks in [1, 2, 3, 4, 7, nblocks(nf)] {
        let part = split(&sim, ranks).expect("partition");
        assert_eq!(part.ranks.len(), ranks);
        assert_eq!(part.primary, Kind::Fluid);
        for k in Kind::ALL {
            let n = part.len(k);
            let mut order = part.order[k as usize].clone();
            order.sort_unstable();
            assert!(order.iter().enumerate().all(|(i, &o)| i as u32 == o), "{ranks} ranks: {k:?} order");
            // The ranges tile 0..n in rank order.
            let mut next = 0;
            for rp in &part.ranks {
                assert_eq!(rp.owned[k as usize].start, next, "{ranks} ranks, {k:?}");
                next = rp.owned[k as usize].end;
            }
            assert_eq!(next, n, "{ranks} ranks, {k:?}");
            // Key order within each rank; the fluid's ranges are runs of
            // keys from the rank's first to the next rank's first.
            let keys = &part.keys[k as usize];
            for (r, rp) in part.ranks.iter().enumerate() {
                let own = &keys[rp.owned[k as usize].clone()];
                assert!(own.windows(2).all(|w| w[0] <= w[1]), "{ranks} ranks, rank {r}, {k:?}");
                if k != Kind::Fluid {
                    continue;
                }
                for &key in own {
                    assert!(key >= rp.first_key, "{ranks} ranks, rank {r}");
                    if let Some(next) = part.ranks.get(r + 1) {
                        assert!(key <= next.first_key, "{ranks} ranks, rank {r}");
                    }
                }
            }
        }
        // A wall or solid particle belongs to the owner of its nearest
        // fluid particle within H, else to the last rank whose first key is
        // at most its own.
        if ranks == 4 {
            let h2 = sim.params.kernel.support * sim.params.kernel.support;
            let fluid = sorted_positions(&sim, &part, Kind::Fluid);
            let owner_of = |k: Kind, i: usize| part.ranks.iter().position(|r| r.owned[k as usize].contains(&i));
            for k in [Kind::Wall, Kind::Solid] {
                for (i, x) in sorted_positions(&sim, &part, k).into_iter().enumerate() {
                    let mut best: Option<(f32, usize)> = None;
                    for (j, f) in fluid.iter().enumerate() {
                        let (dx, dy, dz) = (x[0] - f[0], x[1] - f[1], x[2] - f[2]);
                        let d2 = dx * dx + dy * dy + dz * dz;
                        if d2 < h2 && best.is_none_or(|(b, _)| d2 < b) {
                            best = Some((d2, j));
                        }
                    }
                    let want = match best {
                        Some((_, j)) => owner_of(Kind::Fluid, j),
                        None => part.ranks.iter().rposition(|r| r.first_key <= part.keys[k as usize][i]),
                    };
                    assert_eq!(owner_of(k, i), want, "{k:?} {i} at {x:?}");
                }
            }
        }
        // Cuts of the fluid on whole blocks; at most one block over the mean.
        let mean = nf as f64 / ranks as f64;
        for rp in &part.ranks {
            assert_eq!(rp.owned[0].start % BLOCK, 0);
            assert!(!rp.owned[0].is_empty());
            assert!((rp.owned[0].len() as f64) < mean + BLOCK as f64, "{ranks} ranks: {:?}", rp.owned[0]);
        }
        assert!(part.imbalance(&[Kind::Fluid]) < 1.0 + BLOCK as f64 / mean);
        if ranks == 1 {
            assert_eq!(part.ranks[0].halo_total(), 0);
            assert_eq!(part.imbalance(&Kind::ALL), 1.0);
        } else {
            assert!(part.ranks.iter().all(|r| r.halo_total() > 0), "{ranks} ranks: a rank without halo");
        }
    }
}

/// A particle's index in its kind's order and its rank, in one partition.
type IndexAndOwner = (u32, u32);

#[test]
fn the_halo_is_every_other_ranks_particle_within_h_brute_force() {
    let sim = wave_block();
    let h = sim.params.kernel.support;
    let h2 = h * h;
    let all_ranks = [2usize, 3, 4];
    let parts: Vec<Partition> = all_ranks.iter().map(|&p| split(&sim, p).expect("partition")).collect();
    // Every particle: kind, position, and under each partition its index
    // in its kind's order and its owner (the order of walls and solids is
    // rank by rank, so it depends on the partition).
    let mut pts: Vec<(usize, [f32; 3], Vec<IndexAndOwner>)> = Vec::new();
    for k in Kind::ALL {
        let inverse: Vec<Vec<u32>> = parts
            .iter()
            .map(|p| {
                let mut inv = vec![0u32; p.len(k)];
                for (new, &old) in p.order[k as usize].iter().enumerate() {
                    inv[old as usize] = new as u32;
                }
                inv
            })
            .collect();
        let pos = sorted_positions(&sim, &parts[0], k);
        for (i, x) in pos.into_iter().enumerate() {
            let old = parts[0].order[k as usize][i] as usize;
            let at = parts
                .iter()
                .zip(&inverse)
                .map(|(p, inv)| {
                    let new = inv[old] as usize;
                    let r = p.ranks.iter().position(|r| r.owned[k as usize].contains(&new)).expect("owned");
                    (new as u32, r as u32)
                })
                .collect();
            pts.push((k as usize, x, at));
        }
    }
    let mut want: Vec<Vec<[Vec<u32>; 3]>> = all_ranks.iter().map(|&p| vec![Default::default(); p]).collect();
    for a in 0..pts.len() {
        let (ka, xa, at_a) = &pts[a];
        for (kb, xb, at_b) in &pts[a + 1..] {
            let (dx, dy, dz) = (xa[0] - xb[0], xa[1] - xb[1], xa[2] - xb[2]);
            if dx * dx + dy * dy + dz * dz >= h2 {
                continue;
            }
            for (w, (&(ia, ra), &(ib, rb))) in want.iter_mut().zip(at_a.iter().zip(at_b)) {
                if ra != rb {
                    w[ra as usize][*kb].push(ib);
                    w[rb as usize][*ka].push(ia);
                }
            }
        }
    }
    let mut halo_sizes = Vec::new();
    for ((part, w), &p) in parts.iter().zip(&mut want).zip(&all_ranks) {
        for (r, (rp, wr)) in part.ranks.iter().zip(w.iter_mut()).enumerate() {
            for k in Kind::ALL {
                let v = &mut wr[k as usize];
                v.sort_unstable();
                v.dedup();
                assert_eq!(rp.halo[k as usize], *v, "{p} ranks, rank {r}, {k:?} halo");
            }
            halo_sizes.push(rp.halo_total());
        }
    }
    assert!(halo_sizes.iter().all(|&n| n > 0), "{halo_sizes:?}");
}

#[test]
fn impossible_rank_counts_are_refused_with_what_is_possible() {
    let sim = wave_block();
    let nb = nblocks(sim.fluid.len());
    assert_eq!(split(&sim, 0).unwrap_err(), PartitionError::NoRanks);
    assert_eq!(split(&sim, MAX_RANKS + 1).unwrap_err(), PartitionError::TooManyRanks { ranks: MAX_RANKS + 1 });
    let e = split(&sim, nb + 1).unwrap_err();
    assert!(e.to_string().contains(&format!("give 1 to {nb} ranks")), "{e}");
    assert!(split(&sim, nb).is_ok());
}

#[test]
fn the_command_prints_the_table_for_the_default_scene_and_refuses_zero_ranks() {
    let r = porosph(&["partition", "--ranks", "4", "--threads", "1"]);
    let out = text(&r.stdout);
    assert!(r.status.success(), "{}{}", out, text(&r.stderr));
    assert!(out.contains("<built-in wave_block>"), "{out}");
    assert!(out.contains("halo_B/step"), "{out}");
    for rank in 0..4 {
        assert!(out.lines().any(|l| l.split_whitespace().next() == Some(&rank.to_string())), "rank {rank}: {out}");
    }
    assert!(!out.lines().any(|l| l.split_whitespace().next() == Some("4")), "{out}");
    assert!(out.contains("imbalance (max/mean owned): "), "{out}");
    assert!(out.contains("halo fraction"), "{out}");

    // The same scene at another spacing: 0.2 x 0.4 x 0.2 m of water at 2 cm.
    let r = porosph(&["partition", "dam_break", "--ranks", "2", "--spacing", "0.02", "--threads", "1"]);
    let out = text(&r.stdout);
    assert!(r.status.success(), "{}{}", out, text(&r.stderr));
    assert!(out.contains("<built-in dam_break> at --spacing 0.02: 2000 fluid + "), "{out}");
    let r = porosph(&["partition", "--ranks", "2", "--spacing", "0"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("--spacing must be > 0 m, got 0"), "{}", text(&r.stderr));

    let r = porosph(&["partition", "--ranks", "0"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("porosph: error: --ranks must be 1 to 4096, got 0"), "{}", text(&r.stderr));
    let r = porosph(&["partition", "--ranks", "4097"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("--ranks must be 1 to 4096, got 4097"), "{}", text(&r.stderr));
    let r = porosph(&["partition", "--ranks", "4096", "--threads", "1"]);
    assert_eq!(r.status.code(), Some(1));
    let err = text(&r.stderr);
    assert!(err.contains("cache block(s) of 512, and a rank owns whole blocks: give 1 to"), "{err}");
}
