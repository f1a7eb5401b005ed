"""Materials: the node graph behind each material's Surface output, folded
into the Principled parameters the core evaluates (base colour, metallic,
roughness, specular, IOR, transmission, and emission per face side). Reads
both the Blender 3.x and 4.x names of the Principled inputs."""

import bpy
import numpy as np

from .nodes import Evaluator, srgb_to_linear, to_color, to_float

# Blender 4.0 renamed some Principled inputs; the first name found wins.
_NAMES = {
    "emission": ("Emission Color", "Emission"),
    "specular": ("Specular IOR Level", "Specular"),
    "transmission": ("Transmission Weight", "Transmission"),
}


def _find(node, key):
    for name in _NAMES[key]:
        if name in node.inputs:
            return name
    return None


def output_node(tree, kind):
    """The active output node of a material or world tree."""
    outputs = [n for n in tree.nodes if n.type == kind]
    for n in outputs:
        if n.is_active_output:
            return n
    return outputs[0] if outputs else None


_image_cache = {}


def image_average(node):
    """Mean linear RGBA of an image texture node's image, or None."""
    img = node.image
    if img is None:
        return None
    key = img.as_pointer()
    if key not in _image_cache:
        try:
            n = img.size[0] * img.size[1]
            if n == 0:
                _image_cache[key] = None
                return None
            px = np.empty(n * 4, dtype=np.float32)
            img.pixels.foreach_get(px)
            mean = px.reshape(-1, 4).mean(axis=0).astype(np.float64)
            if not img.is_float and img.colorspace_settings.name == 'sRGB':
                mean[:3] = srgb_to_linear(mean[:3])
            _image_cache[key] = tuple(float(x) for x in mean)
        except RuntimeError:
            _image_cache[key] = None
    return _image_cache[key]


class MaterialCache:
    def __init__(self, scene_core, report):
        self.scene = scene_core
        self.report = report
        self.ids = {}

    def get(self, material):
        """Core material index of a Blender material (0, the default grey, for None)."""
        if material is None:
            return 0
        key = material.as_pointer()
        if key not in self.ids:
            self.ids[key] = self.scene.add_material(**material_params(material, self.report))
        return self.ids[key]


def material_params(material, report):
    front = _side_params(material, report, backfacing=False)
    back = _side_params(material, report, backfacing=True)
    front["emission_back"] = back["emission_front"]
    return front


def _side_params(material, report, backfacing):
    params = dict(base_color=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5, specular=0.5, ior=1.45,
                  transmission=0.0, emission_front=(0.0, 0.0, 0.0))
    if not material.use_nodes or material.node_tree is None:
        params["base_color"] = tuple(material.diffuse_color)[:3]
        params["metallic"] = material.metallic
        params["roughness"] = material.roughness
        return params
    out = output_node(material.node_tree, 'OUTPUT_MATERIAL')
    if out is None or not out.inputs['Surface'].is_linked:
        params["base_color"] = (0.0, 0.0, 0.0)  # Cycles renders a material without surface as black
        return params
    ev = Evaluator(material.name, report, backfacing, image_average)
    link = out.inputs['Surface'].links[0]
    shader = link.from_node
    while shader.type == 'REROUTE' and shader.inputs[0].is_linked:
        shader = shader.inputs[0].links[0].from_node
    t = shader.type
    if t == 'BSDF_PRINCIPLED':
        params["base_color"] = to_color(ev.input(shader, 'Base Color'))
        params["metallic"] = to_float(ev.input(shader, 'Metallic'))
        params["roughness"] = to_float(ev.input(shader, 'Roughness'))
        params["specular"] = to_float(ev.input(shader, _find(shader, "specular")))
        params["ior"] = to_float(ev.input(shader, 'IOR', 1.45))
        params["transmission"] = to_float(ev.input(shader, _find(shader, "transmission")))
        emission = to_color(ev.input(shader, _find(shader, "emission")))
        strength = to_float(ev.input(shader, 'Emission Strength', 1.0))
        params["emission_front"] = tuple(c * strength for c in emission)
    elif t == 'BSDF_DIFFUSE':
        params["base_color"] = to_color(ev.input(shader, 'Color'))
        params["roughness"] = 1.0
        params["specular"] = 0.0
    elif t == 'EMISSION':
        strength = to_float(ev.input(shader, 'Strength', 1.0))
        params["base_color"] = (0.0, 0.0, 0.0)
        params["specular"] = 0.0
        params["emission_front"] = tuple(c * strength for c in to_color(ev.input(shader, 'Color')))
    else:
        color = ev.input(shader, 'Color', (0.8, 0.8, 0.8)) if 'Color' in shader.inputs else (0.8, 0.8, 0.8)
        params["base_color"] = to_color(color)
        ev.warn(f"shader '{shader.name}' ({shader.bl_idname}) is not supported yet; it is rendered as a "
                f"diffuse surface of its colour.")
    params["base_color"] = tuple(float(min(max(c, 0.0), 1.0)) for c in params["base_color"][:3])
    params["emission_front"] = tuple(float(max(c, 0.0)) for c in params["emission_front"][:3])
    return params
