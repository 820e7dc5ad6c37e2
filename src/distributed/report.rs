//! The table `porosph partition` prints: per rank the owned and halo
//! particles and the halo bytes per step, then the imbalance and the halo
//! fraction.

use super::partition::{Kind, Partition};
use super::traffic::HaloModel;
use porosph_kernels::blocks::BLOCK;
use std::fmt::Write;

/// The table for `part`, with halo bytes from `model` at `sweeps` Jacobi
/// sweeps per step.
pub fn table(part: &Partition, model: &HaloModel, sweeps: u32) -> String {
    let mut s = String::new();
    let p = part.ranks.len();
    let _ = writeln!(
        s,
        "ranks: {p}, H = {} m; cuts on whole blocks of {BLOCK} {} particles (Morton order)",
        part.support,
        part.primary.name()
    );
    let _ = writeln!(
        s,
        "{:>5} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>14}",
        "rank", "fluid", "wall", "solid", "halo_fluid", "halo_wall", "halo_solid", "halo_B/step"
    );
    let mut total_bytes = 0u64;
    let mut max_bytes = 0u64;
    for (r, rp) in part.ranks.iter().enumerate() {
        let halo = rp.halo.each_ref().map(Vec::len);
        let b = model.bytes(halo, sweeps);
        total_bytes += b;
        max_bytes = max_bytes.max(b);
        let _ = writeln!(
            s,
            "{r:>5} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {b:>14}",
            rp.owned[0].len(),
            rp.owned[1].len(),
            rp.owned[2].len(),
            halo[0],
            halo[1],
            halo[2]
        );
    }
    let sum = |k: Kind| part.ranks.iter().map(|r| r.halo[k as usize].len()).sum::<usize>();
    let _ = writeln!(
        s,
        "{:>5} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {total_bytes:>14}",
        "all",
        part.len(Kind::Fluid),
        part.len(Kind::Wall),
        part.len(Kind::Solid),
        sum(Kind::Fluid),
        sum(Kind::Wall),
        sum(Kind::Solid)
    );
    let _ = writeln!(
        s,
        "imbalance (max/mean owned): {:.4} {} (the cut kind), {:.4} fluid + solid, {:.4} all kinds",
        part.imbalance(&[part.primary]),
        part.primary.name(),
        part.imbalance(&[Kind::Fluid, Kind::Solid]),
        part.imbalance(&Kind::ALL)
    );
    let _ = writeln!(s, "halo fraction (halo particles of all ranks / particles): {:.4}", part.halo_fraction());
    let per = |k: Kind| format!("{} B + {} B/sweep", model.per_step[k as usize], model.per_sweep[k as usize]);
    let _ = writeln!(
        s,
        "halo bytes per step at {sweeps} Jacobi sweeps: {total_bytes} B in all, {max_bytes} B on the busiest rank \
         (per halo particle: fluid {}, wall {}, solid {})",
        per(Kind::Fluid),
        per(Kind::Wall),
        per(Kind::Solid)
    );
    s
}
