"""Renders every shared scene with Tessera and with Cycles at the same size,
samples and bounces, and writes a report: side-by-side images, a difference
image, and a table of mean difference per channel, relative RMSE after 1/8
downsampling, and the worst 8x8 block of the downsampled image.

    blender -b --factory-startup --python scripts/compare_cycles.py -- \
        [--size 320] [--samples 256] [--bounces 8] [--out docs/compare]
"""

import argparse
import os
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "addon"))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))

import tessera  # noqa: E402
from helpers import SCENES, compare, open_scene, remove_duplicate_faces, render, set_size  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--size", type=int, default=320)
ap.add_argument("--samples", type=int, default=256)
ap.add_argument("--bounces", type=int, default=8)
ap.add_argument("--scenes", nargs="*", default=None)
ap.add_argument("--out", default=os.path.join(HERE, "..", "docs", "compare"))
args = ap.parse_args(argv)
os.makedirs(args.out, exist_ok=True)
if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()


def save_png(img, path):
    h, w = img.shape[:2]
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = np.clip(img[..., :3], 0.0, 1.0) ** (1 / 2.2)
    im = bpy.data.images.new(os.path.basename(path), w, h, float_buffer=True)
    im.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())
    im.filepath_raw = path
    im.file_format = 'PNG'
    im.save()
    bpy.data.images.remove(im)


names = args.scenes or sorted(f for f in os.listdir(SCENES) if f.endswith(".blend"))
rows = []
for name in names:
    scene = open_scene(name)
    removed = remove_duplicate_faces(scene)
    set_size(scene, args.size)
    ours = render(scene, 'TESSERA', samples=args.samples, bounces=args.bounces)
    ref = render(scene, 'CYCLES', samples=args.samples, bounces=args.bounces)
    c = compare(ours, ref)
    diff = np.abs(ours[..., :3] - ref[..., :3]) / max(float(ref[..., :3].mean()), 1e-6)
    stem = os.path.splitext(name)[0]
    save_png(np.concatenate([ours, ref], axis=1), os.path.join(args.out, f"{stem}_tessera_cycles.png"))
    save_png(np.repeat(diff.mean(axis=-1, keepdims=True), 3, axis=-1), os.path.join(args.out, f"{stem}_diff.png"))
    rows.append((name, c, bool(np.all(np.isfinite(ours))), removed))
    print(f"compare: {name}: mean diff {np.round(c['mean_rel_diff'], 4)}, rel RMSE {c['rel_rmse']:.4f}, "
          f"worst block {c['worst_block']:.4f}", flush=True)

lines = ["# Tessera against Cycles on the shared scenes", "",
         f"{args.size} px wide, {args.samples} samples, {args.bounces} max bounces, both engines on the same "
         f"Blender {bpy.app.version_string} file. Mean difference per channel (relative), relative RMSE of the "
         f"1/8-downsampled images, worst 8x8 block of the downsampled image. Left: Tessera, right: Cycles.", "",
         "| scene | mean diff R / G / B | rel. RMSE (1/8) | worst block | finite | note |", "|---|---|---|---|---|---|"]
for name, c, finite, removed in rows:
    d = " / ".join(f"{100 * x:.1f}%" for x in c["mean_rel_diff"])
    note = f"{removed} duplicate faces removed (Cycles shades them with z-fighting)" if removed else ""
    lines.append(f"| {name} | {d} | {100 * c['rel_rmse']:.1f}% | {100 * c['worst_block']:.1f}% | {finite} | {note} |")
lines += ["", "Command:", "", "```sh", "blender -b --factory-startup --python scripts/compare_cycles.py -- " +
          " ".join(argv), "```", ""]
for name, *_ in rows:
    stem = os.path.splitext(name)[0]
    lines += [f"## {name}", "", f"![{stem}]({stem}_tessera_cycles.png)", "", f"![{stem} difference]({stem}_diff.png)", ""]
with open(os.path.join(args.out, "README.md"), "w") as f:
    f.write("\n".join(lines))
print("\n".join(lines[:12 + len(rows)]))
sys.stdout.flush()
os._exit(0)
