"""What Cycles' own path guiding (Intel Open PGL, Blender 3.4+ builds that have
it: the `bpy` wheels from PyPI do, Debian's Blender 3.4 does not) buys on a
scene: Cycles with and without surface guiding, same samples and seeds,
against one high-sample reference without guiding.

    python -m venv ... && pip install bpy==4.5.*      # or: scripts/setup_bpy.sh
    $(scripts/setup_bpy.sh) scripts/cycles_guiding.py -- /work/shared/scenes/cornell_mcguire.blend \
        [more .blend] [--width 120] [--samples 64 256] [--seeds 4] [--ref-samples 2048]

Per scene and sample count: the mean MSE over the seeds (0..N-1, the two
settings taking turns), the median wall time of the render call, efficiency
1 / (MSE x time), and the guided/unguided ratios. Guiding is deterministic
(use_deterministic_guiding), trains on its default 128 samples and guides
surfaces only. Everything else as in the convergence study
(tests/blender/helpers.py configure_engine: 8 bounces, no denoising, no
clamping, adaptive sampling off)."""

import argparse
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
from helpers import configure_engine, render_as_configured, set_size  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
ap = argparse.ArgumentParser()
ap.add_argument("scenes", nargs="+")
ap.add_argument("--width", type=int, default=120)
ap.add_argument("--samples", type=int, nargs="+", default=[64, 256])
ap.add_argument("--seeds", type=int, default=4)
ap.add_argument("--ref-samples", type=int, default=2048)
args = ap.parse_args(argv)

import _cycles  # noqa: E402

if not getattr(_cycles, "with_path_guiding", False):
    sys.exit(f"cycles_guiding: this Cycles (Blender {bpy.app.version_string}) was built without path guiding; "
             "run it with the bpy wheel from PyPI (scripts/setup_bpy.sh prints its python)")


def render(scene, samples, seed, guiding):
    """The render call's wall time (with its EXR write, as the convergence study) and its pixels (RGB)."""
    configure_engine(scene, "CYCLES", samples=samples, seed=seed)
    c = scene.cycles
    c.use_guiding = guiding
    c.use_surface_guiding = guiding
    c.use_volume_guiding = False
    c.use_deterministic_guiding = True
    t = time.perf_counter()
    px = render_as_configured(scene, "CYCLES")
    return time.perf_counter() - t, px[..., :3]


rows = []
for path in args.scenes:
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    set_size(scene, args.width)
    name = os.path.basename(path)
    _, ref = render(scene, args.ref_samples, 1000, False)
    for spp in args.samples:
        runs = {False: [], True: []}
        for seed in range(args.seeds):
            for guiding in (False, True):
                t, px = render(scene, spp, seed, guiding)
                runs[guiding].append((float(np.mean((px - ref) ** 2)), t))
        stats = {}
        for guiding, r in runs.items():
            mse = float(np.mean([m for m, _ in r]))
            t = float(np.median([s for _, s in r]))
            stats[guiding] = (mse, t, 1.0 / (mse * t))
        (m0, t0, e0), (m1, t1, e1) = stats[False], stats[True]
        rows.append((name, spp, m0, t0, m1, t1, m1 / m0, t1 / t0, e1 / e0))
        print(f"{name} {spp} spp: MSE {m0:.5g} -> {m1:.5g} with guiding ({m1 / m0:.2f}x), "
              f"time {t0:.2f} -> {t1:.2f} s ({t1 / t0:.2f}x), efficiency {e1 / e0:.2f}x", flush=True)

print(f"\nBlender {bpy.app.version_string}, width {args.width} px, {args.seeds} seeds, reference "
      f"{args.ref_samples} spp without guiding\n")
print("| scene | spp | MSE off | s off | MSE guided | s guided | MSE guided/off | time guided/off | efficiency guided/off |")
print("|---|---|---|---|---|---|---|---|---|")
for name, spp, m0, t0, m1, t1, rm, rt, re in rows:
    print(f"| {name} | {spp} | {m0:.5g} | {t0:.2f} | {m1:.5g} | {t1:.2f} | {rm:.2f} | {rt:.2f} | {re:.2f} |")
