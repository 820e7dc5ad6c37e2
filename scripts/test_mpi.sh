#!/usr/bin/env bash
# The MPI communicator's checks (issue 19): installs MPICH and libclang if
# missing (setup.sh --mpi), builds examples/mpi_check with `--features mpi`,
# and runs the communication layer's self-checks (distributed::check: the
# cases of tests/distributed.rs, each against the single process) over MPI
# for P = 1 to 4 (`mpirun -np P`, oversubscribed where P exceeds the
# cores: MPICH allows it without flags, also as root), once without mpirun
# (one rank, MPI's singleton start), and over P virtual ranks in one
# process; the digests of the results over MPI must be those of the
# virtual ranks. Exits non-zero on any failure or mismatch.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --mpi
cargo build --release --features mpi --example mpi_check
bin="${CARGO_TARGET_DIR:-target}/release/examples/mpi_check"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# Each run well under a minute; the limit only ends a hang.
limit=300
fail=0
compare() { # what, expected file, got file
  if ! diff -u "$2" "$3"; then
    echo "test_mpi: $1: the digests differ from the virtual ranks'" >&2
    fail=1
  fi
}
for p in 1 2 3 4; do
  echo "test_mpi: P = $p, virtual ranks" >&2
  timeout "$limit" "$bin" --virtual "$p" >"$out/virtual$p"
  echo "test_mpi: P = $p, mpirun -np $p" >&2
  timeout "$limit" mpirun -np "$p" "$bin" >"$out/mpi$p"
  compare "mpirun -np $p" "$out/virtual$p" "$out/mpi$p"
done
echo "test_mpi: one rank without mpirun" >&2
timeout "$limit" "$bin" >"$out/singleton"
compare "without mpirun" "$out/virtual1" "$out/singleton"
# A rank that panics ends the run (MPI_Abort) instead of leaving the
# others waiting for it.
echo "test_mpi: rank 1 of 3 panics" >&2
rc=0
timeout 60 mpirun -np 3 "$bin" --panic-on-rank 1 >/dev/null 2>"$out/panic" || rc=$?
if [ "$rc" -eq 0 ] || [ "$rc" -eq 124 ]; then
  echo "test_mpi: a panicking rank gave exit status $rc (0: passed, 124: hung)" >&2
  cat "$out/panic" >&2
  fail=1
fi
[ "$fail" -eq 0 ] || exit 1
echo "test_mpi: all checks passed, MPI digests equal to the virtual ranks' for P = 1 to 4" >&2
