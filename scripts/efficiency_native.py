"""Tessera against Cycles at each scene's own resolution and settings, where
its users render it (issue 5's efficiency target): the error of a render is
measured as the variance between renders of different seeds, which needs no
high-sample reference (a 1024-sample reference of modern_hall.blend at its
1280 x 720 takes Cycles about an hour here). Run inside Blender:

    blender -b --factory-startup --python scripts/efficiency_native.py -- \\
        /work/shared/scenes/modern_hall.blend [more .blend] [--seeds 4] \\
        [--scene-seeds bunny_glass.blend=12 modern_hall.blend=3] \\
        [--tessera-ladder 32 48 64] [--cycles-samples 64] [--bounces 8] [--width 0] \\
        [--out docs/convergence/native]

Per scene and engine, every sample count is rendered with seeds 0..N-1 (the
engines taking turns, their order alternating per seed, so that machine load
hits both alike). A point's MSE is the per-pixel variance across its seeds
(unbiased, ddof 1), averaged over pixels and channels: the expected squared
error of one render against the true image, for an unbiased renderer (its
bias is checked below). Time: the median wall time of the whole render call
(export/sync, BVH, render, EXR write). Efficiency Tessera/Cycles = Cycles' time
at its sample count / the time Tessera needs for Cycles' MSE, read off
Tessera's ladder in log-log (efficiency.time_for_mse), as in
scripts/convergence.py.

Bias check: the two engines' mean images over the seeds differ by the
systematic difference between them plus their noise (V_T / N + V_C / N); the
table gives the RMS of that difference with the noise taken out, over the RMS
error of one Cycles render (0: the engines agree as closely as the seeds can
tell; a bias of either engine, or a difference in what they model, shows as
more).

Writes OUT/README.md (tables and the command) and OUT/efficiency_native.csv."""

import argparse
import csv
import math
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("scenes", nargs="+")
ap.add_argument("--seeds", type=int, default=4, help="renders per point (seeds 0..N-1); at least 2")
ap.add_argument("--scene-seeds", nargs="*", default=[], metavar="NAME=N",
                help="another seed count for a scene (file name), e.g. bunny_glass.blend=12: a scene whose error is "
                     "a few rare bright samples (caustics) needs more seeds for its variance to settle")
ap.add_argument("--tessera-ladder", type=int, nargs="+", default=[32, 48, 64])
ap.add_argument("--cycles-samples", type=int, default=64)
ap.add_argument("--bounces", type=int, default=8)
ap.add_argument("--width", type=int, default=0, help="0: the scene's own resolution (and percentage)")
ap.add_argument("--addon", default=os.path.join(HERE, "..", "addon"), help="folder holding the tessera add-on")
ap.add_argument("--out", default=os.path.join(HERE, "..", "docs", "convergence", "native"))
args = ap.parse_args(argv)
SCENE_SEEDS = dict((k, int(v)) for k, v in (x.split("=", 1) for x in args.scene_seeds))
if min([args.seeds] + list(SCENE_SEEDS.values())) < 2:
    ap.error("--seeds and --scene-seeds must be at least 2: the error is the variance between seeds")
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
sys.path.insert(0, args.addon)
sys.path.insert(0, HERE)

import tessera  # noqa: E402
from helpers import render, set_size  # noqa: E402
from efficiency import cpu_name, time_for_mse  # noqa: E402

if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()
from tessera import engine  # noqa: E402

os.makedirs(args.out, exist_ok=True)
CPU = cpu_name()
LADDERS = {"TESSERA": args.tessera_ladder, "CYCLES": [args.cycles_samples]}


class Point:
    """One engine at one sample count over the seeds: running sums of the pixels and their squares."""

    def __init__(self):
        self.n, self.sum, self.sum_sq, self.walls, self.estimates = 0, None, None, [], []

    def add(self, img, wall, estimate):
        if self.sum is None:
            self.sum, self.sum_sq = np.zeros_like(img), np.zeros_like(img)
        self.n += 1
        self.sum += img
        self.sum_sq += img * img
        self.walls.append(wall)
        if estimate is not None:
            self.estimates.append(estimate)

    def mean_image(self):
        return self.sum / self.n

    def mse(self):
        """Mean over pixels and channels of the per-pixel variance across seeds (ddof 1)."""
        m = self.mean_image()
        return float(np.maximum(self.sum_sq - self.n * m * m, 0.0).mean() / (self.n - 1))

    def seconds(self):
        return float(np.median(self.walls))


