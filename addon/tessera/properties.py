"""Render settings: scene.tessera. Each field is copied into the core's
RenderOptions in engine.py and read where it is used."""

import bpy
from bpy.props import FloatProperty, IntProperty, PointerProperty


class TesseraRenderSettings(bpy.types.PropertyGroup):
    samples: IntProperty(
        name="Samples", description="Number of samples per pixel",
        default=64, min=1, soft_max=4096)
    max_bounces: IntProperty(
        name="Max Bounces", description="Total maximum number of bounces; 0 renders direct light only",
        default=8, min=0, max=1024)
    rr_depth: IntProperty(
        name="Russian Roulette Depth", description="Bounce from which paths are ended at random by their throughput",
        default=3, min=1, max=1024)
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


def register():
    bpy.utils.register_class(TesseraRenderSettings)
    bpy.types.Scene.tessera = PointerProperty(type=TesseraRenderSettings)


def unregister():
    del bpy.types.Scene.tessera
    bpy.utils.unregister_class(TesseraRenderSettings)
