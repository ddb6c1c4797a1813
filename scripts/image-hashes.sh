#!/usr/bin/env bash
# SHA-256 of the PNG and depth TIFF of every demo scene, a dome master and a
# cylinder-3ch channel, rendered small by the given relief binary on the given
# wgpu backend. Used to show that a refactor leaves images byte-identical:
#   scripts/image-hashes.sh ./before vulkan > before-vk.txt
#   scripts/image-hashes.sh target/release/relief vulkan | diff before-vk.txt -
# Frame JSON is left out (it holds timings).
set -euo pipefail
bin=${1:?usage: image-hashes.sh RELIEF_BINARY BACKEND(vulkan|gl)}
backend=${2:?usage: image-hashes.sh RELIEF_BINARY BACKEND(vulkan|gl)}
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export WGPU_BACKEND=$backend NODEVICE_SELECT=1
run() { # name, relief arguments...
    local name=$1; shift
    "$bin" render "$@" --out "$work/$name" >/dev/null 2>"$work/$name.log" ||
        { cat "$work/$name.log" >&2; exit 1; }
    (cd "$work/$name" && sha256sum frame_0000.png depth_0000.tiff | sed "s|  |  $name/|")
}
for s in alps airfield brain clouds tree function4d; do
    run "$s" "$root/terrains/$s.toml" --size 160x120
done
run dome-master "$root/terrains/alps.toml" --size 128x128 --dome-master 180
run cylinder-3ch-1 "$root/terrains/alps.toml" \
    --display "$root/distortion/cylinder-3ch.toml" --channel 1