rows, summary = [], []
for path in args.scenes:
    name = os.path.basename(path)
    points = {eng: {spp: Point() for spp in ladder} for eng, ladder in LADDERS.items()}
    size = None
    for seed in range(SCENE_SEEDS.get(name, args.seeds)):
        for eng in ("TESSERA", "CYCLES") if seed % 2 == 0 else ("CYCLES", "TESSERA"):
            for spp in LADDERS[eng]:
                bpy.ops.wm.open_mainfile(filepath=path)
                scene = bpy.context.scene
                if args.width:
                    set_size(scene, args.width)
                r = scene.render
                size = (r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100)
                t0 = time.perf_counter()
                img = render(scene, eng, samples=spp, bounces=args.bounces, seed=seed)[..., :3].astype(np.float64)
                wall = time.perf_counter() - t0
                estimate = engine.last_render_stats.get("estimated_error") if eng == "TESSERA" else None
                points[eng][spp].add(img, wall, estimate)
                print(f"efficiency_native: {name} {eng} {spp} spp seed {seed}: {wall:.1f} s", flush=True)

    for eng, by_spp in points.items():
        for spp, p in by_spp.items():
            rows.append(dict(scene=name, width=size[0], height=size[1], engine=eng, samples=spp, bounces=args.bounces,
                             seeds=p.n, seconds=p.seconds(), seconds_min=min(p.walls), seconds_max=max(p.walls),
                             mse=p.mse(), rmse=math.sqrt(p.mse()), efficiency=1.0 / (p.mse() * p.seconds()),
                             image_mean=float(p.mean_image().mean()),
                             estimated_error=float(np.mean(p.estimates)) if p.estimates else "",
                             true_rel_error=math.sqrt(p.mse()) / max(float(p.mean_image().mean()), 1e-12)))
    c = points["CYCLES"][args.cycles_samples]
    t_needed = time_for_mse([(p.mse(), p.seconds()) for p in points["TESSERA"].values()], c.mse())
    t_top = points["TESSERA"][max(args.tessera_ladder)]
    # The engines' mean images: their systematic difference, noise taken out.
    d2 = float(((t_top.mean_image() - c.mean_image()) ** 2).mean()) - t_top.mse() / t_top.n - c.mse() / c.n
    summary.append(dict(name=name, size=size, cycles=c, tessera_top=t_top, t_needed=t_needed,
                        ratio=c.seconds() / t_needed if t_needed else None,
                        difference=math.sqrt(max(d2, 0.0)) / math.sqrt(c.mse())))

    # Written after every scene so that a long run keeps what it has.
    with open(os.path.join(args.out, "efficiency_native.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    top = max(args.tessera_ladder)
    lines = ["# Efficiency at each scene's own resolution: Tessera and Cycles", "",
             f"Blender {bpy.app.version_string}, {CPU}, {os.cpu_count()} cores, {time.strftime('%Y-%m-%d')}, "
             f"{args.bounces} max bounces, {args.seeds} seeds a point unless the table says otherwise (seeds 0..N-1, the "
             "engines taking turns). "
             "MSE: the per-pixel variance between the seeds' renders, averaged over pixels and channels (the expected "
             "squared error of one render, no reference needed); time: the median wall time of the whole render call. "
             f"Efficiency Tessera/Cycles: Cycles' time at {args.cycles_samples} samples over the time Tessera needs for "
             f"Cycles' MSE, read off Tessera's ladder {args.tessera_ladder} in log-log. Difference: the RMS "
             f"difference between the engines' mean images (Tessera at {top} samples), their noise taken out, over "
             "one Cycles render's RMS error.", "",
             f"| scene | size | seeds | Cycles {args.cycles_samples} spp RMSE | Cycles s (min-max) | Tessera {top} spp RMSE | "
             f"Tessera {top} spp s (min-max) | Tessera s for Cycles' MSE | **Tessera/Cycles efficiency** | "
             "difference | Tessera's estimate / its true relative error |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summary:
        c, t = s["cycles"], s["tessera_top"]
        est = (float(np.mean(t.estimates)) / (math.sqrt(t.mse()) / float(t.mean_image().mean()))
               if t.estimates else float("nan"))
        ratio = f"**{s['ratio']:.2f}**" if s["ratio"] else "-"
        needed = f"{s['t_needed']:.2f}" if s["t_needed"] else "-"
        lines.append(f"| {s['name']} | {s['size'][0]} x {s['size'][1]} | {c.n} | {math.sqrt(c.mse()):.5f} | "
                     f"{c.seconds():.2f} ({min(c.walls):.2f}-{max(c.walls):.2f}) | {math.sqrt(t.mse()):.5f} | "
                     f"{t.seconds():.2f} ({min(t.walls):.2f}-{max(t.walls):.2f}) | {needed} | {ratio} | "
                     f"{s['difference']:.2f} | {est:.2f} |")
    lines += ["", "## Runs", "", "| scene | engine | samples | s (median; min-max) | RMSE | 1/(MSE s) | image mean |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['engine'].title()} | {r['samples']} | {r['seconds']:.2f}; "
                     f"{r['seconds_min']:.2f}-{r['seconds_max']:.2f} | {r['rmse']:.5f} | {r['efficiency']:.3g} | "
                     f"{r['image_mean']:.5f} |")
    cmd = "blender -b --factory-startup --python scripts/efficiency_native.py -- " + " ".join(argv)
    lines += ["", "All runs: `efficiency_native.csv`.", "", "Command:", "", "```sh", cmd, "```", ""]
    with open(os.path.join(args.out, "README.md"), "w") as f:
        f.write("\n".join(lines))

print(open(os.path.join(args.out, "README.md")).read())
sys.stdout.flush()
os._exit(0)
