"""What one Tessera setting buys: error, time and efficiency over a list of its
values, on each scene. Run inside Blender:

    blender -b --factory-startup --python scripts/setting_sweep.py -- \\
        /work/shared/scenes/cornell_mcguire.blend [more .blend] --setting rr_depth --values 3 4 5 \\
        [--width 160] [--samples 64] [--seeds 6] [--ref-samples 1024] [--bounces 8] \\
        [--cache /tmp/tessera_sweep] [--addon DIR] [--out FILE.md]

Per scene: Tessera's reference (--ref-samples, seed 1000, the settings as the
file has them; cached in --cache), then for each seed 0..N-1 one render per
value, the values in a rotated order from seed to seed (machine load drifts;
no value always goes first). Per value: median render time (the core's own,
without export), mean MSE against the reference over the seeds, mean rays,
efficiency 1 / (MSE x time), and that efficiency over the first value's. The
error of each seed is exact for a given build (same seed, same image); the
times are as steady as the machine. Prints a markdown table, and writes it to
--out when given."""
import argparse
import os
import statistics
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("scenes", nargs="+")
ap.add_argument("--setting", required=True, help="a scene.tessera property, e.g. rr_depth")
ap.add_argument("--values", nargs="+", required=True)
ap.add_argument("--width", type=int, default=160)
ap.add_argument("--samples", type=int, default=64)
ap.add_argument("--seeds", type=int, default=6)
ap.add_argument("--ref-samples", type=int, default=1024)
ap.add_argument("--bounces", type=int, default=8)
ap.add_argument("--cache", default="/tmp/tessera_sweep")
ap.add_argument("--addon", default=os.path.join(HERE, "..", "addon"))
ap.add_argument("--out", default="")
args = ap.parse_args(argv)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
sys.path.insert(0, args.addon)

import tessera  # noqa: E402
from helpers import render, set_size  # noqa: E402

if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()
from tessera import engine  # noqa: E402

os.makedirs(args.cache, exist_ok=True)


def load(path, value=None):
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    set_size(scene, args.width)
    if value is not None:
        current = getattr(scene.tessera, args.setting)
        setattr(scene.tessera, args.setting, type(current)(value if isinstance(current, str) else float(value)))
    return scene


lines = [f"Setting `{args.setting}`: {args.width} px wide, {args.samples} samples, {args.seeds} seeds, "
         f"{args.bounces} bounces, against Tessera's {args.ref_samples}-sample reference.", "",
         "| scene | value | render s (median) | MSE (mean) | rays (mean) | 1/(MSE s) | efficiency / first |",
         "|---|---|---:|---:|---:|---:|---:|"]
for path in args.scenes:
    name = os.path.basename(path)[:-6]
    cache = os.path.join(args.cache, f"{name}_{args.ref_samples}_{args.bounces}_{args.width}.npy")
    if not os.path.exists(cache):
        np.save(cache, render(load(path), "TESSERA", samples=args.ref_samples, bounces=args.bounces,
                              seed=1000)[..., :3].astype(np.float64))
    ref = np.load(cache)
    runs = {v: [] for v in args.values}
    for seed in range(args.seeds):
        k = seed % len(args.values)
        for value in args.values[k:] + args.values[:k]:
            img = render(load(path, value), "TESSERA", samples=args.samples, bounces=args.bounces,
                         seed=seed)[..., :3].astype(np.float64)
            st = engine.last_render_stats
            runs[value].append((float(((img - ref) ** 2).mean()), st["render_seconds"], st["rays"]))
            print(f"  {name} {args.setting}={value} seed {seed}: MSE {runs[value][-1][0]:.6g}, "
                  f"{st['render_seconds']:.3f} s", flush=True)
    first = None
    for value in args.values:
        mse = statistics.mean(r[0] for r in runs[value])
        seconds = statistics.median(r[1] for r in runs[value])
        rays = statistics.mean(r[2] for r in runs[value])
        eff = 1.0 / (mse * seconds)
        first = first or eff
        lines.append(f"| {name} | {value} | {seconds:.3f} | {mse:.6g} | {rays:.0f} | {eff:.4g} | {eff / first:.3f} |")
table = "\n".join(lines)
print(table)
if args.out:
    with open(args.out, "w") as f:
        f.write(table + "\n\nCommand:\n\n```sh\nblender -b --factory-startup --python scripts/setting_sweep.py -- "
                + " ".join(sys.argv[sys.argv.index("--") + 1:]) + "\n```\n")
