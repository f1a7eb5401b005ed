"""Render settings: scene.tessera. Each field is copied into the core's
RenderOptions in engine.py and read where it is used."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

# Speed against accuracy, in one choice. Each preset sets these fields; a
# field changed by hand afterwards keeps its value (the preset shows 'CUSTOM'
# only in the sense that it is not re-applied).
PRESETS = {
    'PREVIEW': dict(samples=32, adaptive_threshold=0.1, adaptive_min_samples=8, max_bounces=4,
                    max_diffuse_bounces=2, max_glossy_bounces=2, max_transmission_bounces=4,
                    max_transparent_bounces=8,
                    rr_depth=2, clamp_direct=0.0, clamp_indirect=10.0, diffuse_texture_blur=1 / 32, light_threshold=0.01,
                    time_limit=0.0, error_target=0.0),
    'PRODUCTION': dict(samples=1024, adaptive_threshold=0.01, adaptive_min_samples=0, max_bounces=12,
                       max_diffuse_bounces=4, max_glossy_bounces=4, max_transmission_bounces=12,
                       max_transparent_bounces=8,
                       rr_depth=3, clamp_direct=0.0, clamp_indirect=10.0, diffuse_texture_blur=1 / 64,
                       light_threshold=0.01,
                       time_limit=0.0, error_target=0.0),
    'REFERENCE': dict(samples=16384, adaptive_threshold=0.0, adaptive_min_samples=0, max_bounces=64,
                      max_diffuse_bounces=64, max_glossy_bounces=64, max_transmission_bounces=64,
                      max_transparent_bounces=64,
                      rr_depth=8, clamp_direct=0.0, clamp_indirect=0.0, diffuse_texture_blur=0.0, light_threshold=0.0,
                      time_limit=0.0, error_target=0.0),
}


def apply_preset(settings, name):
    for key, value in PRESETS[name].items():
        setattr(settings, key, value)


def _preset_update(self, context):
    if self.preset in PRESETS:
        apply_preset(self, self.preset)


class TesseraRenderSettings(bpy.types.PropertyGroup):
    preset: EnumProperty(
        name="Preset", description="Sets samples, adaptive sampling, bounces and clamping for a purpose",
        items=[('CUSTOM', "Custom", "Settings as set by hand"),
               ('PREVIEW', "Preview", "Fast and noisy: 32 samples, adaptive (threshold 0.1), 4 bounces, indirect clamp 10"),
               ('PRODUCTION', "Production", "Up to 1024 samples, adaptive (threshold 0.01), Cycles' default bounces, indirect clamp 10"),
               ('REFERENCE', "Reference", "Unbiased: 16384 uniform samples, 64 bounces, no clamping, no texture blur")],
        default='CUSTOM', update=_preset_update)
    samples: IntProperty(
        name="Samples", description="Number of samples per pixel (the most any pixel gets with adaptive sampling, "
        "a time limit or an error target)",
        default=64, min=1, soft_max=4096)
    adaptive_threshold: FloatProperty(
        name="Noise Threshold", description="Adaptive sampling: a pixel stops when its estimated error (Cycles' "
        "measure) is below this; with a Time Limit or an Error Target, the pixels still above it share the "
        "samples by their estimated error (noisier pixels get more). 0 disables adaptive sampling",
        default=0.0, min=0.0, max=1.0, soft_max=0.2, precision=4, step=0.1)
    adaptive_min_samples: IntProperty(
        name="Min Samples", description="Adaptive sampling: samples every pixel gets before it may stop; 0 is automatic",
        default=0, min=0, soft_max=4096)
    time_limit: FloatProperty(
        name="Time Limit", description="Stop rendering after this many seconds (with adaptive sampling, the time "
        "goes to the noisiest pixels); 0 disables",
        default=0.0, min=0.0, subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE')
    error_target: FloatProperty(
        name="Error Target", description="Stop when the estimated relative RMSE of the whole image is below this "
        "(e.g. 0.02 = 2%); 0 disables",
        default=0.0, min=0.0, max=1.0, precision=4, step=0.1)
    estimate_error: BoolProperty(
        name="Estimate Error", description="Estimate the image's error for the status line and the render log: a "
        "sparse grid of at least 256 pixels (1/16 of a 120-pixel image, 1/256 of a 1080p frame) also renders an independent "
        "replicate of its samples. Always on with an Error Target",
        default=True)
    max_bounces: IntProperty(
        name="Total", description="Total maximum number of bounces; 0 renders direct light only",
        default=8, min=0, max=1024)
    max_diffuse_bounces: IntProperty(
        name="Diffuse", description="Maximum number of diffuse bounces",
        default=12, min=0, max=1024)
    max_glossy_bounces: IntProperty(
        name="Glossy", description="Maximum number of glossy bounces (specular and glass reflection)",
        default=12, min=0, max=1024)
    max_transmission_bounces: IntProperty(
        name="Transmission", description="Maximum number of transmission bounces (glass refraction)",
        default=12, min=0, max=1024)
    max_transparent_bounces: IntProperty(
        name="Transparent", description="Maximum number of transparent surfaces (Transparent BSDF, Principled Alpha) "
        "a ray passes straight through; they are not counted as bounces (Cycles' Transparent bounces)",
        default=8, min=0, max=1024)
    rr_depth: IntProperty(
        name="Russian Roulette Depth", description="Bounce from which paths are ended at random by their throughput",
        default=3, min=1, max=1024)
    clamp_direct: FloatProperty(
        name="Direct Light", description="Clamp a sample's direct light (seen by the camera or lighting the first "
        "hit) to this largest component; 0 disables",
        default=0.0, min=0.0)
    clamp_indirect: FloatProperty(
        name="Indirect Light", description="Clamp a sample's indirect light to this largest component; 0 disables",
        default=0.0, min=0.0)
    light_threshold: FloatProperty(
        name="Light Threshold", description="Probabilistically skip the shadow rays of light samples that would "
        "add less than this (before the path's throughput), weighting up the ones kept: the same image on "
        "average, a little more noise, fewer rays to lights that barely reach a point (Cycles' Light "
        "Threshold). 0 traces every light sample",
        default=0.01, min=0.0, soft_max=1.0, precision=3, step=0.1)
    caustic_light_paths: FloatProperty(
        name="Caustic Light Paths", description="Light paths traced per camera sample from small point and spot "
        "lights through glass and mirrors, for the caustics seen directly on rough surfaces (path tracing finds "
        "those only when a bounce happens to hit the tiny light through the glass). The same image on average "
        "with far less noise in such caustics; used only where the scene has such lights and smooth surfaces, "
        "with a pinhole camera and no clamping. 0 disables",
        default=0.25, min=0.0, soft_max=2.0, precision=2, step=5)
    diffuse_texture_blur: FloatProperty(
        name="Diffuse Texture Blur", description="After a diffuse bounce, image textures that drive the surface "
        "(color, metallic, roughness) are read box-filtered over this fraction of the image's width and height, "
        "as with Cycles' texture cache: such paths average over much more of the surface anyway, and the small "
        "blurred copy stays in the CPU's cache. What the camera sees "
        "directly and through glossy or glass bounces keeps every texel. 0 disables",
        default=1 / 64, min=0.0, max=1.0, soft_max=0.1, precision=4, step=0.1)
    seed: IntProperty(
        name="Seed", description="Seed of the per-pixel random numbers; the same seed gives the same image",
        default=0, min=0)
    threads: IntProperty(
        name="Threads", description="Number of threads to render with; 0 uses all cores",
        default=0, min=0, max=1024)
    tile_size: IntProperty(
        name="Tile Size", description="Width and height of the square tiles rendered in parallel",
        default=8, min=1, max=1024)
    filter_width: FloatProperty(
        name="Filter Width", description="Width of the Blackman-Harris pixel filter, in pixels",
        default=1.5, min=0.01, max=10.0, subtype='PIXEL')
    max_camera_rays: IntProperty(
        name="Emitter Antialiasing",
        description="Most camera rays per sample in a pixel where the emission seen directly varies, as on the edge "
                    "of a bright light or window: the extra rays only look for that emission, which takes the noise "
                    "off such edges for little time. The extra rays come in powers of two; 1 turns it off",
        default=64, min=1, max=256)


def _update_render_passes(self, context):
    # The compositor's Render Layers node shows the new set of passes.
    view_layer = context.view_layer if context else None
    if view_layer is not None:
        view_layer.update_render_passes()


class TesseraViewLayerSettings(bpy.types.PropertyGroup):
    """view_layer.tessera: passes that Blender's view layer has no flag for."""
    denoising_store_passes: BoolProperty(
        name="Denoising Data", description="Write the Denoising Normal, Albedo and Depth passes (as Cycles "
        "does), for denoising in the compositor",
        default=False, update=_update_render_passes)
    pass_debug_sample_count: BoolProperty(
        name="Sample Count", description="Write the Debug Sample Count pass: the samples each pixel took over "
        "the Samples setting (as Cycles), to see where adaptive sampling and the time limit put the work",
        default=False, update=_update_render_passes)


class TESSERA_OT_apply_preset(bpy.types.Operator):
    """Set samples, adaptive sampling, bounces and clamping from a preset"""
    bl_idname = "tessera.apply_preset"
    bl_label = "Apply Tessera Preset"
    bl_options = {'REGISTER', 'UNDO'}

    preset: EnumProperty(items=[(k, k.title(), "") for k in PRESETS])

    def execute(self, context):
        apply_preset(context.scene.tessera, self.preset)
        return {'FINISHED'}


def register():
    bpy.utils.register_class(TesseraRenderSettings)
    bpy.utils.register_class(TESSERA_OT_apply_preset)
    bpy.types.Scene.tessera = PointerProperty(type=TesseraRenderSettings)
    bpy.utils.register_class(TesseraViewLayerSettings)
    bpy.types.ViewLayer.tessera = PointerProperty(type=TesseraViewLayerSettings)


def unregister():
    del bpy.types.ViewLayer.tessera
    bpy.utils.unregister_class(TesseraViewLayerSettings)
    del bpy.types.Scene.tessera
    bpy.utils.unregister_class(TESSERA_OT_apply_preset)
    bpy.utils.unregister_class(TesseraRenderSettings)
