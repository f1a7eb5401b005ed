"""Blender lights, converted from Watts (W/m^2 for the sun) to the radiance
or intensity the core samples, exactly as Cycles converts them."""

import math

import numpy as np


def export_light(scene_core, obj, matrix_world, report):
    light = obj.data
    m = np.array(matrix_world, dtype=np.float64)
    if not np.all(np.isfinite(m)):
        report.warn(obj.name, f"Light '{obj.name}' has a non-finite transform; it is ignored.")
        return
    color = np.array(light.color, dtype=np.float64)
    energy = float(light.energy)
    if not math.isfinite(energy) or energy <= 0.0 or not color.any():
        return
    position = m[:3, 3]
    z_axis = m[:3, 2]
    if np.linalg.norm(z_axis) == 0.0:
        report.warn(obj.name, f"Light '{obj.name}' has zero scale; it is ignored.")
        return
    direction = -z_axis / np.linalg.norm(z_axis)  # lights shine down their local -Z
    kind = light.type
    if getattr(light, "use_nodes", False):
        report.warn(obj.name, f"Light '{obj.name}' uses a node tree, which Tessera ignores; "
                              f"its colour and power are used.")
    args = dict(type=kind, position=position.tolist(), direction=direction.tolist())
    if kind in ('POINT', 'SPOT'):
        radius = float(light.shadow_soft_size)
        intensity = color * energy / (4.0 * math.pi)  # W/sr
        if radius > 0.0:
            args["radius"] = radius
            args["radiance"] = (intensity / (math.pi * radius * radius)).tolist()
        else:
            args["radiance"] = intensity.tolist()
        if kind == 'SPOT':
            spot_cos = math.cos(0.5 * float(light.spot_size))
            args["spot_cos"] = spot_cos
            args["spot_smooth"] = (1.0 - spot_cos) * float(light.spot_blend)
    elif kind == 'SUN':
        half = 0.5 * float(light.angle)
        irradiance = color * energy  # W/m^2
        if half > 0.0:
            r = math.tan(half)
            args["radius"] = r
            args["radiance"] = (irradiance / (math.pi * r * r)).tolist()
        else:
            args["radiance"] = irradiance.tolist()
    elif kind == 'AREA':
        shape = light.shape
        size_x = float(light.size)
        size_y = float(light.size_y) if shape in ('RECTANGLE', 'ELLIPSE') else size_x
        axis_u = m[:3, 0] * (0.5 * size_x)
        axis_v = m[:3, 1] * (0.5 * size_y)
        area = 4.0 * np.linalg.norm(axis_u) * np.linalg.norm(axis_v)
        if shape in ('DISK', 'ELLIPSE'):
            area *= math.pi / 4.0
        if area <= 0.0:
            report.warn(obj.name, f"Area light '{obj.name}' has zero size; it is ignored.")
            return
        if abs(float(getattr(light, "spread", math.pi)) - math.pi) > 1e-3:
            report.warn(obj.name, f"Area light '{obj.name}': spread is not supported yet; it emits over the "
                                  f"full hemisphere.")
        args["axis_u"] = axis_u.tolist()
        args["axis_v"] = axis_v.tolist()
        args["ellipse"] = shape in ('DISK', 'ELLIPSE')
        # Cycles: radiance = P / (4 A) for an area light of power P.
        args["radiance"] = (color * energy / (4.0 * area)).tolist()
    else:
        report.warn(obj.name, f"Light '{obj.name}' of type {kind} is not supported; it is ignored.")
        return
    scene_core.add_light(**args)
