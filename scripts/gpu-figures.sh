#!/usr/bin/env bash
# The GPU figures in one run, for a machine with a GPU lent for a few minutes (the session's
# `device` tool; docs/benchmarks.md#gpu-figures). A relief binary built on this machine is
# carried there with the working tree, and this script writes under the output folder:
#   adapter.txt, nvidia-smi.txt  what wgpu opened (it must name the GPU, not llvmpipe)
#   NAME.json / NAME.log         each `relief bench ... --json` of the README's speed table
#   tests.log                    the GPU-against-CPU test binaries, when a folder of them is given
#   summary.txt                  the headline figures
# Usage: scripts/gpu-figures.sh [RELIEF_BINARY [OUT_DIR [FRAMES [TEST_BIN_DIR]]]]
# Each bench is cut at its own limit and the whole run at $DEADLINE seconds (default 400):
# what is left out is named in summary.txt. Test binaries (`cargo test --release --no-run`)
# run with the repository root as their working directory; they were built with
# CARGO_MANIFEST_DIR set to this machine's checkout, so that path must point at the copy.
# A dry run on this machine (lavapipe): scripts/gpu-figures.sh target/release/relief /tmp/g 2
set -uo pipefail
bin=${1:-target/release/relief}
out=${2:-${OUT:-/tmp/relief-gpu-figures}}
frames=${3:-20}
tests=${4:-}
deadline=${DEADLINE:-400}
start=$(date +%s)
mkdir -p "$out"
summary="$out/summary.txt"
: >"$summary"
say() { echo "$*" | tee -a "$summary"; }
left() { echo $((deadline - ($(date +%s) - start))); }
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
command -v nvidia-smi >/dev/null && nvidia-smi >"$out/nvidia-smi.txt" 2>&1
status=0
run() { # name, seconds, relief arguments...
    local name=$1 limit=$2 rest
    shift 2
    rest=$(left)
    if [ "$rest" -lt 10 ]; then
        say "skipped (deadline): relief $*"
        return
    fi
    [ "$limit" -gt "$rest" ] && limit=$rest
    echo "=== relief $*"
    local t0=$(date +%s)
    if ! timeout "$limit" "$bin" "$@" --json >"$out/$name.json" 2>"$out/$name.log"; then
        say "failed or cut at ${limit} s: relief $* (see $name.log)"
        tail -n 5 "$out/$name.log"
        status=1
    fi
    echo "    $(($(date +%s) - t0)) s"
}
"$bin" adapter >"$out/adapter.txt" 2>&1 || { cat "$out/adapter.txt"; exit 1; }
say "adapter: $(head -n 3 "$out/adapter.txt" | tr '\n' ' ')"
for scene in alps airfield tree; do
    run "antialias-$scene" 50 bench antialias "terrains/$scene.toml" --frames "$frames"
done
# The list of marked pixels built on the GPU (the default there) against the CPU's: the
# frame ratio, and the "edges and list" lap of --trace-passes (docs/antialiasing.md#on-a-gpu).
for scene in alps airfield; do
    run "antialias-$scene-cpu-list" 50 bench antialias "terrains/$scene.toml" --frames "$frames" --aa-list cpu
done
for list in cpu gpu cpu gpu; do
    [ "$(left)" -lt 20 ] && { say "skipped (deadline): the list laps"; break; }
    laps=$(RUST_LOG=info timeout 30 "$bin" render terrains/alps.toml --size 1280x720 --antialias edges \
        --trace-passes --frames 8 --aa-list "$list" --out "$out/laps-$list" 2>&1 |
        grep -o 'edges and list [0-9.]* ms' | tail -n 6 | grep -o '[0-9.]*' | tr '\n' ' ')
    say "alps 1280x720, --aa-list $list, edges and list (ms, frames 3-8): $laps"
done
run primary 30 bench primary
run terrain 30 bench terrain --frames 6
run freeforms 30 bench freeforms --frames 9
run volume 30 bench volume --frames 3
run voxels 30 bench voxels --frames 6
run display 30 bench display --display distortion/dome-5proj.toml --size 1920x1200 --frames 5
run soak 30 bench soak --size 160x120
run soak-1280 30 bench soak --size 1280x720 --frames 300
run db 60 bench db --size 320x180 --frames 10 --flight-frames 600 --terrain-memory 8
# The GPU-against-CPU tests on this adapter, six binaries at a time (timing does not matter
# here), each in its own log.
if [ -n "$tests" ]; then
    rest=$(left)
    if [ "$rest" -lt 20 ]; then
        say "skipped (deadline): the tests in $tests"
    else
        limit=$((rest < 150 ? rest : 150))
        mkdir -p "$out/tests"
        export limit out
        find "$tests" -maxdepth 1 -type f -perm -u+x -print0 | xargs -0 -P 6 -I{} sh -c \
            'n=$(basename "$1"); timeout "$limit" "$1" >"$out/tests/$n.log" 2>&1; echo "exit $?" >>"$out/tests/$n.log"' _ {}
        for log in "$out"/tests/*.log; do
            n=$(basename "$log" .log)
            rc=$(tail -n 1 "$log")
            [ "$rc" = "exit 0" ] || status=1
            say "test $n: $rc, $(grep -E '^test result' "$log" | tail -n 1)"
            grep -E '^test .* FAILED$|^    [a-z_]+$' "$log" | head -n 20 | tee -a "$summary"
        done
    fi
fi
# The headline figures, where the machine has a Python.
if command -v python3 >/dev/null; then
    python3 - "$out" <<'PY' | tee -a "$summary"
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
say "total $(($(date +%s) - start)) s"
exit $status
