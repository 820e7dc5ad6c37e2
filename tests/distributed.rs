//! The communication layer of distributed runs (issue 19), on P virtual
//! ranks as threads (`distributed::run_ranks`), without MPI: messages and
//! collectives, halos, migration and reductions, and the proof on a real
//! pass: the dam break's densities computed rank by rank over owned + halo
//! particles are bitwise those of the single-process step, for P = 1 to 4.
//!
//! The cases live in `distributed::check`, as functions of a
//! communicator, so that `examples/mpi_check.rs` runs the same ones under
//! `mpirun` (`scripts/test_mpi.sh`).

mod common;

use porosph::distributed::check::{self, Checked, Outcome};
use porosph::distributed::{run_ranks, Communicator};

/// Runs a check on `ranks` virtual ranks: every rank the same outcome,
/// whose report is printed.
fn run_check(ranks: usize, f: impl Fn(&dyn Communicator) -> Checked + Sync) -> Outcome {
    let out = run_ranks(ranks, f);
    let first = out[0].clone().unwrap_or_else(|e| panic!("{ranks} ranks: {e}"));
    for (r, o) in out.iter().enumerate() {
        assert_eq!(o.as_ref(), Ok(&first), "{ranks} ranks: rank {r}'s outcome");
    }
    eprintln!("{}", first.report);
    first
}

#[test]
fn messages_arrive_in_order_per_sender_and_tag_and_collectives_agree() {
    for size in 1..=4 {
        run_check(size, check::messages);
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

#[test]
fn a_global_sum_is_bitwise_the_single_process_sum_for_any_rank_count() {
    let mut naive_differs = false;
    for ranks in 1..=4 {
        let out = run_ranks(ranks, check::global_sum);
        let first = out[0].clone().unwrap_or_else(|e| panic!("{ranks} ranks: {e}"));
        for o in &out {
            assert_eq!(o.as_ref(), Ok(&first), "{ranks} ranks");
        }
        naive_differs |= !first.naive_agrees;
    }
    // The order matters: summing rank by rank does not give these bits.
    assert!(naive_differs, "per-rank sums happened to agree; pick values that show the order");
}

#[test]
fn dam_break_densities_on_1_to_4_ranks_are_the_single_process_pass_bit_for_bit() {
    let db = check::DamBreak::new();
    eprintln!("dam break, halo from the partitioner");
    for ranks in 1..=4 {
        run_check(ranks, |comm: &dyn Communicator| check::dam_break_densities(comm, &db));
    }
}

#[test]
fn dam_break_step_51_on_migrated_ranks_with_a_discovered_halo_is_the_single_process_pass() {
    let d = check::DamBreak51::new();
    for ranks in 1..=4 {
        run_check(ranks, |comm: &dyn Communicator| check::dam_break_step_51(comm, &d));
    }
}

#[test]
fn migration_leaves_each_particle_on_one_rank_and_the_store_the_single_process_sort() {
    let t = check::ThreePhase::new(common::scene_file("three_phase_separation.toml"));
    for ranks in 1..=4 {
        run_check(ranks, |comm: &dyn Communicator| check::migration(comm, &t));
    }
}
