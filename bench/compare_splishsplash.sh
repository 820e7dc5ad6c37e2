#!/usr/bin/env bash
# porosph vs SPlisHSPlasH (IISPH, or DFSPH with METHOD=dfsph) on the same dam break, back to back in one run:
# same fluid particle count (63^3 = 250,047), fixed dt, density-error
# tolerance, threads and step window. Prints both results and the ratio of
# median-step particle-steps/s (porosph / SPlisHSPlasH).
#
#   bash bench/compare_splishsplash.sh            # steps 150..200, dt 1 ms, 0.1 %, 2 threads
#   STEPS=60 WARMUP=10 bash bench/compare_splishsplash.sh
#   METHOD=dfsph bash bench/compare_splishsplash.sh   # its divergence-free solver
#
# SPlisHSPlasH uses its default volume-map boundaries (BOUNDARY=2) or, with
# BOUNDARY=0, Akinci boundary particles like porosph's walls.
set -euo pipefail
cd "$(dirname "$0")/.."
STEPS=${STEPS:-200}
WARMUP=${WARMUP:-150}
THREADS=${THREADS:-2}
MAXERR_PERCENT=${MAXERR_PERCENT:-0.1}
BOUNDARY=${BOUNDARY:-2}
METHOD=${METHOD:-iisph}
case "$METHOD" in
iisph | dfsph) ;;
*)
    echo "compare_splishsplash: METHOD must be iisph or dfsph, not '$METHOD'" >&2
    exit 2
    ;;
esac
OUT=${OUT:-bench/out}
mkdir -p "$OUT"
cargo build --release -q -p porosph-bench
maxerr=$(python3 -c "print($MAXERR_PERCENT / 100)")
echo "== porosph" >&2
./target/release/porosph-bench --spacing 0.015873016 --steps "$STEPS" --warmup "$WARMUP" \
    --threads "$THREADS" --max-error "$maxerr" --dt 0.001 --json "$OUT/porosph.jsonl"
echo "== SPlisHSPlasH $METHOD" >&2
THREADS=$THREADS bash bench/peer_splishsplash.sh --method "$METHOD" --radius 0.0078125 \
    --maxerr "$MAXERR_PERCENT" --steps "$STEPS" --warmup "$WARMUP" --boundary "$BOUNDARY" \
    --json "$OUT/splishsplash.jsonl" | tee "$OUT/splishsplash.last"
python3 - "$OUT" "$METHOD" <<'PY'
import json, sys
out, method = sys.argv[1], sys.argv[2]
p = [json.loads(l) for l in open(f"{out}/porosph.jsonl")][-1]
line = [l for l in open(f"{out}/splishsplash.last") if l.startswith("RESULT ")][-1]
s = json.loads(line[len("RESULT "):])
pp = p["fluid_particles"] / p["median_s_per_step"]
ss = s["n_fluid"] / s["median_s_per_step"]
sc = s["n_fluid"] / s["median_s_clean"] if s.get("median_s_clean") else float("nan")
print(f"porosph       {p['fluid_particles']} particles, median {p['median_s_per_step']:.4f} s/step, "
      f"{pp/1e6:.3f} M particle-steps/s, {p['mean_iterations']:.2f} iterations/step")
print(f"SPlisHSPlasH {method} {s['n_fluid']} particles, median {s['median_s_per_step']:.4f} s/step "
      f"(clean steps {s.get('median_s_clean')}), {ss/1e6:.3f} M particle-steps/s, "
      f"{s['mean_iters']:.2f} iterations/step"
      + (f" + {s['mean_itersV']:.2f} divergence" if s.get("mean_itersV") is not None else "")
      + f", foreign load {s['foreign_cpu_load']}")
print(f"ratio porosph / SPlisHSPlasH {method} (median steps): {pp/ss:.2f}x  (vs its clean steps: {pp/sc:.2f}x)")
PY
