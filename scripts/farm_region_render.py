#!/usr/bin/env python3
"""Renders one frame of a .blend as region (border) renders in separate
`blender -b` processes, the way Flamenco's single-image job splits a frame
into tiles, and stitches them into one image.

    scripts/farm_region_render.py FILE.blend OUT.exr [--tiles 2x2] [--frame 1]
        [--jobs 4] [--size WxH] [--samples N] [--seed N] [--threads N]
        [--no-crop] [--addon DIR] [--blender BIN] [--keep]

Each tile is `blender -b FILE -E TESSERA --python THIS -o TILE -f FRAME -- ...`
(crop to border on by default; --no-crop renders full-size frames with only
the border filled, as Flamenco's tiles are). Tiles are 32-bit float EXR; the
stitch runs in one more `blender -b` and writes OUT as 32-bit float EXR
(exactly the pixels of a full render with the same seed) or, for .png/.jpg,
through the scene's colour management. --tiles 1x1 renders the frame whole
(the reference). Exit status: 0 when every tile and the stitch succeeded,
1 otherwise (Blender's output of a failed tile is printed).

The same file runs inside Blender in two roles, chosen by the arguments after
`--`: `--tile-setup` (set the border and overrides before the render) and
`--stitch` (paste the tiles)."""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.abspath(__file__)
# Blender prints these for failures it does not turn into an exit status
# (an exception escaping RenderEngine.render leaves status 0 and a black image).
FAILURE_MARKERS = ("Traceback (most recent call last)", "Error: Python:", "FARM_ERROR")


def tile_bounds(i, n, size):
    """Border fraction and pixel span of tile i of n along an axis of `size`
    pixels, computed as Blender does (float32 product, truncated)."""
    import numpy as np
    f0, f1 = np.float32(i / n), np.float32((i + 1) / n)
    return float(f0), float(f1), int(f0 * np.float32(size)), int(f1 * np.float32(size))


def common_args(p):
    p.add_argument("--size", help="override the resolution, WxH at 100%%")
    p.add_argument("--samples", type=int)
    p.add_argument("--seed", type=int)
    p.add_argument("--threads", type=int)
    p.add_argument("--addon", help="folder holding the tessera package, registered from there in Blenders "
                                   "started with --factory-startup (default: the add-on installed in Blender's "
                                   "preferences)")


# ---------------------------------------------------------------- inside Blender

def _apply_overrides(scene, a):
    import bpy
    if a.addon:
        sys.path.insert(0, a.addon)
        import tessera
        if not hasattr(bpy.types.Scene, "tessera"):
            tessera.register()
    r = scene.render
    if a.size:
        w, h = (int(v) for v in a.size.lower().split("x"))
        r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    r.engine = 'TESSERA'
    if hasattr(scene, "tessera"):
        t = scene.tessera
        if a.samples is not None:
            t.samples = a.samples
        if a.seed is not None:
            t.seed = a.seed
        if a.threads is not None:
            t.threads = a.threads


def blender_tile_setup(argv):
    import bpy
    p = argparse.ArgumentParser(prog="farm tile setup")
    p.add_argument("--tile-setup", required=True, help="ix,iy,nx,ny")
    p.add_argument("--no-crop", action="store_true")
    common_args(p)
    a = p.parse_args(argv)
    ix, iy, nx, ny = (int(v) for v in a.tile_setup.split(","))
    scene = bpy.context.scene
    _apply_overrides(scene, a)
    r = scene.render
    if nx * ny > 1:
        r.use_border = True
        r.use_crop_to_border = not a.no_crop
        r.border_min_x, r.border_max_x = tile_bounds(ix, nx, 1)[:2]
        r.border_min_y, r.border_max_y = tile_bounds(iy, ny, 1)[:2]
    else:
        r.use_border = False
    s = r.image_settings
    s.file_format, s.color_depth, s.color_mode, s.exr_codec = 'OPEN_EXR', '32', 'RGBA', 'ZIP'
    r.use_file_extension = True
    print(f"FARM_TILE {ix},{iy} of {nx}x{ny} border x {r.border_min_x:.6f}..{r.border_max_x:.6f} "
          f"y {r.border_min_y:.6f}..{r.border_max_y:.6f} crop {r.use_crop_to_border}", flush=True)


def blender_stitch(argv):
    import bpy
    import numpy as np
    p = argparse.ArgumentParser(prog="farm stitch")
    p.add_argument("--stitch", required=True, help="output path")
    p.add_argument("--grid", required=True, help="nx,ny")
    p.add_argument("--tile-dir", required=True)
    p.add_argument("--no-crop", action="store_true")
    common_args(p)
    a = p.parse_args(argv)
    nx, ny = (int(v) for v in a.grid.split(","))
    scene = bpy.context.scene
    _apply_overrides(scene, a)
    r = scene.render
    width = r.resolution_x * r.resolution_percentage // 100
    height = r.resolution_y * r.resolution_percentage // 100
    out = np.zeros((height, width, 4), dtype=np.float32)  # rows bottom to top, as Blender stores them
    for iy in range(ny):
        for ix in range(nx):
            _, _, x0, x1 = tile_bounds(ix, nx, width)
            _, _, y0, y1 = tile_bounds(iy, ny, height)
            path = os.path.join(a.tile_dir, f"tile_{ix}_{iy}.exr")
            img = bpy.data.images.load(path)
            w, h = img.size
            px = np.empty(w * h * 4, dtype=np.float32)
            img.pixels.foreach_get(px)
            bpy.data.images.remove(img)
            px = px.reshape(h, w, 4)
            if a.no_crop or nx * ny == 1:
                if (w, h) != (width, height):
                    raise SystemExit(f"FARM_ERROR tile {ix},{iy} is {w}x{h}, expected the full {width}x{height}")
                px = px[y0:y1, x0:x1]
            elif (w, h) != (x1 - x0, y1 - y0):
                raise SystemExit(f"FARM_ERROR tile {ix},{iy} is {w}x{h}, expected {x1 - x0}x{y1 - y0}")
            out[y0:y1, x0:x1] = px
    img = bpy.data.images.new("farm_stitched", width, height, alpha=True, float_buffer=True)
    img.pixels.foreach_set(out.ravel())
    ext = os.path.splitext(a.stitch)[1].lower()
    s = scene.render.image_settings
    if ext == ".exr":
        s.file_format, s.color_depth, s.color_mode, s.exr_codec = 'OPEN_EXR', '32', 'RGBA', 'ZIP'
    else:
        s.file_format = {".png": 'PNG', ".jpg": 'JPEG', ".jpeg": 'JPEG', ".tif": 'TIFF', ".tiff": 'TIFF'}.get(ext, 'PNG')
    img.save_render(a.stitch, scene=scene)  # EXR stays linear; 8/16-bit formats get the view transform
    print(f"FARM_STITCHED {a.stitch} {width}x{height} from {nx}x{ny} tiles", flush=True)


