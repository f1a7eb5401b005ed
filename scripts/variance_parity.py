"""Noise per sample against Cycles, light by light and material by material:
where Tessera is noisier than Cycles at the same samples, something in its
estimator differs (three bugs were found this way: the bent-normal cosine, the
constant world's light sampling, the sun disk missing from escaping rays).

    blender -b --factory-startup --python scripts/variance_parity.py -- \
        [--lights point spot sun area disk smallarea mesh world point+sky] \
        [--materials diffuse plastic metal glass roughglass] [--size 64] [--samples 16] [--seeds 8]

Each case is a small scene built here: a smooth UV sphere of the material on a
diffuse floor before a wall, lit by one light (`+sky`: with Blender's default
dim grey world as well). Both engines render it with seeds 0..N-1; the
per-pixel variance across the seeds (no reference needed) and the image mean
are compared. Prints one row per case: mean Tessera/Cycles, variance
Tessera/Cycles and the brightest pixel of each. Caustics through glass from
small lights are rare events: their means and variances need many seeds."""

import argparse
import math
import os
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))
sys.path.insert(0, os.path.join(HERE, "..", "addon"))
import scenes as S  # noqa: E402
import tessera  # noqa: E402
from helpers import render  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--lights", nargs="+",
                default=["point", "spot", "sun", "area", "disk", "smallarea", "mesh", "world", "point+sky"])
ap.add_argument("--materials", nargs="+", default=["diffuse", "plastic", "metal", "glass", "roughglass"])
ap.add_argument("--size", type=int, default=64)
ap.add_argument("--samples", type=int, default=16)
ap.add_argument("--seeds", type=int, default=8)
args = ap.parse_args(argv)

if not hasattr(bpy.types.Scene, "tessera"):
    tessera.register()

MATERIALS = {
    "diffuse": dict(color=(0.8, 0.3, 0.2), Specular=0.0, Roughness=1.0),
    "plastic": dict(color=(0.8, 0.3, 0.2)),
    "metal": dict(color=(0.9, 0.7, 0.4), Metallic=1.0, Roughness=0.2),
    "glass": dict(color=(1, 1, 1), Transmission=1.0, Roughness=0.0, IOR=1.5),
    "roughglass": dict(color=(1, 1, 1), Transmission=1.0, Roughness=0.2, IOR=1.5),
}
# Blender light type, energy (W, or W/m^2 for the sun), size (radius, area side or disk diameter).
LIGHTS = {"point": ("POINT", 150.0, 0.1), "spot": ("SPOT", 150.0, 0.1), "sun": ("SUN", 3.0, 0.0),
          "area": ("AREA", 60.0, 0.6), "disk": ("AREA", 60.0, 0.6), "smallarea": ("AREA", 60.0, 0.05)}


def build(light, material):
    scene = S.empty_scene()
    scene.render.resolution_x = scene.render.resolution_y = args.size
    S.add_plane(8, material=S.principled("floor", (0.8, 0.8, 0.8), Specular=0.0, Roughness=1.0))
    S.add_plane(8, location=(0, 2, 2), rotation=(math.pi / 2, 0, 0),
                material=S.principled("wall", (0.6, 0.6, 0.8), Specular=0.0))
    props = dict(MATERIALS[material])
    mat = S.principled("sphere", props.pop("color"), **props)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(0, 0, 0.6), segments=24, ring_count=12)
    bpy.context.object.data.materials.append(mat)
    bpy.ops.object.shade_smooth()
    S.add_camera(scene, location=(0, -4, 1.6), rotation=(math.radians(75), 0, 0))
    base, sky = light.split("+")[0], light.endswith("+sky")
    S.set_world(scene, (0.8, 0.9, 1.0), 1.0) if base == "world" else S.set_world(scene, (0, 0, 0), 0.0)
    if base == "mesh":
        emitter = S.principled("emitter", (0, 0, 0), Emission=(1, 1, 1, 1), **{"Emission Strength": 30.0})
        S.add_plane(0.6, location=(1.0, -0.5, 2.2), rotation=(0.3, -0.3, 0), material=emitter)
    elif base != "world":
        kind, energy, size = LIGHTS[base]
        bpy.ops.object.light_add(type=kind, location=(1.0, -0.5, 2.2), rotation=(0.3, 0.3, 0))
        data = bpy.context.object.data
        data.energy = energy
        if kind == "SUN":
            data.angle = math.radians(5.0)
        elif kind == "AREA":
            data.size = size
            data.shape = "DISK" if base == "disk" else "SQUARE"
        else:
            data.shadow_soft_size = size
        if kind == "SPOT":
            data.spot_size = math.radians(60.0)
    if sky:
        S.set_world(scene, (0.05, 0.05, 0.05), 1.0)  # Blender's default world
    return scene


print(f"\nBlender {bpy.app.version_string}, {args.size} px, {args.samples} spp, seeds 0..{args.seeds - 1}\n")
print("| light | material | mean T/C | variance T/C | variance T / C | brightest pixel T / C |")
print("|---|---|---|---|---|---|")
for light in args.lights:
    for material in args.materials:
        scene = build(light, material)
        stats = {}
        for engine in ("TESSERA", "CYCLES"):
            imgs = np.stack([render(scene, engine, samples=args.samples, seed=k)[..., :3] for k in range(args.seeds)])
            stats[engine] = (float(imgs.mean()), float(imgs.var(axis=0, ddof=1).mean()), float(imgs.mean(-1).max()))
        (mt, vt, xt), (mc, vc, xc) = stats["TESSERA"], stats["CYCLES"]
        print(f"| {light} | {material} | {mt / mc:.3f} | {vt / vc:.3f} | {vt:.3g} / {vc:.3g} | {xt:.1f} / {xc:.1f} |",
              flush=True)
