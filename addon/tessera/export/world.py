"""The world: Background colour x strength, or an Environment Texture
(equirectangular image, optionally rotated by a Mapping node) x strength."""

import math

import bpy
import numpy as np

from .. import core
from .materials import image_pixels, output_node
from .nodes import Evaluator, to_color, to_float


def _rotation_matrix(rx, ry, rz):
    # Blender's Euler XYZ: R = Rz * Ry * Rx.
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    rx_m = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry_m = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz_m = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz_m @ ry_m @ rx_m


def _environment(env_node, report, world_name):
    """(pixels (H,W,4) float32 linear, rotation 3x3) of an Environment Texture node, or None."""
    img = env_node.image
    if img is None:
        report.warn(world_name, f"World '{world_name}': the Environment Texture has no image; it is black.")
        return None
    px = image_pixels(img)
    if px is None:
        report.warn(world_name, f"World '{world_name}': image '{img.name}' could not be loaded "
                                f"(missing file?); the environment is black. Relink or pack the image.")
        return None
    if env_node.projection != 'EQUIRECTANGULAR':
        report.warn(world_name, f"World '{world_name}': {env_node.projection} projection is not supported; "
                                f"the image is read as equirectangular.")
    rotation = np.eye(3)
    vec = env_node.inputs['Vector']
    if vec.is_linked:
        src = vec.links[0].from_node
        if src.type == 'MAPPING':
            r = src.inputs['Rotation'].default_value
            # The Mapping node (Point) rotates the texture coordinate: lookup = R * direction.
            rotation = _rotation_matrix(r[0], r[1], r[2])
        elif src.type != 'TEX_COORD':
            report.warn(world_name, f"World '{world_name}': the environment's vector input from "
                                    f"'{src.name}' is not supported; the default mapping is used.")
    return px, rotation.astype(np.float32)


def ray_visibility(world):
    """World Properties > Ray Visibility as the core's ray-kind mask (Volume
    Scatter has no ray in Tessera)."""
    return core.ray_mask(getattr(world, "cycles_visibility", None),
                         (("camera", "RAY_CAMERA"), ("diffuse", "RAY_DIFFUSE"), ("glossy", "RAY_GLOSSY"),
                          ("transmission", "RAY_TRANSMISSION")))


def export_world(scene_core, world, report):
    if world is None:
        return  # Blender renders a missing world as black
    scene_core.set_world_visibility(ray_visibility(world))
    # Blender 5.0 always uses a world's nodes (use_nodes is deprecated there).
    if world.node_tree is None or (bpy.app.version < (5, 0, 0) and not world.use_nodes):
        scene_core.set_world_color(list(world.color)[:3])
        return
    out = output_node(world.node_tree, 'OUTPUT_WORLD')
    if out is None or not out.inputs['Surface'].is_linked:
        return
    bg = out.inputs['Surface'].links[0].from_node
    if bg.type != 'BACKGROUND':
        report.warn(world.name, f"World '{world.name}': surface shader '{bg.name}' is not supported; the world is black.")
        return
    ev = Evaluator(world.name, report)
    strength = to_float(ev.input(bg, 'Strength', 1.0))
    color_socket = bg.inputs['Color']
    if color_socket.is_linked and color_socket.links[0].from_node.type == 'TEX_ENVIRONMENT':
        env = _environment(color_socket.links[0].from_node, report, world.name)
        if env is not None:
            scene_core.set_world_image(env[0], env[1], [strength] * 3)
        return
    color = to_color(ev.socket(color_socket))
    scene_core.set_world_color([c * strength for c in color[:3]])
