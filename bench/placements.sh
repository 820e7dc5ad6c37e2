#!/usr/bin/env bash
# Issue 34's placement campaign: PLACEMENTS (default 500) seeded one- and
# two-body scenes in a pool at d = PLACEMENTS_D m (default 0.01), each run
# PLACEMENTS_STEPS steps (default 300); prints every failure with its scene
# and exits non-zero if any failed. The generator is tests/placements.rs
# (CI runs 30 of its scenes at d = 2 cm).
#   bash bench/placements.sh
#   PLACEMENTS=50 PLACEMENTS_FIRST=101 bash bench/placements.sh
set -euo pipefail
cd "$(dirname "$0")/.."
export PLACEMENTS="${PLACEMENTS:-500}" PLACEMENTS_D="${PLACEMENTS_D:-0.01}" PLACEMENTS_STEPS="${PLACEMENTS_STEPS:-300}"
exec cargo test --release --test placements -- --ignored --nocapture --exact placement_campaign
