"""Rendering helpers for the Blender tests: render the open file with an
engine at a given size, samples and bounces, and read the float pixels back."""

import os
import subprocess
import tempfile

import bpy
import numpy as np

SHARED = os.environ.get("TESSERA_SHARED",
                        os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared"))
SCENES = os.path.join(SHARED, "scenes")
ADDON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "addon")


def blender_render_frame(blend, out_dir):
    """Renders frame 1 of a saved .blend with Tessera in a separate `blender -b`
    process, as a farm worker would (PNG files out_dir/f_####); returns the
    CompletedProcess. Renders with this checkout's add-on: the process skips
    the user preferences (--factory-startup), where another Tessera may be
    installed."""
    expr = f"import sys; sys.path.insert(0, {ADDON!r}); import tessera; tessera.register()"
    return subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", str(blend), "--python-expr", expr, "-E", "TESSERA",
                           "-o", os.path.join(str(out_dir), "f_####"), "-F", "PNG", "-f", "1"],
                          capture_output=True, text=True, timeout=300)


def open_scene(name):
    bpy.ops.wm.open_mainfile(filepath=os.path.join(SCENES, name))
    return bpy.context.scene


def set_size(scene, width, height=None):
    """Renders at width x height keeping the aspect when height is None."""
    r = scene.render
    if height is None:
        height = max(1, round(width * r.resolution_y / r.resolution_x))
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100


def configure_engine(scene, engine, samples=64, bounces=8, seed=0, threads=0, adaptive_threshold=None):
    """Sets the engine and the settings both engines share (samples, bounces,
    seed, threads); Cycles without denoising, clamping or glossy blur, so that
    both estimate the same image. Adaptive sampling: Cycles' is off unless
    adaptive_threshold > 0 is given, which both engines then use (min samples
    automatic); None leaves Tessera's own setting as it is."""
    r = scene.render
    r.engine = engine
    if engine == 'CYCLES':
        scene.cycles.device = 'CPU'
        scene.cycles.samples = samples
        scene.cycles.max_bounces = bounces
        for kind in ("diffuse", "glossy", "transmission", "transparent_max"):
            setattr(scene.cycles, f"{kind}_bounces", max(bounces, 1))
        scene.cycles.volume_bounces = 0
        scene.cycles.use_denoising = False
        scene.cycles.use_adaptive_sampling = bool(adaptive_threshold)
        if adaptive_threshold:
            scene.cycles.adaptive_threshold = adaptive_threshold
            scene.cycles.adaptive_min_samples = 0
        scene.cycles.seed = seed
        scene.cycles.sample_clamp_direct = 0.0
        scene.cycles.sample_clamp_indirect = 0.0
        scene.cycles.caustics_reflective = True
        scene.cycles.caustics_refractive = True
        scene.cycles.blur_glossy = 0.0
        r.threads_mode = 'AUTO' if threads == 0 else 'FIXED'
        if threads:
            r.threads = threads
    else:
        t = scene.tessera
        t.samples, t.max_bounces, t.seed, t.threads = samples, bounces, seed, threads
        if adaptive_threshold is not None:
            t.adaptive_threshold, t.adaptive_min_samples = adaptive_threshold, 0


def render(scene, engine, samples=64, bounces=8, seed=0, threads=0, adaptive_threshold=None):
    """Renders the scene's camera view; returns float32 (H, W, 4), rows top to bottom."""
    configure_engine(scene, engine, samples, bounces, seed, threads, adaptive_threshold)
    return render_as_configured(scene, engine)


def render_as_configured(scene, engine):
    """render() with the engine's settings as they are (configure_engine first, then any of its own)."""
    r = scene.render
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    r.use_compositing = False
    r.use_sequencer = False
    path = os.path.join(tempfile.mkdtemp(prefix="tessera_test_"), f"{engine.lower()}.exr")
    r.filepath = path
    bpy.ops.render.render(write_still=True)
    px = load_image(path)
    os.remove(path)
    return px


def load_image(path):
    """An image file's pixels as float32 (H, W, 4), rows top to bottom."""
    img = bpy.data.images.load(path)
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1]


def downsample(img, factor):
    h, w = img.shape[0] // factor * factor, img.shape[1] // factor * factor
    return img[:h, :w, :3].reshape(h // factor, factor, w // factor, factor, 3).mean(axis=(1, 3))


def compare(test, ref):
    """Mean per channel ratio, relative RMSE after 1/8 downsampling and the worst 8x8 block."""
    mean_t = test[..., :3].reshape(-1, 3).mean(axis=0)
    mean_r = ref[..., :3].reshape(-1, 3).mean(axis=0)
    dt, dr = downsample(test, 8), downsample(ref, 8)
    scale = max(float(dr.mean()), 1e-8)
    rel_rmse = float(np.sqrt(np.mean((dt - dr) ** 2)) / scale)
    bt, br = downsample(dt, 8) if min(dt.shape[:2]) >= 8 else dt, downsample(dr, 8) if min(dr.shape[:2]) >= 8 else dr
    worst_block = float(np.max(np.abs(bt - br).mean(axis=-1) / np.maximum(br.mean(axis=-1), scale * 0.1)))
    return {"mean_test": mean_t, "mean_ref": mean_r,
            "mean_rel_diff": np.abs(mean_t - mean_r) / np.maximum(mean_r, 1e-6),
            "rel_rmse": rel_rmse, "worst_block": worst_block}


def remove_duplicate_faces(scene):
    """Deletes faces that repeat another face of the same mesh exactly.
    Returns how many were removed. (Cycles 3.4 renders such coincident faces
    with z-fighting stripes, Tessera as one surface; comparisons use clean data.)"""
    import bmesh
    removed = 0
    for obj in scene.objects:
        if obj.type != 'MESH':
            continue
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        seen, doomed = set(), []
        for f in bm.faces:
            key = tuple(sorted(tuple(round(c, 6) for c in v.co) for v in f.verts))
            if key in seen:
                doomed.append(f)
            else:
                seen.add(key)
        if doomed:
            bmesh.ops.delete(bm, geom=doomed, context='FACES_ONLY')
            bm.to_mesh(obj.data)
            removed += len(doomed)
        bm.free()
    return removed


def enlarge_small_lights(scene, min_radius=0.15, min_area_size=0.5):
    """Gives every point and spot light at least min_radius and every area light
    at least min_area_size on each side (same Watts), and returns how many lights
    changed. Caustics of tiny lights seen through smooth glass (bunny_glass: a
    1 cm spot and a 20 x 10 cm area light behind a glass bunny) are found only by
    BSDF sampling, so their estimate is heavy-tailed: at test sample counts the
    image mean swings by several percent from seed to seed in both engines.
    Larger lights keep the same glass paths and light models, converged."""
    changed = 0
    for obj in scene.objects:
        if obj.type != 'LIGHT':
            continue
        light = obj.data
        if light.type in ('POINT', 'SPOT') and light.shadow_soft_size < min_radius:
            light.shadow_soft_size = min_radius
            changed += 1
        elif light.type == 'AREA':
            before = (light.size, light.size_y)
            light.size = max(light.size, min_area_size)
            light.size_y = max(light.size_y, min_area_size)
            changed += (light.size, light.size_y) != before
    return changed
