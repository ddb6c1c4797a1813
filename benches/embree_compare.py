#!/usr/bin/env python3
"""relief vs Embree on the same primary rays (not part of `cargo test`).

Runs `relief bench terrain --json --dump-rays DIR` (1280x720 view of the real DEM by default),
builds a triangle mesh of the same height grid (2 triangles per cell) for Embree through Open3D's
RaycastingScene, casts the same rays on all CPU threads, and prints both rays/s and their depth
agreement. Triangles differ from relief's bilinear patches by up to the cell's twist, so depths
are compared with a tolerance that reflects the triangulation (1% relative).

Set-up (once): pip install open3d-cpu numpy ; Debian: apt-get install libusb-1.0-0
Usage: python3 benches/embree_compare.py [SCENE] [--size 1280x720] [--repeats 5]
"""
import argparse, json, os, subprocess, sys, tempfile, time

import numpy as np

try:
    import open3d as o3d
except ImportError:
    sys.exit("open3d is missing: pip install open3d-cpu (and apt-get install libusb-1.0-0)")

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ap = argparse.ArgumentParser()
ap.add_argument("scene", nargs="?", default=os.path.join(root, "terrains", "alps.toml"))
ap.add_argument("--size", default="1280x720")
ap.add_argument("--frames", type=int, default=10)
ap.add_argument("--repeats", type=int, default=5)
ap.add_argument("--rounds", type=int, default=5)
args = ap.parse_args()

subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=root, check=True)
exe = os.path.join(root, "target", "release", "relief")
with tempfile.TemporaryDirectory() as d:
    env = dict(os.environ, NODEVICE_SELECT="1", RUST_LOG="warn")
    out = subprocess.run([exe, "bench", "terrain", args.scene, "--size", args.size, "--frames", str(args.frames), "--json", "--dump-rays", d],
                         check=True, capture_output=True, text=True, env=env).stdout
    report = json.loads(out)
    grid = json.load(open(os.path.join(d, "grid.json")))
    rays = np.fromfile(os.path.join(d, "rays.f32"), dtype=np.float32).reshape(-1, 6)
    relief_t = np.fromfile(os.path.join(d, "depth.f32"), dtype=np.float32)
    h = np.fromfile(os.path.join(d, "heights.f32"), dtype=np.float32).reshape(grid["height"], grid["width"])

W, H = grid["width"], grid["height"]
m = np.array(grid["world_from_grid"], dtype=np.float64)  # rows
jj, ii = np.mgrid[0:H, 0:W]
g = np.stack([ii.ravel(), jj.ravel(), h.ravel().astype(np.float64), np.ones(W * H)], axis=1)
verts = (g @ m.T)[:, :3].astype(np.float32)
idx = (jj[:-1, :-1] * W + ii[:-1, :-1]).ravel()
tris = np.concatenate([np.stack([idx, idx + 1, idx + W + 1], 1), np.stack([idx, idx + W + 1, idx + W], 1)]).astype(np.uint32)

t0 = time.perf_counter()
scene = o3d.t.geometry.RaycastingScene()
scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))
scene.cast_rays(o3d.core.Tensor(rays[:16]))  # builds the BVH
build_s = time.perf_counter() - t0
rt = o3d.core.Tensor(rays)
# Alternate: relief's primary-ray median over --frames (`bench primary`), then the median of
# --repeats Embree casts.
rounds = []
for r in range(args.rounds):
    out = subprocess.run([exe, "bench", "primary", args.scene, "--size", args.size, "--frames", str(args.frames),
                          "--json"], check=True, capture_output=True, text=True, env=env).stdout
    relief_rps = json.loads(out)["details"]["rays_per_second"]
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        ans = scene.cast_rays(rt)
        times.append(time.perf_counter() - t0)
    embree_rps = len(rays) / float(np.median(times))
    rounds.append((relief_rps, embree_rps))
    print(f"round {r + 1}: relief {relief_rps / 1e6:.2f} M rays/s, Embree {embree_rps / 1e6:.2f} M rays/s, "
          f"ratio {relief_rps / embree_rps:.2f}", flush=True)
embree_t = ans["t_hit"].numpy()

n = len(rays)
both = np.isfinite(relief_t) & np.isfinite(embree_t)
rel = np.abs(relief_t[both] - embree_t[both]) / embree_t[both]
class_diff = int(np.sum(np.isfinite(relief_t) != np.isfinite(embree_t)))
relief_med = float(np.median([a for a, _ in rounds]))
embree_med = float(np.median([b for _, b in rounds]))
ratios = [a / b for a, b in rounds]
print(f"rays: {n} ({args.size}), scene {args.scene}")
pt = next(c for c in report["details"]["configs"] if c["name"] == "pyramid+tiles")
print(f"relief  ({report['adapter']}, {report['backend']}): {relief_med / 1e6:.2f} M rays/s "
      f"(median of {args.rounds} rounds; {pt['mean_steps_per_ray']:.1f} steps/ray)")
print(f"Embree  (Open3D {o3d.__version__}, {os.cpu_count()} threads): {embree_med / 1e6:.2f} M rays/s "
      f"(median of {args.rounds} rounds of {args.repeats} casts; BVH build {build_s:.2f} s not counted)")
print(f"ratio relief/Embree: {relief_med / embree_med:.2f} (medians); per round {min(ratios):.2f}-{max(ratios):.2f}, "
      f"relief ahead in {sum(r > 1 for r in ratios)} of {len(ratios)}")
print(f"depth agreement: {np.mean(rel < 0.01) * 100:.2f}% of {both.sum()} common hits within 1% "
      f"(median {np.median(rel):.2e}), hit/sky class differs on {class_diff} rays")
