//! The communication layer's self-checks (`porosph::distributed::check`)
//! over MPI, one process per rank, or over P virtual ranks in this process
//! (issue 19). Built only with `--features mpi`; `scripts/test_mpi.sh`
//! runs it for P = 1 to 4 and compares the two.
//!
//! ```text
//! cargo build --release --features mpi --example mpi_check
//! mpirun -np P target/release/examples/mpi_check     # P ranks over MPI
//! target/release/examples/mpi_check                  # one rank (MPI singleton)
//! target/release/examples/mpi_check --virtual P      # P threads, no MPI
//! mpirun -np P target/release/examples/mpi_check --panic-on-rank R
//! ```
//!
//! With `--panic-on-rank R`, rank R panics before the checks, while the
//! others wait for its messages: the run must end (`MPI_Abort`), not hang.
//!
//! Every check compares what the ranks computed with the single process
//! (bit for bit where the in-process tests do). Rank 0 prints one line per
//! check to stdout, `NAME P=P DIGEST` (the digest of the ranks' results,
//! the same over MPI and over the virtual ranks for one P), and the
//! measurements to stderr. Exits 1 if a check fails.

use porosph::distributed::check::{self_check, Outcome, References};
use porosph::distributed::{run_ranks, Communicator, MpiComm};
use porosph::scene::Scene;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        [] => over_mpi(None),
        ["--panic-on-rank", r] => match r.parse::<usize>() {
            Ok(r) => over_mpi(Some(r)),
            Err(e) => Err(format!("--panic-on-rank {r}: {e}")),
        },
        ["--virtual", p] => match p.parse::<usize>() {
            Ok(p) if p >= 1 => virtual_ranks(p),
            _ => Err(format!("--virtual {p}: a number of ranks, at least 1")),
        },
        _ => Err("usage: mpi_check [--virtual P | --panic-on-rank R]".into()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mpi_check: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The single-process references (every process computes its own).
fn references() -> Result<References, String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join("three_phase_separation.toml");
    let scene = Scene::from_file(&path).map_err(|e| e.to_string())?;
    Ok(References::new(scene))
}

/// Prints the outcomes: digests to stdout, reports to stderr.
fn print(size: usize, outcomes: &[(&str, Outcome)]) {
    for (name, o) in outcomes {
        println!("{name} P={size} {:016x}", o.digest);
        eprintln!("{name}: {}", o.report);
    }
}

fn over_mpi(panic_on: Option<usize>) -> Result<(), String> {
    let comm = MpiComm::init()?;
    let (rank, size) = (comm.rank(), comm.size());
    if panic_on == Some(rank) {
        panic!("rank {rank} panics on purpose (--panic-on-rank)");
    }
    if rank == 0 {
        eprintln!(
            "{}; {size} ranks, MPI_TAG_UB {}, {} rayon threads a rank",
            MpiComm::library_version().lines().next().unwrap_or(""),
            comm.tag_upper_bound(),
            rayon::current_num_threads()
        );
    }
    let t = Instant::now();
    let refs = references()?;
    let t_refs = t.elapsed().as_secs_f64();
    comm.barrier();
    let t = Instant::now();
    let outcomes = self_check(&comm, &refs)?;
    if rank == 0 {
        print(size, &outcomes);
        eprintln!("references {t_refs:.2} s, checks {:.2} s (rank 0)", t.elapsed().as_secs_f64());
    }
    Ok(())
}

fn virtual_ranks(size: usize) -> Result<(), String> {
    let t = Instant::now();
    let refs = references()?;
    let t_refs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let out = run_ranks(size, |comm: &dyn Communicator| self_check(comm, &refs));
    let first = out[0].clone()?;
    if let Some(r) = out.iter().position(|o| o.as_ref() != Ok(&first)) {
        return Err(format!("rank {r}'s outcome differs from rank 0's: {:?}", out[r]));
    }
    print(size, &first);
    eprintln!("references {t_refs:.2} s, checks {:.2} s ({size} virtual ranks)", t.elapsed().as_secs_f64());
    Ok(())
}
