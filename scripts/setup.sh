#!/usr/bin/env bash
# Installs what porosph needs on a fresh Debian machine, only if missing:
# HDF5 (frames and checkpoints), pkg-config (to find it), and a Vulkan
# driver for the GPU backend: mesa-vulkan-drivers brings the software one
# (lavapipe), so `--backend gpu` and the GPU tests run on a machine without
# a GPU (a real GPU's vendor driver is used instead where installed).
# Rust/cargo must be present (rustup).
#
# `--mpi` also installs what `cargo build --features mpi` needs (issue 19):
# MPICH (its `mpirun`, and `mpicc`, through which the `mpi` crate finds the
# library) and libclang for the crate's bindgen.
set -euo pipefail
pkgs=(libhdf5-dev pkg-config mesa-vulkan-drivers)
for arg in "$@"; do
  case "$arg" in
    --mpi) pkgs+=(mpich libmpich-dev libclang-dev) ;;
    *) echo "setup: unknown option $arg (usage: setup.sh [--mpi])" >&2; exit 2 ;;
  esac
done
need=()
for pkg in "${pkgs[@]}"; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  echo "setup: installing ${need[*]}" >&2
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need[@]}" >/dev/null
fi
command -v cargo >/dev/null || { echo "setup: cargo not found; install Rust from https://rustup.rs" >&2; exit 1; }