# ---------------------------------------------------------------- the driver

def run(cmd, log_path):
    with open(log_path, "w") as log:
        return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)


def failed(code, log_path):
    text = open(log_path, errors="replace").read()
    bad = code != 0 or any(m in text for m in FAILURE_MARKERS)
    return bad, text


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("blend")
    p.add_argument("output", help="stitched image: .exr (32-bit float, exact) or .png/.jpg/.tif")
    p.add_argument("--tiles", default="2x2", help="tiles across x down, e.g. 2x2 (four region renders)")
    p.add_argument("--frame", type=int, default=1)
    p.add_argument("--jobs", type=int, default=0, help="processes at once (default: all tiles)")
    p.add_argument("--no-crop", action="store_true", help="render tiles full-size with only the border filled")
    p.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    p.add_argument("--keep", action="store_true", help="keep the tile folder and logs")
    common_args(p)
    a = p.parse_args(argv)
    nx, ny = (int(v) for v in a.tiles.lower().split("x"))
    blend = os.path.abspath(a.blend)
    output = os.path.abspath(a.output)
    os.makedirs(os.path.dirname(output) or ".", exist_ok=True)
    work = tempfile.mkdtemp(prefix="tessera_farm_", dir=os.path.dirname(output))
    passthrough = []
    for name in ("size", "samples", "seed", "threads", "addon"):
        v = getattr(a, name)
        if v is not None:
            passthrough += [f"--{name}", str(os.path.abspath(v) if name == "addon" else v)]
    if a.no_crop:
        passthrough.append("--no-crop")
    # With --addon, the Blenders skip the user preferences: an add-on enabled there (another Tessera, or a
    # dangling link to one) would otherwise be loaded instead of DIR's, or fail every tile with its traceback.
    prefs = ["--factory-startup"] if a.addon else []

    tiles = [(ix, iy) for iy in range(ny) for ix in range(nx)]
    pending, running, failures = list(tiles), [], []
    jobs = a.jobs or len(tiles)
    t0 = time.perf_counter()
    while pending or running:
        while pending and len(running) < jobs:
            ix, iy = pending.pop(0)
            # Options are applied in order: --python (border, overrides), -E, -o, then -f renders.
            out_base = os.path.join(work, f"tile_{ix}_{iy}_")
            cmd = [a.blender, "-b", *prefs, blend, "--python", HERE, "-E", "TESSERA",
                   "-o", out_base + "####", "-f", str(a.frame),
                   "--", "--tile-setup", f"{ix},{iy},{nx},{ny}", *passthrough]
            log = os.path.join(work, f"tile_{ix}_{iy}.log")
            running.append(((ix, iy), run(cmd, log), log, out_base))
        time.sleep(0.05)
        for item in list(running):
            (ix, iy), proc, log, out_base = item
            if proc.poll() is None:
                continue
            running.remove(item)
            bad, text = failed(proc.returncode, log)
            produced = f"{out_base}{a.frame:04d}.exr"
            if bad or not os.path.exists(produced):
                failures.append((ix, iy))
                print(f"farm: tile {ix},{iy} FAILED (exit {proc.returncode}); its Blender output:\n{text}",
                      file=sys.stderr)
            else:
                os.replace(produced, os.path.join(work, f"tile_{ix}_{iy}.exr"))
                print(f"farm: tile {ix},{iy} done ({time.perf_counter() - t0:.1f} s)")
    if failures:
        print(f"farm: {len(failures)} of {len(tiles)} tiles failed; nothing stitched. Tiles and logs: {work}",
              file=sys.stderr)
        return 1
    log = os.path.join(work, "stitch.log")
    cmd = [a.blender, "-b", *prefs, blend, "--python", HERE, "--",
           "--stitch", output, "--grid", f"{nx},{ny}", "--tile-dir", work, *passthrough]
    proc = run(cmd, log)
    bad, text = failed(proc.wait(), log)
    if bad or not os.path.exists(output):
        print(f"farm: stitching FAILED; its Blender output:\n{text}", file=sys.stderr)
        return 1
    print(f"farm: wrote {output} from {nx}x{ny} region renders in {time.perf_counter() - t0:.1f} s")
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)
    else:
        print(f"farm: tiles and logs kept in {work}")
    return 0


def _blender_role():
    import bpy  # noqa: F401  (only inside Blender)
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if "--tile-setup" in argv:
        blender_tile_setup(argv)
    elif "--stitch" in argv:
        blender_stitch(argv)


if __name__ == "__main__":
    try:
        import bpy  # noqa: F401
    except ImportError:
        sys.exit(main())
    _blender_role()
