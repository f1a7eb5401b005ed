"""Folds the value part of a node graph (Value, RGB, Math, Mix, Separate /
Combine, Geometry > Backfacing, ...) into constants, once per material and per
face side. Nodes Tessera does not model are named in one warning each and
replaced by the closest constant (Fresnel and Layer Weight: their average
over viewing directions)."""

import math

import numpy as np

_LUMA = (0.2126, 0.7152, 0.0722)


def to_float(v):
    return v if isinstance(v, float) else _LUMA[0] * v[0] + _LUMA[1] * v[1] + _LUMA[2] * v[2]


def to_color(v):
    return (v, v, v) if isinstance(v, float) else v


def socket_default(socket):
    v = getattr(socket, "default_value", 0.0)
    try:
        return tuple(float(x) for x in v)[:3]
    except TypeError:
        return float(v)


def fresnel_dielectric_cos(cos_i, eta):
    """Cycles' fresnel_dielectric_cos: unpolarised Fresnel reflectance."""
    c = abs(cos_i)
    g = eta * eta - 1.0 + c * c
    if g <= 0.0:
        return 1.0
    g = math.sqrt(g)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


def hemisphere_average(f, n=256):
    """Cosine-weighted average over the hemisphere of f(cos): integral of f(mu) 2 mu dmu."""
    return sum(f((i + 0.5) / n) * 2.0 * (i + 0.5) / n for i in range(n)) / n


def srgb_to_linear(c):
    c = np.asarray(c)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


_MATH = {
    'ADD': lambda a, b, c: a + b, 'SUBTRACT': lambda a, b, c: a - b, 'MULTIPLY': lambda a, b, c: a * b,
    'DIVIDE': lambda a, b, c: a / b if b != 0 else 0.0, 'MULTIPLY_ADD': lambda a, b, c: a * b + c,
    'POWER': lambda a, b, c: a ** b if a > 0 or float(b).is_integer() else 0.0,
    'MINIMUM': lambda a, b, c: min(a, b), 'MAXIMUM': lambda a, b, c: max(a, b),
    'LESS_THAN': lambda a, b, c: float(a < b), 'GREATER_THAN': lambda a, b, c: float(a > b),
    'ABSOLUTE': lambda a, b, c: abs(a), 'SQRT': lambda a, b, c: math.sqrt(a) if a > 0 else 0.0,
    'SIGN': lambda a, b, c: math.copysign(1.0, a) if a != 0 else 0.0,
    'ROUND': lambda a, b, c: math.floor(a + 0.5), 'FLOOR': lambda a, b, c: math.floor(a),
    'CEIL': lambda a, b, c: math.ceil(a), 'FRACT': lambda a, b, c: a - math.floor(a),
    'MODULO': lambda a, b, c: math.fmod(a, b) if b != 0 else 0.0,
    'SINE': lambda a, b, c: math.sin(a), 'COSINE': lambda a, b, c: math.cos(a),
    'EXPONENT': lambda a, b, c: math.exp(min(a, 700.0)), 'INVERSE_SQRT': lambda a, b, c: 1 / math.sqrt(a) if a > 0 else 0.0,
    'SNAP': lambda a, b, c: math.floor(a / b) * b if b != 0 else 0.0,
}


