//! A rank's local particle set: its owned particles and its halo of one
//! support radius, received from the ranks that own them (issue 19: "keeps
//! a halo of one support radius ... exchanges halo values where a pass
//! reads a neighbour's value computed in the same step").
//!
//! [`HaloPlan::new`] reads one rank's share from a [`Partition`] (the
//! partitioner's search over all positions, at setup), and
//! [`HaloPlan::discover`] finds it among the ranks themselves, as a step
//! must after [`super::migrate::migrate`]: which of its owned particles
//! each other rank needs, and how many it receives from each.
//! [`HaloPlan::exchange`] then turns the values of the owned particles of
//! a kind (positions, a value a pass computed) into the values of every
//! local particle, in the *local order*: owned and halo particles
//! together, by Morton key, ties by the index in the single process's
//! store ([`Partition::order`], for a partition made from the stores in
//! their order). That is the single process's order restricted to the
//! local particles (its stores are in key order, ties by index: the fluid
//! after pass 0's sort, the walls since setup, the solids' sorted copy),
//! so a pair search over them lists each particle's neighbours in the
//! same order, and a pass sums them in the same order, to the same bits.
//!
//! [`HaloPlan::discover`], on every rank together:
//! 1. Each rank's occupied cells (size H, every kind) go to every rank.
//! 2. Each rank sends every other rank, as candidates, its owned particles
//!    in a cell next to one the other occupies (within H of a particle
//!    means in one of the 27 cells around its cell).
//! 3. The receiver keeps the candidates closer than H to a particle it
//!    owns (`|x_i - x_j| < H` in the pair search's f32 arithmetic, the
//!    partitioner's halo rule) and tells the sender which; those are the
//!    sender's send lists from then on.
//!
//! Every rank sends to every other in steps 1-3: P^2 messages, fine for
//! the virtual ranks; an MPI run would send only to the ranks whose cells
//! touch its own.

use super::comm::{from_bytes, Communicator};
use super::partition::{sort, Kind, Partition, Sorted};
use bytemuck::Pod;
use porosph_kernels::grid::{cell_of, CellGrid};
use porosph_kernels::neighbors::compute_keys;
use porosph_kernels::soa::Vel;

/// Tags of [`HaloPlan::discover`]'s rounds (below the communicator's own),
/// one per kind from each.
const TAG_CANDIDATES: u32 = 0x4800;
const TAG_KEPT: u32 = 0x4810;

/// One kind's part of a [`HaloPlan`].
#[derive(Clone, Debug, Default)]
pub struct KindPlan {
    /// The owned particles: how many values [`HaloPlan::exchange`] takes.
    pub owned: usize,
    /// The Morton key of every local particle, in local order (ascending):
    /// what a `CellGrid` of the local particles is built from.
    pub keys: Vec<u64>,
    /// The single process's store index of every local particle, in local
    /// order (ascending among equal keys).
    pub index: Vec<u32>,
    /// The local slot of every owned particle, in owned order.
    pub owned_slots: Vec<u32>,
    /// Per local slot, where its value comes from: `i < owned` the owned
    /// particle i, else the halo particle `i - owned` in the order received
    /// (rank by rank, in each rank's send order).
    source: Vec<u32>,
    /// For each other rank that needs some: the rank and the owned
    /// particles it needs (ascending).
    send: Vec<(usize, Vec<u32>)>,
    /// For each other rank that sends some: the rank and how many.
    recv: Vec<(usize, usize)>,
}

impl KindPlan {
    /// The plan of `owned` particles (key and store index of each) and a
    /// halo (key and store index, in the order received by `recv`).
    fn new(
        owned: impl ExactSizeIterator<Item = (u64, u32)>,
        halo: impl Iterator<Item = (u64, u32)>,
        send: Vec<(usize, Vec<u32>)>,
        recv: Vec<(usize, usize)>,
    ) -> Self {
        let n = owned.len();
        let all: Vec<(u64, u32)> = owned.chain(halo).collect();
        assert_eq!(all.len() - n, recv.iter().map(|&(_, c)| c).sum::<usize>());
        // The local order: by key, ties by the single process's index.
        let mut source: Vec<u32> = (0..all.len() as u32).collect();
        source.sort_unstable_by_key(|&s| all[s as usize]);
        let mut owned_slots = vec![0u32; n];
        for (l, &s) in source.iter().enumerate() {
            if (s as usize) < n {
                owned_slots[s as usize] = l as u32;
            }
        }
        KindPlan {
            owned: n,
            keys: source.iter().map(|&s| all[s as usize].0).collect(),
            index: source.iter().map(|&s| all[s as usize].1).collect(),
            owned_slots,
            source,
            send,
            recv,
        }
    }

