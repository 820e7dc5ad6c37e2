//! A rank's local particle set: its owned particles and its halo of one
//! support radius, received from the ranks that own them (issue 19: "keeps
//! a halo of one support radius ... exchanges halo values where a pass
//! reads a neighbour's value computed in the same step").
//!
//! [`HaloPlan::new`] reads one rank's share from a [`Partition`]: which of
//! its owned particles each other rank needs, and how many it receives
//! from each. [`HaloPlan::exchange`] then turns the values of the owned
//! particles of a kind (positions, a value a pass computed) into the values
//! of every local particle, in the *local order*: owned and halo particles
//! together, by Morton key, ties by the index in the single process's
//! store ([`Partition::order`], for a partition made from the stores in
//! their order). That is the single process's order restricted to the local
//! particles (its stores are in key order, ties by index: the fluid after
//! pass 0's sort, the walls since setup, the solids' sorted copy), so a
//! pair search over them lists each particle's neighbours in the same
//! order, and a pass sums them in the same order, to the same bits.
//!
//! The halo comes from the partitioner's search over all positions, done
//! once; after the particles move, the halo of the new owners is not found
//! yet (a later slice: ranks exchange their occupied cells and send the
//! particles within H of the other's).

use super::comm::{from_bytes, Communicator};
use super::partition::{Kind, Partition};
use bytemuck::Pod;
use std::ops::Range;

/// One kind's part of a [`HaloPlan`].
#[derive(Clone, Debug, Default)]
pub struct KindPlan {
    /// The owned particles, a range of the kind's global order
    /// ([`Partition::order`]).
    pub owned: Range<usize>,
    /// The global index of every local particle, in local order (module doc).
    pub local: Vec<u32>,
    /// The Morton key of every local particle, in local order (ascending):
    /// what a `CellGrid` of the local particles is built from.
    pub keys: Vec<u64>,
    /// The local slot of every owned particle, in global order.
    pub owned_slots: Vec<u32>,
    /// Per local slot, where its value comes from: `i < owned.len()` the
    /// owned particle `owned.start + i`, else the halo particle
    /// `i - owned.len()` in global order (received rank by rank).
    source: Vec<u32>,
    /// For each other rank that needs some: the rank and the owned
    /// particles it needs (offsets into `owned`, ascending).
    send: Vec<(usize, Vec<u32>)>,
    /// For each other rank that sends some: the rank and how many.
    recv: Vec<(usize, usize)>,
}

impl KindPlan {
    /// The halo particles.
    pub fn halo_len(&self) -> usize {
        self.local.len() - self.owned.len()
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
    /// Rank `rank`'s plan in `part`.
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
            let mut recv: Vec<(usize, usize)> = Vec::new();
            for &g in halo {
                match recv.last_mut() {
                    Some((r, c)) if *r == owner(g) => *c += 1,
                    _ => recv.push((owner(g), 1)),
                }
            }
            // The local order: by key, ties by the single process's index.
            let (keys, order) = (&part.keys[ki], &part.order[ki]);
            let mut slots: Vec<u32> = (0..(owned.len() + halo.len()) as u32).collect();
            let global = |s: u32| {
                let s = s as usize;
                if s < owned.len() {
                    (owned.start + s) as u32
                } else {
                    halo[s - owned.len()]
                }
            };
            slots.sort_unstable_by_key(|&s| {
                let g = global(s) as usize;
                (keys[g], order[g])
            });
            let local: Vec<u32> = slots.iter().map(|&s| global(s)).collect();
            let mut owned_slots = vec![0u32; owned.len()];
            for (l, &s) in slots.iter().enumerate() {
                if (s as usize) < owned.len() {
                    owned_slots[s as usize] = l as u32;
                }
            }
            KindPlan {
                keys: local.iter().map(|&g| keys[g as usize]).collect(),
                owned,
                local,
                owned_slots,
                source: slots,
                send,
                recv,
            }
        });
        HaloPlan { rank, kinds }
    }

    /// The values of every local particle of kind `k` (local order) from
    /// those of this rank's owned ones (global order): sends the owned
    /// values other ranks need, receives the halo's, with `tag`. Every rank
    /// calls it with the same kind and tag.
    pub fn exchange<T: Pod>(&self, comm: &dyn Communicator, k: Kind, tag: u32, owned: &[T]) -> Vec<T> {
        let p = &self.kinds[k as usize];
        assert_eq!(owned.len(), p.owned.len(), "rank {}: owned {} values", self.rank, k.name());
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

    /// The values of the owned particles of kind `k` (global order) out of
    /// values of every local particle (local order).
    pub fn owned_of<T: Copy>(&self, k: Kind, local: &[T]) -> Vec<T> {
        self.kinds[k as usize].owned_slots.iter().map(|&l| local[l as usize]).collect()
    }
}
