"""Times Tessera against Cycles on shared scenes, side by side in one Blender
process, and writes a markdown table.

    blender -b --factory-startup --python scripts/bench_render.py -- \
        [--scenes cornell_mcguire.blend bunny_glass.blend] [--size 512] [--samples 64] \
        [--bounces 8] [--runs 3] [--out docs/RENDER_BENCHMARK.md]

Runs alternate between the engines so that load on the machine affects both
alike; figures are medians over the runs."""

import argparse
import os
import statistics
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "addon"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))

import tessera  # noqa: E402
from helpers import SCENES, open_scene, render  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--scenes", nargs="+", default=["cornell_mcguire.blend", "bunny_glass.blend"])
ap.add_argument("--size", type=int, default=512)
ap.add_argument("--samples", type=int, default=64)
ap.add_argument("--bounces", type=int, default=8)
ap.add_argument("--runs", type=int, default=3)
ap.add_argument("--out", default=os.path.join(HERE, "..", "docs", "RENDER_BENCHMARK.md"))
args = ap.parse_args(argv)

if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()
from tessera import engine  # noqa: E402

rows = []
for name in args.scenes:
    times = {"TESSERA": [], "CYCLES": []}
    stats = []
    for run in range(args.runs):
        for eng in ("TESSERA", "CYCLES"):
            scene = open_scene(name)
            scene.render.resolution_x = scene.render.resolution_y = args.size
            scene.render.resolution_percentage = 100
            t0 = time.perf_counter()
            render(scene, eng, samples=args.samples, bounces=args.bounces)
            times[eng].append(time.perf_counter() - t0)
            if eng == "TESSERA":
                stats.append(dict(engine.last_render_stats))
            print(f"bench: {name} {eng} run {run}: {times[eng][-1]:.2f} s", flush=True)
    med = {k: statistics.median(v) for k, v in times.items()}
    s = {k: statistics.median(st[k] for st in stats) for k in
         ("export_seconds", "blas_build_seconds", "tlas_build_seconds", "render_seconds", "rays_per_second")}
    rows.append((name, med["TESSERA"], med["CYCLES"], s, stats[0]["triangles"]))

cpu = os.cpu_count()
lines = [
    "# Render time: Tessera and Cycles side by side",
    "",
    f"{args.size}x{args.size}, {args.samples} samples, {args.bounces} max bounces, both engines on all {cpu} cores "
    f"(Cycles CPU, no denoising, no adaptive sampling). Wall time of the whole `bpy.ops.render.render` call "
    f"(scene sync, build, render, writing the file), median of {args.runs} runs alternating the engines "
    f"in one Blender {bpy.app.version_string} process.",
    "",
    "| scene | triangles | Tessera s | Cycles s | Cycles / Tessera | export s | BVH build s | render s | Mrays/s |",
    "|---|---|---|---|---|---|---|---|---|",
]
for name, t, c, s, tris in rows:
    lines.append(f"| {name} | {tris:,} | {t:.2f} | {c:.2f} | {c / t:.2f} | {s['export_seconds']:.3f} | "
                 f"{s['blas_build_seconds'] + s['tlas_build_seconds']:.3f} | {s['render_seconds']:.2f} | "
                 f"{s['rays_per_second'] / 1e6:.2f} |")
lines += ["", "Command:", "", "```sh",
          "blender -b --factory-startup --python scripts/bench_render.py -- " + " ".join(argv), "```", ""]
# The sections below this table ("## ...": the features study of
# scripts/bench_features.py, notes) are kept when the table is regenerated.
kept = ""
if os.path.exists(args.out):
    with open(args.out) as f:
        old = f.read()
    at = old.find("\n## ")
    kept = old[at + 1:] if at >= 0 else ""
with open(args.out, "w") as f:
    f.write("\n".join(lines) + ("\n" + kept if kept else ""))
print("\n".join(lines))
sys.stdout.flush()
os._exit(0)