    /// Owned and halo particles.
    pub fn local_len(&self) -> usize {
        self.keys.len()
    }

    /// The halo particles.
    pub fn halo_len(&self) -> usize {
        self.local_len() - self.owned
    }

    /// The owned particles sent to other ranks in one exchange (a particle
    /// that two ranks need counts twice).
    pub fn sent_len(&self) -> usize {
        self.send.iter().map(|(_, s)| s.len()).sum()
    }
}

/// What one rank sends and receives to have its halo (module doc).
#[derive(Clone, Debug)]
pub struct HaloPlan {
    pub rank: usize,
    /// One per [`Kind`], in [`Kind`] order.
    pub kinds: [KindPlan; 3],
}

impl HaloPlan {
    /// Rank `rank`'s plan in `part`: it owns its ranges of the partition's
    /// orders, whose store indices are [`Partition::order`].
    pub fn new(part: &Partition, rank: usize) -> Self {
        let kinds = Kind::ALL.map(|k| {
            let ki = k as usize;
            let owned = part.ranks[rank].owned[ki].clone();
            let halo = &part.ranks[rank].halo[ki];
            let owner = |g: u32| part.ranks.partition_point(|r| r.owned[ki].end <= g as usize);
            let send = (0..part.ranks.len())
                .filter(|&d| d != rank)
                .filter_map(|d| {
                    let need: Vec<u32> = part.ranks[d].halo[ki]
                        .iter()
                        .filter(|&&g| owned.contains(&(g as usize)))
                        .map(|&g| g - owned.start as u32)
                        .collect();
                    (!need.is_empty()).then_some((d, need))
                })
                .collect();
            // The halo in global order is rank by rank: the order received.
            let mut recv: Vec<(usize, usize)> = Vec::new();
            for &g in halo {
                match recv.last_mut() {
                    Some((r, c)) if *r == owner(g) => *c += 1,
                    _ => recv.push((owner(g), 1)),
                }
            }
            let (keys, order) = (&part.keys[ki], &part.order[ki]);
            let at = |g: usize| (keys[g], order[g]);
            KindPlan::new(owned.map(at), halo.iter().map(|&g| at(g as usize)), send, recv)
        });
        HaloPlan { rank, kinds }
    }

