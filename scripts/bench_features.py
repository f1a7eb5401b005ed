"""What modelling only the scene's features saves: every shared scene is
exported once and rendered by the core with its features specialised (the
default: SceneFeatures decided once per render from what the scene has) and
with every feature modelled (RenderOptions.specialise = False: transparent
shadows through every shadow ray, and the ray after the last bounce traced
even where no emitter can be hit). Both must give the same image; the table
shows the time, the rays per sample and the ratio. Run inside Blender:

    blender -b --factory-startup --python scripts/bench_features.py -- \\
        [--scenes cornell_mcguire ...] [--width 160] [--samples 64] [--runs 3] [--addon DIR]

Renders alternate between the two kernels; figures are medians over --runs.
Other structures already follow the scene and are not switched here: the
light BVH exists only with emitters, the world's importance map only with an
environment texture, UVs only for textured materials, BSDF lobes only for
the closures a material has."""

import argparse
import os
import statistics
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--scenes", nargs="+",
                default=["cornell_mcguire", "cbox_mitsuba", "veach_mis", "bunny_glass", "modern_hall"])
ap.add_argument("--width", type=int, default=160)
ap.add_argument("--samples", type=int, default=64)
ap.add_argument("--runs", type=int, default=3)
ap.add_argument("--addon", default=os.path.join(HERE, "..", "addon"))
args = ap.parse_args(argv)
sys.path.insert(0, args.addon)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))

import tessera  # noqa: E402
from tessera import core  # noqa: E402
from tessera.engine import render_options, render_region, render_size  # noqa: E402
from tessera.export import export_scene  # noqa: E402
from helpers import open_scene, set_size  # noqa: E402

if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()


def render(scene_core, options):
    session = core.native.Session(scene_core, options)
    t0 = time.perf_counter()
    session.start()
    while not session.wait(1.0):
        pass
    seconds = time.perf_counter() - t0
    return seconds, session.pixels().copy(), session.stats()


rows = []
for name in args.scenes:
    scene = open_scene(name + ".blend")
    set_size(scene, args.width)
    scene.tessera.samples = args.samples
    depsgraph = bpy.context.evaluated_depsgraph_get()
    width, height = render_size(scene)
    scene_core, stats, _ = export_scene(depsgraph, width, height, lambda: False, None)
    features = core.native.scene_features(scene_core)
    times = {True: [], False: []}
    rays = {}
    images = {}
    for run in range(args.runs):
        for specialise in (True, False):
            options = render_options(scene.tessera, render_region(scene, width, height))
            options.specialise = specialise
            seconds, px, st = render(scene_core, options)
            times[specialise].append(seconds)
            rays[specialise] = st["rays"] / max(1, st["pixel_samples"])
            images[specialise] = px
    t_spec, t_all = statistics.median(times[True]), statistics.median(times[False])
    diff = float(np.max(np.abs(images[True] - images[False])))
    rows.append((name, features, t_spec, t_all, rays[True], rays[False], diff))
    print(f"ROW {name} {features} specialised {t_spec:.3f} s, all features {t_all:.3f} s, "
          f"rays/sample {rays[True]:.3f} / {rays[False]:.3f}, max pixel difference {diff:g}", flush=True)

print()
print(f"{args.width} px wide, {args.samples} samples, median of {args.runs} runs (alternating), "
      f"Blender {bpy.app.version_string}")
print()
print("| scene | emitters hittable | transparent materials | specialised s | all features s | saved | "
      "rays/sample specialised / all | max pixel difference |")
print("|---|---|---|---|---|---|---|---|")
for name, f, ts, ta, rs, ra, diff in rows:
    print(f"| {name} | {'yes' if f['hittable_emitters'] else 'no'} | {'yes' if f['transparent'] else 'no'} | "
          f"{ts:.3f} | {ta:.3f} | {100 * (1 - ts / ta):.1f}% | {rs:.2f} / {ra:.2f} | {diff:g} |")
