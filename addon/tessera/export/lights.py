"""Blender lights, converted from Watts (W/m^2 for the sun) to the radiance
or intensity the core samples, exactly as the Cycles of the running Blender
converts them (intern/cycles/scene/light.cpp and kernel/light/*.h):

- point/spot, radius r > 0: radiance P / (4 pi * pi r^2) (Light::area is the
  sphere's 4 pi r^2), seen as the disk facing the shading point (3.x; 4.x's
  default "Soft Falloff"), or, in 4.x with Soft Falloff off, emitted from the
  sphere's surface (kernel/light/point.h, is_sphere); r = 0: intensity
  P / (4 pi). Unnormalised (4.x): radiance P / pi. The object's scale does
  not change the radius.
- spot edge: 3.x multiplies the smoothstep by the cosine to the axis; 4.0+
  uses the smoothstep alone (kernel/light/spot.h). 4.0+ measures the angle
  in the light object's own space (spot_light_to_local, through the inverse
  transform), so a non-uniform scale makes the cone elliptical; 3.x uses the
  normalised -Z axis whatever the scale.
- area: 3.x radiance P / (4 A); 4.0+ P / (pi A), the physical value, and
  files older than 4.0 are versioned with energy *= pi / 4 (versioning_400,
  "Fix area light scaling"); unnormalised (4.x): P / pi.
- area Spread s (Cycles' soft box, kernel/light/area.h,
  area_light_spread_attenuation): radiance at angle a to the normal times
  max((tan h - tan a) / (tan h - h), 0), h = s / 2, which keeps the power.
  3.x writes it as (1 - tan(pi/2 - h) tan a) * 2 / (2 + (2 (pi/2 - h) - pi)
  tan(pi/2 - h)), the same function, with s clamped to at least 1 degree and
  no attenuation at exactly 180; 4.x takes any s > 0 (a Taylor expansion of
  the normalisation below 0.05 rad, the same value) and s = 0 as a parallel
  beam, which Tessera renders as a spread of 0.1 degree (see area_spread).
- sun of half angle h: 4.x constant radiance E / (pi sin^2 h) over the
  cone, irradiance E; 3.x sampled a disk tan(h) one unit away and weighted
  each direction by its own pdf (eval_fac = pdf), irradiance
  E 2 cos h / (1 + cos h) at normal incidence: the constant radiance with
  that irradiance is used (exact at normal incidence). Unnormalised (4.x): E.
"""

import math

import bpy
import numpy as np

# Cycles 4.0 changed area light units, spot edges and sun normalisation.
CYCLES_4 = bpy.app.version >= (4, 0, 0)


