#!/usr/bin/env bash
# The GPU figures in one run, for a machine with a GPU lent for a few minutes (the session's
# `device` tool; docs/benchmarks.md#gpu-figures): a relief binary built on this machine is
# carried there with the working tree, and this script writes what the README's GPU column
# needs under $OUT (or the folder given):
#   adapter.txt                  what wgpu opened (it must name the GPU, not llvmpipe)
#   antialias-SCENE.json         `relief bench antialias SCENE --frames N` at 1280x720
#   primary.json                 `relief bench primary` (the plain frame's rays, for scale)
# Usage: scripts/gpu-figures.sh [RELIEF_BINARY [OUT_DIR [FRAMES]]] (at most 6 minutes: each
# bench is cut at 100 s, the primary one at 60 s)
# A dry run on this machine (lavapipe): scripts/gpu-figures.sh target/release/relief /tmp/g 2
set -uo pipefail
bin=${1:-target/release/relief}
out=${2:-${OUT:-/tmp/relief-gpu-figures}}
frames=${3:-20}
mkdir -p "$out"
# Vulkan and EGL loaders carried as Debian packages in .gl (the device tool's notes), and the
# NVIDIA driver's ICD files where the machine has them.
if compgen -G ".gl/*.deb" >/dev/null; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
egl=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f "$icd" ] && export VK_DRIVER_FILES=$icd
[ -f "$egl" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$egl
export NODEVICE_SELECT=1 RUST_LOG=${RUST_LOG:-warn}
status=0
run() { # name, seconds, relief arguments...
    local name=$1 limit=$2
    shift 2
    echo "=== relief $*"
    if ! timeout "$limit" "$bin" "$@" --json >"$out/$name.json" 2>"$out/$name.log"; then
        echo "failed: see $name.log"
        tail -n 5 "$out/$name.log"
        status=1
    fi
}
"$bin" adapter >"$out/adapter.txt" 2>&1 || { cat "$out/adapter.txt"; exit 1; }
cat "$out/adapter.txt"
for scene in alps airfield tree; do
    run "antialias-$scene" 100 bench antialias "terrains/$scene.toml" --frames "$frames"
done
run primary 60 bench primary --frames "$frames"
# The headline figures, where the machine has a Python.
if command -v python3 >/dev/null; then
    python3 - "$out" <<'PY'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
for scene in ("alps", "airfield", "tree"):
    p = out / f"antialias-{scene}.json"
    if not p.exists():
        continue
    try:
        d = json.loads(p.read_text())["details"]
    except (ValueError, KeyError):
        print(f"{scene}: no figures (see antialias-{scene}.log)")
        continue
    cells = [f"{t['frame_ms']:.2f} ms x{t['ratio']:.2f}" for t in d["timings"]]
    rows = d["quality"]["rows"]
    print(f"{scene}: off/4/8/16/edges {' | '.join(cells)}; temporal excess off {rows[0]['temporal_excess']:.3f}, edges {rows[-1]['temporal_excess']:.3f}")
PY
fi
exit $status
