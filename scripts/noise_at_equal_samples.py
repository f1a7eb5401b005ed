"""Per-sample noise of Tessera against Cycles: RMSE at equal sample counts,
each engine against its own high-sample reference (independent of machine
load, unlike error-against-time ladders). Run inside Blender:

    blender -b --factory-startup --python scripts/noise_at_equal_samples.py -- \\
        [--scenes veach_mis modern_hall cornell_mcguire cbox_mitsuba bunny_glass] \\
        [--spp 16 64] [--seeds 3] [--width 120] [--ref 1024] [--bounces 8] \\
        [--cache /tmp/tessera_noise] [--addon DIR] [--tag NAME] [--tessera-only]

Per scene and sample count: sqrt of the mean over seeds 0..N-1 of the MSE
against the reference (seed 1000), for Tessera and Cycles; Tessera's rays per
pixel sample; image means (bias check against Cycles' reference); Tessera's
estimated relative error (the error-target mode's estimate) over the true
relative RMSE against its reference, per seed, and the mean estimate over the
seeds against the RMS of their true errors (what the estimate predicts: the
expected error; single images swing with rare bright samples), and a short
table of both with each image's true error over the RMS (its own spread). References
and Cycles renders are cached in --cache (delete Tessera's references there
after a change that moves Tessera's image mean). Prints a markdown table and
writes CACHE/results_TAG.json."""
import argparse
import json
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--addon", default=os.path.join(HERE, "..", "addon"))
ap.add_argument("--tag", default="run")
ap.add_argument("--scenes", nargs="+", default=["veach_mis", "modern_hall", "cornell_mcguire", "cbox_mitsuba", "bunny_glass"])
ap.add_argument("--spp", type=int, nargs="+", default=[16, 64])
ap.add_argument("--seeds", type=int, default=3)
ap.add_argument("--bounces", type=int, default=8)
ap.add_argument("--width", type=int, default=120)
ap.add_argument("--ref", type=int, default=1024)
ap.add_argument("--cache", default="/tmp/tessera_noise")
ap.add_argument("--tessera-only", action="store_true",
                help="no Cycles renders (its columns show nan): for the estimate's figures alone")
a = ap.parse_args(argv)
sys.path.insert(0, a.addon)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
import tessera  # noqa: E402
if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()
from tessera import engine  # noqa: E402
from helpers import SCENES, render, set_size  # noqa: E402

os.makedirs(a.cache, exist_ok=True)


def rendered(scene_name, eng, spp, seed):
    bpy.ops.wm.open_mainfile(filepath=os.path.join(SCENES, scene_name + ".blend"))
    sc = bpy.context.scene
    set_size(sc, a.width)
    return render(sc, eng, samples=spp, bounces=a.bounces, seed=seed)[..., :3].astype(np.float64)


def cached(scene_name, eng, spp, seed):
    f = os.path.join(a.cache, f"{scene_name}_{eng}_{spp}_{seed}_{a.bounces}_{a.width}.npy")
    if not os.path.exists(f):
        np.save(f, rendered(scene_name, eng, spp, seed))
    return np.load(f)


rows = []
for s in a.scenes:
    refs = {e: cached(s, e, a.ref, 1000) for e in (("TESSERA",) if a.tessera_only else ("TESSERA", "CYCLES"))}
    row = {"scene": s, "mean_ref_tessera": float(refs["TESSERA"].mean()),
           "mean_ref_cycles": float(refs["CYCLES"].mean()) if "CYCLES" in refs else float("nan")}
    for spp in a.spp:
        mse_t, mse_c, mean_t, rays, est_ratio, est, true_rel = [], [], [], [], [], [], []
        for seed in range(a.seeds):
            im = rendered(s, "TESSERA", spp, seed)
            st = engine.last_render_stats
            rays.append(st["rays"] / max(1, st["pixel_samples"]))
            mse_t.append(((im - refs["TESSERA"]) ** 2).mean())
            true_rel.append(np.sqrt(mse_t[-1]) / refs["TESSERA"].mean())
            est.append(st["estimated_error"])
            est_ratio.append(est[-1] / true_rel[-1])
            mean_t.append(im.mean())
            mse_c.append(np.nan if a.tessera_only else ((cached(s, "CYCLES", spp, seed) - refs["CYCLES"]) ** 2).mean())
        row[f"tessera_{spp}"] = float(np.sqrt(np.mean(mse_t)))
        row[f"cycles_{spp}"] = float(np.sqrt(np.mean(mse_c)))
        row[f"rays_{spp}"] = float(np.mean(rays))
        row[f"mean_{spp}"] = float(np.mean(mean_t))
        row[f"estimate_ratio_{spp}"] = [round(float(x), 3) for x in est_ratio]
        # The estimate predicts the expected error; one image's error and one
        # estimate both swing with rare bright samples. Over the seeds: the
        # mean estimate against the RMS of the true relative errors.
        row[f"estimate_over_expected_{spp}"] = float(np.mean(est) / np.sqrt(np.mean(np.square(true_rel))))
        # How far one image's true error strays from the RMS over the seeds:
        # what an estimate of the expected error cannot follow.
        row[f"true_over_rms_{spp}"] = [round(float(x / np.sqrt(np.mean(np.square(true_rel)))), 3) for x in true_rel]
    rows.append(row)
    print("ROW", json.dumps(row), flush=True)
with open(os.path.join(a.cache, f"results_{a.tag}.json"), "w") as f:
    json.dump(rows, f, indent=1)
head = ("| scene | " + " | ".join(f"Tessera {n} | Cycles {n}" for n in a.spp) + " | rays/sample | mean T / C ref | "
        + " | ".join(f"estimate / true {n}, per seed" for n in a.spp) + " | "
        + " | ".join(f"mean estimate / RMS true {n}" for n in a.spp) + " |")
print("\n" + head + "\n|" + "---|" * (head.count("|") - 1))
for r in rows:
    cells = " | ".join(f"{r[f'tessera_{n}']:.4f} | {r[f'cycles_{n}']:.4f}" for n in a.spp)
    ratios = " | ".join(", ".join(f"{x:.2f}" for x in r[f"estimate_ratio_{n}"]) for n in a.spp)
    expected = " | ".join(f"{r[f'estimate_over_expected_{n}']:.2f}" for n in a.spp)
    print(f"| {r['scene']} | {cells} | {r[f'rays_{a.spp[-1]}']:.2f} | {r[f'mean_{a.spp[-1]}'] / r['mean_ref_cycles']:.3f} | "
          f"{ratios} | {expected} |")
# The estimate in short: per sample count, estimate / true over the seeds (min-max), [mean estimate / RMS true],
# and (true / RMS true, min-max): the spread of one image's error itself.
head = "| scene | " + " | ".join(f"{n} spp" for n in a.spp) + " |"
print("\n" + head + "\n|" + "---|" * (head.count("|") - 1))
for r in rows:
    cells = []
    for n in a.spp:
        e, t = r[f"estimate_ratio_{n}"], r[f"true_over_rms_{n}"]
        cells.append(f"{min(e):.2f}-{max(e):.2f} [{r[f'estimate_over_expected_{n}']:.2f}] ({min(t):.2f}-{max(t):.2f})")
    print(f"| {r['scene']} | " + " | ".join(cells) + " |")
