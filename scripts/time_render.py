"""Times Tessera's core on one scene with the add-on found in ADDON_DIR: one
warm-up render, then N renders, each printed as `TIME <core seconds> <rays>`
(the render call's own figures, without export and Blender's overhead).
Used by scripts/compare_builds.sh, which runs two builds against each other.

    blender -b --factory-startup --python scripts/time_render.py -- ADDON_DIR SCENE \\
        [--width 160] [--samples 64] [--renders 4] [--threads 1] [--seed 0]

SCENE: a path, or a file name in the shared scenes folder."""
import argparse
import os
import sys

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("addon_dir")
ap.add_argument("scene")
ap.add_argument("--width", type=int, default=160)
ap.add_argument("--samples", type=int, default=64)
ap.add_argument("--renders", type=int, default=4)
ap.add_argument("--threads", type=int, default=1, help="0: all cores")
ap.add_argument("--seed", type=int, default=0)
args = ap.parse_args(argv)

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.abspath(args.addon_dir))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
import tessera  # noqa: E402
from tessera import engine  # noqa: E402
from helpers import configure_engine, open_scene, render_as_configured, set_size  # noqa: E402

tessera.register()
scene = open_scene(args.scene)
set_size(scene, args.width)
for i in range(args.renders + 1):
    configure_engine(scene, "TESSERA", samples=args.samples, bounces=8, seed=args.seed, threads=args.threads)
    render_as_configured(scene, "TESSERA")
    st = engine.last_render_stats
    if i > 0:  # the first render warms caches and the image decode
        print(f"TIME {st['render_seconds']:.6f} {st['rays']}", flush=True)