def light_color(light):
    """Colour x power in Watts (W/m^2 for the sun), as Cycles' sync_light:
    colour (x blackbody colour when the temperature is used) x energy x 2^exposure."""
    color = np.array(light.color, dtype=np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.array(light.temperature_color, dtype=np.float64)
    return color * float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def point_radiance(power, radius, normalize=True):
    """Radiance of a point/spot light of radius > 0, or intensity at radius 0."""
    if radius <= 0.0:
        return power / (4.0 * math.pi)
    if not normalize:
        return power / math.pi
    return power / (4.0 * math.pi * math.pi * radius * radius)


def area_radiance(power, area, normalize=True, cycles4=CYCLES_4):
    if not normalize:
        return power / math.pi
    return power / (math.pi * area) if cycles4 else power / (4.0 * area)


# Cycles 3.x clamps the spread to at least 1 degree; 4.x renders 0 as a
# parallel beam, which Tessera approximates by this spread.
MIN_SPREAD_3X = math.radians(1.0)
MIN_SPREAD_4X = math.radians(0.1)


def area_spread(spread, cycles4=CYCLES_4):
    """(tan of the half spread, normalisation) of an area light's Spread, as
    Cycles' scene/light.cpp sets tan_half_spread and normalize_spread (the
    attenuation is max((tan_half - tan a) * norm, 0)); None at 180 degrees,
    where Cycles attenuates nothing. In double: 1 / (tan h - h) cancels in
    float for narrow spreads."""
    spread = float(spread)
    if not math.isfinite(spread) or spread >= math.pi:
        return None
    spread = max(spread, MIN_SPREAD_4X if cycles4 else MIN_SPREAD_3X)
    half = 0.5 * spread
    tan_half = math.tan(half)
    return tan_half, 1.0 / (tan_half - half)


def sun_radiance(irradiance, half_angle, normalize=True, cycles4=CYCLES_4):
    """Constant radiance over the cone of the sun's half angle (> 0)."""
    if not normalize:
        return irradiance
    s2 = math.sin(half_angle) ** 2
    if cycles4:
        return irradiance / (math.pi * s2)
    c = math.cos(half_angle)
    return irradiance * 2.0 * c / ((1.0 + c) * math.pi * s2)


def spot_to_local(m3):
    """The inverse of a spot light's 3x3 transform, row-major (Cycles 4.x
    measures the cone's angle in the light's own space), or None if it has
    no finite inverse."""
    m3 = np.asarray(m3, dtype=np.float64)
    scale = max(float(np.abs(m3).max()), 1e-300)
    if abs(np.linalg.det(m3 / scale)) < 1e-12:
        return None
    inv = np.linalg.inv(m3)
    return inv.reshape(-1).tolist() if np.all(np.isfinite(inv)) else None


def casts_shadow(light):
    """Light Properties > Cast Shadow as Cycles reads it: the Cycles setting on
    Blender 3.x, the light's own from 4.0 (which 3.x's EEVEE used)."""
    cycles_settings = getattr(light, "cycles", None)
    if cycles_settings is not None and hasattr(cycles_settings, "cast_shadow"):
        return bool(cycles_settings.cast_shadow)
    return bool(getattr(light, "use_shadow", True))


def export_light(scene_core, obj, matrix_world, report, visibility):
    """visibility: the core's ray-kind mask (export.ray_visibility)."""
    light = obj.data
    m = np.array(matrix_world, dtype=np.float64)
    if not np.all(np.isfinite(m)):
        report.warn(obj.name, f"Light '{obj.name}' has a non-finite transform; it is ignored.")
        return
    power = light_color(light)
    if not np.all(np.isfinite(power)) or not (power > 0.0).any():
        return
    position = m[:3, 3]
    z_axis = m[:3, 2]
    if np.linalg.norm(z_axis) == 0.0:
        report.warn(obj.name, f"Light '{obj.name}' has zero scale; it is ignored.")
        return
    direction = -z_axis / np.linalg.norm(z_axis)  # lights shine down their local -Z
    kind = light.type
    cycles_settings = getattr(light, "cycles", None)
    if kind == 'AREA' and getattr(cycles_settings, "is_portal", False):
        # A portal emits nothing in Cycles (Light::has_contribution); it only
        # guides the sampling of the world, which Tessera samples without it.
        return
    normalize = bool(getattr(light, "normalize", True))  # Blender 4.x "Normalize"
    if getattr(light, "use_nodes", False):
        report.warn(obj.name, f"Light '{obj.name}' uses a node tree, which Tessera ignores; "
                              f"its colour and power are used.")
    args = dict(type=kind, position=position.tolist(), direction=direction.tolist(), visibility=visibility)
    if kind in ('POINT', 'SPOT'):
        radius = float(light.shadow_soft_size)
        if radius > 0.0:
            args["radius"] = radius
            # Blender 4.x: Soft Falloff off makes it a sphere light (Cycles' is_sphere).
            args["sphere"] = CYCLES_4 and not getattr(light, "use_soft_falloff", True)
        args["radiance"] = point_radiance(power, radius, normalize).tolist()
        if kind == 'SPOT':
            spot_cos = math.cos(0.5 * float(light.spot_size))
            args["spot_cos"] = spot_cos
            args["spot_smooth"] = (1.0 - spot_cos) * float(light.spot_blend)
            args["spot_cosine"] = not CYCLES_4
            if CYCLES_4:
                to_local = spot_to_local(m[:3, :3])
                if to_local is None:
                    report.warn(obj.name, f"Spot light '{obj.name}' has a zero or non-invertible scale, so its "
                                          f"cone has no shape in Cycles; Tessera uses a round cone. Give the "
                                          f"light a non-zero scale on every axis.")
                else:
                    args["spot_to_local"] = to_local
    elif kind == 'SUN':
        half = 0.5 * float(light.angle)
        if half > 0.0:
            # The core samples the cone as a disk of radius tan(h) one unit away.
            args["radius"] = math.tan(min(half, 0.5 * math.pi - 1e-3))
            args["radiance"] = sun_radiance(power, half, normalize).tolist()
        else:
            args["radiance"] = power.tolist()
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
        spread = area_spread(getattr(light, "spread", math.pi))
        if spread is not None:
            args["spread_tan"], args["spread_norm"] = spread
        args["axis_u"] = axis_u.tolist()
        args["axis_v"] = axis_v.tolist()
        args["ellipse"] = shape in ('DISK', 'ELLIPSE')
        args["radiance"] = area_radiance(power, area, normalize).tolist()
    else:
        report.warn(obj.name, f"Light '{obj.name}' of type {kind} is not supported; it is ignored.")
        return
    scene_core.add_light(**args)