    /// This rank's plan, found by the ranks together (module doc) from
    /// what each owns now: positions of each kind ([`Kind`] order) and the
    /// single process's store index of each particle (for the fluid after
    /// [`super::migrate::migrate`], its index in the new global order).
    pub fn discover(comm: &dyn Communicator, support: f32, owned: [Vel; 3], index: [&[u32]; 3]) -> Self {
        let (me, size) = (comm.rank(), comm.size());
        let keys: [Vec<u64>; 3] = owned.map(|p| {
            let mut k = vec![0u64; p.len()];
            compute_keys(p.x, p.y, p.z, 1.0 / support, &mut k);
            k
        });
        // 1. The occupied cells of every rank.
        let mut cells: Vec<u64> = keys.iter().flatten().copied().collect();
        cells.sort_unstable();
        cells.dedup();
        let all_cells: Vec<Vec<u64>> =
            comm.all_gather_bytes(bytemuck::cast_slice(&cells)).iter().map(|b| from_bytes(b)).collect();
        // 2. Candidates: owned particles in the cells next to another's.
        let mut candidates: Vec<[Vec<u32>; 3]> = vec![Default::default(); size];
        for to in (0..size).filter(|&r| r != me) {
            let mut grid = CellGrid::default();
            grid.build(&all_cells[to], support);
            let near = grid.dilated_keys();
            for k in Kind::ALL {
                let (ki, p) = (k as usize, &owned[k as usize]);
                let c: Vec<u32> =
                    (0..p.len() as u32).filter(|&i| near.binary_search(&keys[ki][i as usize]).is_ok()).collect();
                let pick = |v: &[f32]| c.iter().map(|&i| v[i as usize]).collect::<Vec<f32>>();
                let xyz: Vec<f32> = [pick(p.x), pick(p.y), pick(p.z)].concat();
                comm.send_f32(to, TAG_CANDIDATES + ki as u32, &xyz);
                let idx: Vec<u32> = c.iter().map(|&i| index[ki][i as usize]).collect();
                comm.send_u32(to, TAG_CANDIDATES + 3 + ki as u32, &idx);
                candidates[to][ki] = c;
            }
        }
        // 3. Keep those within H of an owned particle; tell the sender.
        let mine = owned.map(|p| sort(p, support));
        let h2 = support * support;
        let mut halo: [Vec<(u64, u32)>; 3] = Default::default();
        let mut recv: [Vec<(usize, usize)>; 3] = Default::default();
        for from in (0..size).filter(|&r| r != me) {
            for k in Kind::ALL {
                let ki = k as usize;
                let xyz = comm.recv_f32(from, TAG_CANDIDATES + ki as u32);
                let idx = comm.recv_u32(from, TAG_CANDIDATES + 3 + ki as u32);
                let n = idx.len();
                assert_eq!(xyz.len(), 3 * n, "rank {me}: candidates from rank {from}");
                let (x, y, z) = (&xyz[..n], &xyz[n..2 * n], &xyz[2 * n..]);
                let kept: Vec<u32> = (0..n as u32)
                    .filter(|&j| mine.iter().any(|s| s.near(x[j as usize], y[j as usize], z[j as usize], h2)))
                    .collect();
                let mut kj = vec![0u64; kept.len()];
                let pick = |v: &[f32]| kept.iter().map(|&j| v[j as usize]).collect::<Vec<f32>>();
                compute_keys(&pick(x), &pick(y), &pick(z), 1.0 / support, &mut kj);
                halo[ki].extend(kj.into_iter().zip(kept.iter().map(|&j| idx[j as usize])));
                if !kept.is_empty() {
                    recv[ki].push((from, kept.len()));
                }
                comm.send_u32(from, TAG_KEPT + ki as u32, &kept);
            }
        }
        // The send lists: the candidates the others kept.
        let mut send: [Vec<(usize, Vec<u32>)>; 3] = Default::default();
        for to in (0..size).filter(|&r| r != me) {
            for (ki, s) in send.iter_mut().enumerate() {
                let kept = comm.recv_u32(to, TAG_KEPT + ki as u32);
                if !kept.is_empty() {
                    s.push((to, kept.iter().map(|&c| candidates[to][ki][c as usize]).collect()));
                }
            }
        }
        let mut parts = send.into_iter().zip(recv).zip(halo).enumerate().map(|(ki, ((send, recv), halo))| {
            let owned = keys[ki].iter().copied().zip(index[ki].iter().copied());
            KindPlan::new(owned, halo.into_iter(), send, recv)
        });
        let kinds = [(); 3].map(|_| parts.next().expect("three kinds"));
        HaloPlan { rank: me, kinds }
    }

    /// The values of every local particle of kind `k` (local order) from
    /// those of this rank's owned ones: sends the owned values other ranks
    /// need, receives the halo's, with `tag`. Every rank calls it with the
    /// same kind and tag.
    pub fn exchange<T: Pod>(&self, comm: &dyn Communicator, k: Kind, tag: u32, owned: &[T]) -> Vec<T> {
        let p = &self.kinds[k as usize];
        assert_eq!(owned.len(), p.owned, "rank {}: owned {} values", self.rank, k.name());
        for (to, list) in &p.send {
            let vals: Vec<T> = list.iter().map(|&i| owned[i as usize]).collect();
            comm.send_bytes(*to, tag, bytemuck::cast_slice(&vals));
        }
        let mut halo: Vec<T> = Vec::with_capacity(p.halo_len());
        for &(from, n) in &p.recv {
            let got: Vec<T> = from_bytes(&comm.recv_bytes(from, tag));
            assert_eq!(got.len(), n, "rank {}: {} halo values from rank {from}", self.rank, k.name());
            halo.extend(got);
        }
        let n = owned.len();
        p.source.iter().map(|&s| if (s as usize) < n { owned[s as usize] } else { halo[s as usize - n] }).collect()
    }

    /// The values of the owned particles of kind `k` (owned order) out of
    /// values of every local particle (local order).
    pub fn owned_of<T: Copy>(&self, k: Kind, local: &[T]) -> Vec<T> {
        self.kinds[k as usize].owned_slots.iter().map(|&l| local[l as usize]).collect()
    }
}

impl Sorted {
    /// Whether an owned particle i has |x_i - x|^2 < h2 (computed as the
    /// partitioner and the pair search do: owned minus other).
    fn near(&self, x: f32, y: f32, z: f32, h2: f32) -> bool {
        let mut ranges = [(0u32, 0u32); 27];
        let nr = self.grid.neighbor_ranges(cell_of(x, y, z, self.grid.inv_cell), &mut ranges);
        ranges[..nr].iter().any(|&(s, e)| {
            (s as usize..e as usize).any(|i| {
                let (dx, dy, dz) = (self.x[i] - x, self.y[i] - y, self.z[i] - z);
                dx * dx + dy * dy + dz * dz < h2
            })
        })
    }
}
