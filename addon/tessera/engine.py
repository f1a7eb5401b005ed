"""The RenderEngine: exports the evaluated scene, runs the native render on a
background thread with the GIL released, shows progress, honours cancel and
writes the pixels into Blender's render result in one bulk call."""

import bpy
import numpy as np

from . import core

# Figures of the last finished render, for benchmarks and tests.
last_render_stats = {}


def render_size(scene):
    # Blender's own integer formula (BKE_render_resolution): res * pct // 100.
    r = scene.render
    pct = r.resolution_percentage
    return max(1, r.resolution_x * pct // 100), max(1, r.resolution_y * pct // 100)


def render_region(scene, width, height):
    """(x0, y0, x1, y1) in pixels from the bottom-left: the border, or the frame."""
    r = scene.render
    if not r.use_border:
        return 0, 0, width, height
    # As Blender (and Cycles) size the border: float32 product, truncated.
    f32 = np.float32
    x0, x1 = int(f32(r.border_min_x) * f32(width)), int(f32(r.border_max_x) * f32(width))
    y0, y1 = int(f32(r.border_min_y) * f32(height)), int(f32(r.border_max_y) * f32(height))
    if x1 <= x0 or y1 <= y0:
        return 0, 0, width, height
    return x0, y0, x1, y1


def format_seconds(s):
    if s >= 60:
        return f"{int(s // 60)}:{s % 60:04.1f}"
    return f"{s:.1f} s"


def live_status(session, total):
    """Status text while rendering: samples, time, remaining, rays/s, error."""
    done = session.samples_done
    elapsed = session.elapsed_seconds
    # Samples, rays and progress are as of the last pass: rate and remaining
    # time are measured at that moment (update_seconds), counting down since.
    updated = session.update_seconds
    progress = session.progress
    text = f"Tessera | Sample {done}/{total} | {format_seconds(elapsed)}"
    remaining = session.remaining_seconds
    if 0 < progress < 1 and remaining >= 0:
        text += f" | Remaining {format_seconds(remaining)}"
    if updated > 0:
        text += f" | {session.rays / updated / 1e6:.2f} Mrays/s"
    if session.estimated_error > 0:
        text += f" | Error {100 * session.estimated_error:.2f}%"
    return text, progress


# The passes besides Combined, as Cycles names and registers them
# (intern/cycles/blender/addon/engine.py): (core name, name in this Blender,
# channel ids, type, enabled(view_layer)). Blender 5.0 renamed two of them.
_BLENDER_5 = bpy.app.version >= (5, 0, 0)
PASSES = (
    ("Depth", "Depth", "Z", 'VALUE', lambda vl: vl.use_pass_z),
    ("Normal", "Normal", "XYZ", 'VECTOR', lambda vl: vl.use_pass_normal),
    ("Emit", "Emission" if _BLENDER_5 else "Emit", "RGB", 'COLOR', lambda vl: vl.use_pass_emit),
    ("DiffCol", "Diffuse Color" if _BLENDER_5 else "DiffCol", "RGB", 'COLOR', lambda vl: vl.use_pass_diffuse_color),
    ("Denoising Normal", "Denoising Normal", "XYZ", 'VECTOR', lambda vl: _denoising_data(vl)),
    ("Denoising Albedo", "Denoising Albedo", "RGB", 'COLOR', lambda vl: _denoising_data(vl)),
    ("Denoising Depth", "Denoising Depth", "Z", 'VALUE', lambda vl: _denoising_data(vl)),
    ("Debug Sample Count", "Debug Sample Count", "X", 'VALUE', lambda vl: _sample_count(vl)),
)
# Blender's pass name -> the core's.
CORE_PASS = {blender: core_name for core_name, blender, _, _, _ in PASSES}


def _denoising_data(view_layer):
    settings = getattr(view_layer, "tessera", None)
    return bool(settings is not None and settings.denoising_store_passes)


def _sample_count(view_layer):
    settings = getattr(view_layer, "tessera", None)
    return bool(settings is not None and settings.pass_debug_sample_count)


def enabled_passes(view_layer):
    """The core's names of the passes besides Combined that the view layer asks for."""
    return [core_name for core_name, _, _, _, enabled in PASSES if enabled(view_layer)]


def pass_bits(names):
    """RenderOptions.passes for these passes (core names), decided once per render."""
    bits = 0
    for name in names:
        bits |= core.native.PASSES[name]
    return bits


def render_options(settings, region):
    opt = core.native.RenderOptions()
    opt.samples = settings.samples
    opt.max_bounces = settings.max_bounces
    opt.max_diffuse_bounces = settings.max_diffuse_bounces
    opt.max_glossy_bounces = settings.max_glossy_bounces
    opt.max_transmission_bounces = settings.max_transmission_bounces
    opt.max_transparent_bounces = settings.max_transparent_bounces
    opt.rr_depth = settings.rr_depth
    opt.clamp_direct = settings.clamp_direct
    opt.clamp_indirect = settings.clamp_indirect
    opt.light_threshold = settings.light_threshold
    opt.caustic_light_paths = settings.caustic_light_paths
    opt.adaptive_threshold = settings.adaptive_threshold
    opt.adaptive_min_samples = settings.adaptive_min_samples
    opt.time_limit = settings.time_limit
    opt.error_target = settings.error_target
    opt.estimate_error = settings.estimate_error
    opt.seed = settings.seed
    opt.threads = settings.threads
    opt.tile_size = settings.tile_size
    opt.filter_width = settings.filter_width
    opt.max_camera_rays = settings.max_camera_rays
    opt.region_x0, opt.region_y0, opt.region_x1, opt.region_y1 = region
    return opt


class TesseraRenderEngine(bpy.types.RenderEngine):
    bl_idname = "TESSERA"
    bl_label = "Tessera"
    bl_use_preview = True
    bl_use_eevee_viewport = True
    bl_use_postprocess = True

    def update_render_passes(self, scene=None, renderlayer=None):
        # Declares the view layer's passes, so that the render result and the
        # compositor's Render Layers node have them (as Cycles' register_passes).
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", 'COLOR')
        for _, name, chan_id, kind, enabled in PASSES:
            if enabled(renderlayer):
                self.register_pass(scene, renderlayer, name, len(chan_id), chan_id, kind)

    def cancel_requested(self):
        """Blender's test_break (Escape, or a closed render window), asked in
        one place so that tests can simulate a user cancelling."""
        return self.test_break()

    def render(self, depsgraph):
        # An exception escaping render() makes Blender save a black frame and
        # exit 0; report it as an error instead, so that a headless render
        # (and a render farm) sees the failure.
        try:
            self._render(depsgraph)
        except MemoryError:
            import traceback
            traceback.print_exc()
            self.report({'ERROR'}, "Tessera ran out of memory. Lower the resolution, the number of enabled "
                                   "passes or the scene's size, or close other programs, and render again.")
        except Exception as e:  # noqa: BLE001 - every failure must reach the report
            import traceback
            traceback.print_exc()
            self.report({'ERROR'}, f"Tessera failed to render: {type(e).__name__}: {e}. "
                                   f"Please report this with the traceback printed above.")

    def _render(self, depsgraph):
        if core.native is None:
            self.report({'ERROR'}, core.load_error)
            return
        from .export import ExportError, export_scene

        scene = depsgraph.scene
        width, height = render_size(scene)
        region = render_region(scene, width, height)
        from .memory import render_memory_error
        too_big = render_memory_error(width, height, region[2] - region[0], region[3] - region[1])
        if too_big:
            self.report({'ERROR'}, too_big)
            return
        self.update_stats("", "Tessera: exporting scene")
        try:
            scene_core, stats, report = export_scene(depsgraph, width, height, self.cancel_requested,
                                                     self.camera_override)
        except ExportError as e:
            self.report({'ERROR'}, str(e))
            return
        if scene_core is not None and stats["triangles"] == 0:
            report.warnings.append("Tessera: the scene has no visible geometry; only the world is rendered.")
        # A material preview renders Blender's own preview scene (whose floor
        # uses nodes Tessera does not evaluate): its warnings are not the user's.
        for message in ([] if self.is_preview else report.warnings):
            self.report({'WARNING'}, message)
            print(f"Tessera: warning: {message}")
        if scene_core is None:
            return  # cancelled during export

        settings = scene.tessera
        options = render_options(settings, region)
        options.passes = pass_bits(enabled_passes(depsgraph.view_layer))
        options.pass_alpha_threshold = depsgraph.view_layer.pass_alpha_threshold
        options.film_transparent = scene.render.film_transparent
        session = core.native.Session(scene_core, options)
        x0, y0, x1, y1 = region
        # Blender's render result is the border only, with or without crop (it pastes
        # the border into the full frame itself when not cropping): offset 0, 0.
        w, h = x1 - x0, y1 - y0
        # The result of the view layer being rendered only (Blender calls
        # render() once per view layer; without the name, layers[0] was always
        # the first one).
        result = self.begin_result(0, 0, w, h, layer=depsgraph.view_layer.name)
        if result is None or (result.resolution_x, result.resolution_y) != (w, h):
            if result is not None:
                self.end_result(result, cancel=True)
            self.report({'ERROR'}, f"Tessera: Blender's render result is not the {w}x{h} region Tessera "
                                   f"computed from the border; nothing was rendered.")
            return
        layer = result.layers[0]
        total = settings.samples
        session.start()
        shown = 0
        # What the user saw during the render (last_render_stats; tests).
        display_updates = progress_updates = 0
        progress = 0.0
        while not session.wait(0.1):
            if self.cancel_requested():
                session.cancel()
                session.wait(30.0)
                self.end_result(result, cancel=True)
                return
            done = session.samples_done
            text, progress = live_status(session, total)
            self.update_progress(progress)
            progress_updates += 1
            self.update_stats("", text)
            if done > shown:
                self._write(layer, session)
                self.update_result(result)
                display_updates += 1
                shown = done
        self._write(layer, session)
        self.end_result(result)
        progress = 1.0  # finished (also when stopped early by a time limit or error target)
        self.update_progress(progress)
        progress_updates += 1
        rs = session.stats()
        rays_per_s = rs["rays"] / max(rs["seconds"], 1e-9)
        pixel_samples_per_s = rs["pixel_samples"] / max(rs["seconds"], 1e-9)
        mean_spp = rs["pixel_samples"] / max(1, w * h)
        summary = (f"Tessera: {width}x{height} region {w}x{h}, {rs['samples_done']} samples "
                   f"(mean {mean_spp:.1f} per pixel, stopped by {rs['stop_reason']}), "
                   f"export {stats['export_seconds']:.3f} s, BVH {stats['blas_build_seconds'] + stats['tlas_build_seconds']:.3f} s, "
                   f"render {rs['seconds']:.3f} s, {stats['triangles']} triangles "
                   f"({stats['instanced_triangles']} instanced, {stats['instances']} instances), "
                   f"{pixel_samples_per_s / 1e6:.3f} Msamples/s, {rays_per_s / 1e6:.2f} Mrays/s, "
                   + (f"estimated error {100 * rs['estimated_error']:.2f}%" if rs["estimated_error"] > 0
                      else "error not estimated (Estimate Error is off)"))
        if rs["light_paths"]:
            summary += f", {rs['light_paths']} caustic light paths"
        if rs["antialiased_pixels"]:
            summary += f", emitter antialiasing on {rs['antialiased_pixels']} pixels"
        if rs["invalid_samples"]:
            summary += f", {rs['invalid_samples']} NaN/Inf samples discarded"
        print(summary)
        self.update_stats("", summary)
        last_render_stats.clear()
        last_render_stats.update(stats)
        last_render_stats.update(render_seconds=rs["seconds"], rays=rs["rays"], samples=rs["samples_done"],
                                 rays_per_second=rays_per_s, invalid_samples=rs["invalid_samples"],
                                 pixel_samples=rs["pixel_samples"], samples_per_second=pixel_samples_per_s,
                                 mean_samples=mean_spp, estimated_error=rs["estimated_error"],
                                 stop_reason=rs["stop_reason"], active_pixels=rs["active_pixels"],
                                 antialiased_pixels=rs["antialiased_pixels"], light_paths=rs["light_paths"],
                                 warnings=list(report.warnings), display_updates=display_updates,
                                 progress_updates=progress_updates, final_progress=progress)

    @staticmethod
    def _write(layer, session):
        # One bulk write of every pass of the layer, in the layer's order; a
        # pass the core does not make (none so far) stays black.
        combined = session.pixels()
        num_pixels = combined.shape[0] * combined.shape[1]
        parts = []
        for render_pass in layer.passes:
            if render_pass.name == "Combined":
                parts.append(combined)
            elif render_pass.name in CORE_PASS:
                parts.append(session.pass_pixels(CORE_PASS[render_pass.name]))
            else:
                parts.append(np.zeros(num_pixels * render_pass.channels, dtype=np.float32))
        data = np.concatenate([np.ascontiguousarray(p, dtype=np.float32).ravel() for p in parts])
        layer.passes.foreach_set("rect", data)


def register():
    bpy.utils.register_class(TesseraRenderEngine)


def unregister():
    bpy.utils.unregister_class(TesseraRenderEngine)
