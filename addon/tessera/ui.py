"""Tessera's panels in Render Properties and the Light tab, and Blender's own
panels (output, dimensions, colour management, camera, material, world)
enabled for the engine."""

import bpy

from . import core
from .engine import TesseraRenderEngine

ENGINE = TesseraRenderEngine.bl_idname


class TesseraPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class TESSERA_PT_sampling(TesseraPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.tessera
        if core.load_error:
            layout.label(text="Native core not loaded; see the Info editor for why", icon='ERROR')
        layout.prop(settings, "preset")
        col = layout.column(align=True)
        col.prop(settings, "samples", text="Max Samples" if settings.adaptive_threshold > 0 else "Samples")
        col.prop(settings, "seed")
        col = layout.column(align=True, heading="Adaptive")
        col.prop(settings, "adaptive_threshold")
        sub = col.column(align=True)
        sub.active = settings.adaptive_threshold > 0
        sub.prop(settings, "adaptive_min_samples")
        col = layout.column(align=True)
        col.prop(settings, "time_limit")
        col.prop(settings, "error_target")
        sub = col.column(align=True)
        sub.active = settings.error_target == 0
        sub.prop(settings, "estimate_error")
        layout.prop(settings, "filter_width")
        layout.prop(settings, "max_camera_rays")
        layout.prop(settings, "light_threshold")


class TESSERA_PT_light_paths(TesseraPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.tessera
        col = layout.column(align=True, heading="Max Bounces")
        col.prop(settings, "max_bounces")
        col.prop(settings, "max_diffuse_bounces")
        col.prop(settings, "max_glossy_bounces")
        col.prop(settings, "max_transmission_bounces")
        col.prop(settings, "max_transparent_bounces")
        col = layout.column(align=True, heading="Clamping")
        col.prop(settings, "clamp_direct")
        col.prop(settings, "clamp_indirect")
        layout.prop(settings, "caustic_light_paths")
        layout.prop(settings, "diffuse_texture_blur")
        layout.prop(settings, "rr_depth")


class TESSERA_PT_film(TesseraPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        # Blender's own setting, as Cycles' Film panel shows it.
        layout.prop(context.scene.render, "film_transparent", text="Transparent")


class TESSERA_PT_performance(TesseraPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.tessera
        col = layout.column(align=True)
        col.prop(settings, "threads")
        col.prop(settings, "tile_size")


class TESSERA_PT_passes_data(bpy.types.Panel):
    """View Layer > Passes > Data: the passes Tessera writes besides Combined."""
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "view_layer"
    bl_label = "Data"
    bl_parent_id = "VIEWLAYER_PT_layer_passes"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        view_layer = context.view_layer
        col = layout.column(heading="Include", align=True)
        col.prop(view_layer, "use_pass_combined")
        col.prop(view_layer, "use_pass_z")
        col.prop(view_layer, "use_pass_normal")
        col.prop(view_layer, "use_pass_diffuse_color", text="Diffuse Color")
        col.prop(view_layer, "use_pass_emit", text="Emission")
        col.prop(view_layer.tessera, "denoising_store_passes")
        col = layout.column(heading="Debug", align=True)
        col.prop(view_layer.tessera, "pass_debug_sample_count")


class TesseraLightPanel(TesseraPanel):
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.light is not None and super().poll(context)


def _has(light, name):
    """Whether this Blender's Light has the property (exposure, normalize,
    soft falloff and temperature are 4.x)."""
    return name in light.bl_rna.properties


class TESSERA_LIGHT_PT_light(TesseraLightPanel, bpy.types.Panel):
    """The one Light panel, laid out as Cycles' (type, colour, power, shape),
    with only what Tessera reads (export/lights.py): no EEVEE factors, shadow
    or distance settings, no Cycles portal or per-light bounces."""
    bl_label = "Light"

    def draw(self, context):
        layout = self.layout
        light = context.light
        if self.bl_space_type == 'PROPERTIES':
            layout.row().prop(light, "type", expand=True)
            layout.use_property_split = True
        else:
            layout.use_property_split = True
            layout.row().prop(light, "type")
        col = layout.column()
        if _has(light, "use_temperature"):
            row = col.row(align=True, heading="Temperature")
            row.prop(light, "use_temperature", text="")
            sub = row.row(align=True)
            sub.active = light.use_temperature
            sub.prop(light, "temperature", text="")
            col.prop(light, "color", text="Tint" if light.use_temperature else "Color")
        else:
            col.prop(light, "color")
        col.separator()
        col.prop(light, "energy")
        if _has(light, "exposure"):
            col.prop(light, "exposure")
        if _has(light, "normalize"):
            col.prop(light, "normalize")
        col.separator()
        if light.type in {'POINT', 'SPOT'}:
            col.prop(light, "shadow_soft_size", text="Radius")
            if _has(light, "use_soft_falloff"):
                col.prop(light, "use_soft_falloff")
        elif light.type == 'SUN':
            col.prop(light, "angle")
        elif light.type == 'AREA':
            col.prop(light, "shape", text="Shape")
            sub = col.column(align=True)
            if light.shape in {'SQUARE', 'DISK'}:
                sub.prop(light, "size")
            else:
                sub.prop(light, "size", text="Size X")
                sub.prop(light, "size_y", text="Y")


class TESSERA_LIGHT_PT_beam_shape(TesseraLightPanel, bpy.types.Panel):
    bl_label = "Beam Shape"
    bl_parent_id = "TESSERA_LIGHT_PT_light"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.light.type in {'SPOT', 'AREA'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        light = context.light
        col = layout.column()
        if light.type == 'SPOT':
            col.prop(light, "spot_size", text="Spot Size")
            col.prop(light, "spot_blend", text="Blend", slider=True)
            col.prop(light, "show_cone")
        else:
            col.prop(light, "spread", text="Spread")


classes = (TESSERA_PT_sampling, TESSERA_PT_light_paths, TESSERA_PT_film, TESSERA_PT_performance, TESSERA_PT_passes_data,
           TESSERA_LIGHT_PT_light, TESSERA_LIGHT_PT_beam_shape)

# Blender's own panels that apply to any engine which renders the usual data.
_BLENDER_PANELS = (
    "RENDER_PT_color_management", "RENDER_PT_color_management_curves", "RENDER_PT_format",
    "RENDER_PT_frame_range", "RENDER_PT_output", "RENDER_PT_output_views", "RENDER_PT_encoding",
    "RENDER_PT_encoding_video", "RENDER_PT_encoding_audio", "RENDER_PT_post_processing", "RENDER_PT_stamp",
    "RENDER_PT_stamp_note", "RENDER_PT_stamp_burn", "RENDER_PT_time_stretching", "RENDER_PT_format_presets",
    "DATA_PT_context_camera", "DATA_PT_lens", "DATA_PT_camera", "DATA_PT_camera_display", "DATA_PT_camera_safe_areas",
    "DATA_PT_camera_background_image", "DATA_PT_camera_dof", "DATA_PT_camera_dof_aperture", "DATA_PT_custom_props_camera",
    # Lights: Tessera's own panels above instead of Blender's DATA_PT_light (the type row only),
    # DATA_PT_area/DATA_PT_spot and EEVEE's panels (whose factors and shadows Tessera ignores).
    "DATA_PT_context_light", "DATA_PT_light_animation", "DATA_PT_custom_props_light",
    "MATERIAL_PT_preview", "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface",
    "MATERIAL_PT_custom_props", "MATERIAL_PT_viewport",
    "WORLD_PT_context_world", "EEVEE_WORLD_PT_surface", "WORLD_PT_custom_props", "WORLD_PT_viewport_display",
    "VIEWLAYER_PT_layer", "VIEWLAYER_PT_layer_passes",
)


def _blender_panels():
    for name in _BLENDER_PANELS:
        panel = getattr(bpy.types, name, None)
        if panel is not None and hasattr(panel, "COMPAT_ENGINES"):
            yield panel


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for panel in _blender_panels():
        panel.COMPAT_ENGINES.add(ENGINE)


def unregister():
    for panel in _blender_panels():
        panel.COMPAT_ENGINES.discard(ENGINE)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
