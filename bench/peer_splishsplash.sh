#!/usr/bin/env bash
# Run the SPlisHSPlasH 2.19 peer dam-break benchmark (see ../shared/peers/README.md).
#
# Usage (from the repository root):
#   bash bench/peer_splishsplash.sh --method iisph --radius 0.0078125 --maxerr 0.1 --steps 60 --warmup 10
# All arguments go to the peer script unchanged; it prints one `RESULT {json}` line.
#
# Environment:
#   SPLASH_VENV  venv holding pysplishsplash==2.19.0 (default $PWD/splash-venv; created if missing)
#   SPLASH_WORK  scenes, volume-map cache, output (default $PWD/splash-work)
#   PEER_SCRIPT  the benchmark script (default ../shared/peers/splishsplash_dambreak.py)
#   THREADS      OMP_NUM_THREADS (default 2)
#   PYTHON       interpreter used to create the venv (default python3)
set -euo pipefail

SPLASH_VENV="${SPLASH_VENV:-$PWD/splash-venv}"
export SPLASH_WORK="${SPLASH_WORK:-$PWD/splash-work}"
PEER_SCRIPT="${PEER_SCRIPT:-../shared/peers/splishsplash_dambreak.py}"
PYTHON="${PYTHON:-python3}"
GLDISPATCH=/lib/x86_64-linux-gnu/libGLdispatch.so.0
PKG="pysplishsplash==2.19.0"

if [[ ! -f "$PEER_SCRIPT" ]]; then
    echo "peer_splishsplash: peer script not found: $PEER_SCRIPT (set PEER_SCRIPT)" >&2
    exit 1
fi

# (a) venv with the pinned wheel
if [[ ! -x "$SPLASH_VENV/bin/python" ]]; then
    echo "peer_splishsplash: creating venv $SPLASH_VENV" >&2
    "$PYTHON" -m venv "$SPLASH_VENV"
fi
if ! "$SPLASH_VENV/bin/python" -m pip show pysplishsplash 2>/dev/null | grep -qx 'Version: 2.19.0'; then
    echo "peer_splishsplash: installing $PKG into $SPLASH_VENV" >&2
    "$SPLASH_VENV/bin/python" -m pip install --quiet --disable-pip-version-check "$PKG"
fi

# (b) the wheel's bundled GL dispatch segfaults unless the system one is preloaded
if [[ ! -e "$GLDISPATCH" ]]; then
    echo "peer_splishsplash: $GLDISPATCH missing, installing it with apt-get" >&2
    SUDO=""
    [[ "$(id -u)" -ne 0 ]] && SUDO="sudo"
    $SUDO apt-get update -qq
    # Debian bookworm ships libGLdispatch in libglvnd0; some releases split it out as libgldispatch0
    for pkg in libgldispatch0 libglvnd0; do
        if apt-cache show "$pkg" >/dev/null 2>&1; then
            DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "$pkg" && break
        fi
    done
    if [[ ! -e "$GLDISPATCH" ]]; then
        echo "peer_splishsplash: $GLDISPATCH still missing after apt-get" >&2
        exit 1
    fi
fi
export LD_PRELOAD="$GLDISPATCH${LD_PRELOAD:+:$LD_PRELOAD}"
export OMP_NUM_THREADS="${THREADS:-2}"

mkdir -p "$SPLASH_WORK"
# (c) run
exec "$SPLASH_VENV/bin/python" "$PEER_SCRIPT" "$@"
