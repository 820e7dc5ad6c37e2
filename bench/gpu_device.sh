#!/usr/bin/env bash
# The GPU backend's per-pass benchmark (issue 7) on a lent GPU machine,
# in two halves, because that machine has no Rust toolchain, no package
# registry and maybe no Vulkan loader:
#
#   here:   bash bench/gpu_device.sh prepare
#           builds porosph-bench for any x86-64-v3 CPU into .device/ and
#           downloads the Vulkan loader package (libvulkan1) beside it;
#   there:  the device tool's run, carrying .device:
#           command = "bash bench/gpu_device.sh run", carry = [".device"]
#           unpacks the loader, points it at the NVIDIA driver, prints the
#           adapter, then runs the bench dam break on the GPU backend at
#           262,144 and 1,000,000 fluid particles (one and two phases, so
#           all three offloaded passes run) and on the machine's CPU for
#           reference; logs and JSON lines go to $OUT.
#
# The CPU numbers to compare with are the 2-core ones in bench/RESULTS.md
# ("GPU backend"), measured on the project machines with the same commands.
# `SPACINGS=0.05 bash bench/gpu_device.sh run` also works here (lavapipe,
# the release build of target/), as a dry run.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=.device

case "${1:-}" in
prepare)
    mkdir -p "$dir"
    grep -qx "/$dir/" .git/info/exclude 2>/dev/null || echo "/$dir/" >>.git/info/exclude
    # x86-64-v3: the lent machine's CPU is not known to have AVX-512.
    CARGO_TARGET_DIR=target/device RUSTFLAGS="-C target-cpu=x86-64-v3" \
        cargo build --release -p porosph-bench
    cp target/device/release/porosph-bench "$dir/"
    # Debug info would take most of the 64 MiB a device call may carry.
    strip "$dir/porosph-bench"
    (cd "$dir" && rm -f ./*.deb && apt-get download libvulkan1)
    ls -l "$dir"
    ;;
run)
    out="${OUT:-bench/out-device}"
    mkdir -p "$out"
    B="$dir/porosph-bench"
    [ -x "$B" ] || B=target/release/porosph-bench
    if ! ldconfig -p | grep -q libvulkan.so.1; then
        for f in "$dir"/*.deb; do dpkg -x "$f" /; done
        ldconfig
    fi
    icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    [ -f "$icd" ] && export VK_DRIVER_FILES="$icd"
    export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
    nvidia-smi -L 2>/dev/null || true
    nproc
    run() {
        local name=$1
        shift
        echo "== $name: $B $*" | tee -a "$out/log.txt"
        timeout 280 "$B" "$@" --json "$out/results.jsonl" 2>&1 | tee -a "$out/log.txt" || echo "($name failed or timed out)" | tee -a "$out/log.txt"
    }
    # SPACINGS="0.05" for a quick dry run.
    spacings=${SPACINGS:-0.015625 0.01}
    for s in $spacings; do
        run "gpu all, spacing $s" --spacing "$s" --steps 6 --warmup 2 --threads 2 --backend gpu
        run "gpu all, 2 phases, spacing $s" --spacing "$s" --steps 6 --warmup 2 --threads 2 --phases 2 --backend gpu
    done
    run "cpu (this machine), 2 phases, spacing $s" --spacing "$s" --steps 4 --warmup 1 --threads "$(nproc)" --phases 2 --backend cpu
    ;;
*)
    echo "usage: bash bench/gpu_device.sh prepare|run" >&2
    exit 2
    ;;
esac