class Evaluator:
    """Evaluates input sockets of a node tree to constants for one face side."""

    def __init__(self, owner_name, report, backfacing=False, image_average=None):
        self.owner = owner_name
        self.report = report
        self.backfacing = backfacing
        self.image_average = image_average
        self.texture_is_sampled = False  # set while reading an input the core samples the image for

    def warn(self, message):
        self.report.warn(self.owner, f"Material '{self.owner}': {message}")

    def input(self, node, name, default=0.0):
        socket = node.inputs.get(name)
        return default if socket is None else self.socket(socket)

    def socket(self, socket):
        if not socket.is_linked:
            return socket_default(socket)
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return socket_default(socket)
        return self.output(link.from_node, link.from_socket)

    def output(self, node, out):
        t = node.type
        if t == 'REROUTE':
            return self.socket(node.inputs[0])
        if t in ('VALUE', 'RGB'):
            return socket_default(node.outputs[0])
        if t == 'NEW_GEOMETRY':
            if out.name == 'Backfacing':
                return 1.0 if self.backfacing else 0.0
            self.warn(f"Geometry > {out.name} is not supported; it is read as 0.")
            return 0.0
        if t == 'MATH':
            a = to_float(self.socket(node.inputs[0]))
            b = to_float(self.socket(node.inputs[1]))
            c = to_float(self.socket(node.inputs[2])) if len(node.inputs) > 2 else 0.0
            op = _MATH.get(node.operation)
            if op is None:
                self.warn(f"Math operation {node.operation} is not supported; its first input is used.")
                r = a
            else:
                r = float(op(a, b, c))
            return min(max(r, 0.0), 1.0) if node.use_clamp else r
        if t in ('MIX_RGB', 'MIX'):
            return self.mix(node)
        if t in ('SEPRGB', 'SEPARATE_COLOR', 'SEPARATE_RGB'):
            c = to_color(self.socket(node.inputs[0]))
            idx = {'R': 0, 'G': 1, 'B': 2, 'Red': 0, 'Green': 1, 'Blue': 2}.get(out.name, 0)
            return float(c[idx])
        if t in ('COMBRGB', 'COMBINE_COLOR', 'COMBINE_RGB'):
            return tuple(to_float(self.socket(node.inputs[i])) for i in range(3))
        if t in ('FRESNEL', 'LAYER_WEIGHT'):
            return self.view_dependent(node, out)
        if t == 'TEX_IMAGE':
            if self.image_average is not None:
                avg = self.image_average(node)
                if avg is not None:
                    if not self.texture_is_sampled:
                        self.warn(f"image texture '{node.image.name}' reaches an input through nodes Tessera "
                                  f"does not sample per pixel; it is approximated by its average colour.")
                    return avg[3] if out.name == 'Alpha' else tuple(avg[:3])
            return (1.0, 0.0, 1.0) if out.name == 'Color' else 1.0  # Blender's missing-image pink
        self.warn(f"node '{node.name}' ({node.bl_idname}) is not supported; its output is taken as "
                  f"{'black' if out.type == 'RGBA' else '0'}.")
        return (0.0, 0.0, 0.0) if out.type == 'RGBA' else 0.0

    def view_dependent(self, node, out):
        """Fresnel and Layer Weight depend on the angle to the viewer, which a
        constant cannot follow: their average over directions (cosine-
        weighted over the hemisphere), with a warning. Formulas of Cycles'
        svm_node_fresnel and svm_node_layer_weight."""
        if node.inputs['Normal'].is_linked:
            self.warn(f"the Normal input of '{node.name}' is ignored.")
        if node.type == 'FRESNEL':
            eta = max(to_float(self.socket(node.inputs['IOR'])), 1e-5)
            eta = 1.0 / eta if self.backfacing else eta
            value = hemisphere_average(lambda mu: fresnel_dielectric_cos(mu, eta))
        else:
            blend = min(max(to_float(self.socket(node.inputs['Blend'])), 0.0), 1.0 - 1e-5)
            if out.name == 'Fresnel':
                eta = max(1.0 - blend, 1e-5)
                eta = eta if self.backfacing else 1.0 / eta
                value = hemisphere_average(lambda mu: fresnel_dielectric_cos(mu, eta))
            else:  # Facing
                k = 1.0 if blend == 0.5 else (2.0 * blend if blend < 0.5 else 0.5 / (1.0 - blend))
                value = hemisphere_average(lambda mu: 1.0 - mu ** k)
        self.warn(f"'{node.name}' ({node.bl_idname}) varies with the viewing angle, which Tessera does not evaluate "
                  f"per pixel; its average over directions ({value:.3f}) is used.")
        return value

    def mix(self, node):
        # Legacy MixRGB (3.3 and before) and the Mix node (3.4 on), colour mode.
        if node.type == 'MIX':
            if node.data_type == 'FLOAT':
                f = to_float(self.socket(node.inputs[0]))
                a, b = to_float(self.socket(node.inputs[2])), to_float(self.socket(node.inputs[3]))
                return a + (b - a) * f
            f = to_float(self.socket(node.inputs[0]))
            a, b = to_color(self.socket(node.inputs[6])), to_color(self.socket(node.inputs[7]))
        else:
            f = to_float(self.socket(node.inputs[0]))
            a, b = to_color(self.socket(node.inputs[1])), to_color(self.socket(node.inputs[2]))
        f = min(max(f, 0.0), 1.0)
        mode = node.blend_type
        if mode == 'MULTIPLY':
            r = tuple(x * (1 - f + f * y) for x, y in zip(a, b))
        elif mode == 'ADD':
            r = tuple(x + f * y for x, y in zip(a, b))
        elif mode == 'SUBTRACT':
            r = tuple(x - f * y for x, y in zip(a, b))
        else:
            if mode != 'MIX':
                self.warn(f"Mix blend mode {mode} is not supported; it is mixed linearly.")
            r = tuple(x + (y - x) * f for x, y in zip(a, b))
        if getattr(node, 'use_clamp', False) or getattr(node, 'clamp_result', False):
            r = tuple(min(max(x, 0.0), 1.0) for x in r)
        return r
