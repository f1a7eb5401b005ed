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
            px = image_pixels(img)
        except RuntimeError:
            px = None
        _image_cache[key] = None if px is None else tuple(float(x) for x in px.reshape(-1, 4).mean(axis=0))
    return _image_cache[key]


def image_pixels(img):
    """Linear RGBA float32 (H, W, 4) of a Blender image, rows bottom to top, or None."""
    w, h = img.size
    if w == 0 or h == 0:
        return None
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    px = px.reshape(h, w, 4)
    if not img.is_float and img.colorspace_settings.name == 'sRGB':
        px[..., :3] = srgb_to_linear(px[..., :3])
    return px


def image_texture_node(socket):
    """(Image Texture node, output name) when the socket reads an image texture
    directly (through reroutes) with the default UV mapping, else None."""
    if not socket.is_linked:
        return None
    link = socket.links[0]
    node = link.from_node
    while node.type == 'REROUTE' and node.inputs[0].is_linked:
        link = node.inputs[0].links[0]
        node = link.from_node
    if node.type != 'TEX_IMAGE' or node.image is None:
        return None
    vec = node.inputs['Vector']
    if vec.is_linked:
        src = vec.links[0].from_node
        if not (src.type == 'UVMAP' or (src.type == 'TEX_COORD' and vec.links[0].from_socket.name == 'UV')):
            return None
    if node.projection != 'FLAT':
        return None
    return node, link.from_socket.name


class MaterialCache:
    def __init__(self, scene_core, report):
        self.scene = scene_core
        self.report = report
        self.ids = {}
        self.textured = set()
        self.textures = {}

    def get(self, material):
        """Core material index of a Blender material (0, the default grey, for None)."""
        if material is None:
            return 0
        key = material.as_pointer()
        if key not in self.ids:
            params = material_params(material, self.report, self.texture)
            if params.get("textures"):
                self.textured.add(key)
            self.ids[key] = self.scene.add_material(**params)
        return self.ids[key]

    def needs_uvs(self, material):
        """True when the material samples an image with the mesh's UV map
        (UVs are exported only for such meshes)."""
        return material is not None and material.as_pointer() in self.textured

    def texture(self, node):
        """Core texture index for an Image Texture node's image and sampling, or None."""
        img = node.image
        key = (img.as_pointer(), node.interpolation, node.extension)
        if key not in self.textures:
            try:
                px = image_pixels(img)
            except RuntimeError:
                px = None
            if px is None:
                self.report.warn(img.name, f"Image '{img.name}' could not be loaded (missing file?); materials "
                                           f"using it show Blender's missing-texture pink. Relink or pack the image.")
                self.textures[key] = None
            else:
                self.textures[key] = self.scene.add_texture(px, node.interpolation, node.extension)
        return self.textures[key]


def material_params(material, report, texture=None):
    front = _side_params(material, report, backfacing=False, texture=texture)
    back = _side_params(material, report, backfacing=True, texture=texture)
    front["emission_back"] = back["emission_front"]
    front["emission_strength_back"] = back.get("emission_strength_front", 0.0)
    return front


def _textured(ev, shader, name, params, key, texture):
    """Reads a Principled input; when an image texture drives it directly,
    records the texture reference too (the constant is the image average,
    used where one value is needed, e.g. light sampling power)."""
    socket = shader.inputs.get(name) if name else None
    if socket is None:
        return None
    if texture is not None:
        found = image_texture_node(socket)
        if found is not None:
            node, out = found
            tex = texture(node)
            if tex is not None:
                params.setdefault("textures", {})[key] = (tex, 1 if out == 'Alpha' else 0)
                ev.texture_is_sampled = True
                try:
                    return ev.socket(socket)  # the image average: the value where one value is needed
                finally:
                    ev.texture_is_sampled = False
    return ev.socket(socket)


def _side_params(material, report, backfacing, texture=None):
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
        tex = texture
        params["base_color"] = to_color(_textured(ev, shader, 'Base Color', params, "base_color", tex))
        params["metallic"] = to_float(_textured(ev, shader, 'Metallic', params, "metallic", tex))
        params["roughness"] = to_float(_textured(ev, shader, 'Roughness', params, "roughness", tex))
        params["specular"] = to_float(ev.input(shader, _find(shader, "specular")))
        params["ior"] = to_float(ev.input(shader, 'IOR', 1.45))
        params["transmission"] = to_float(ev.input(shader, _find(shader, "transmission")))
        emission = to_color(_textured(ev, shader, _find(shader, "emission"), params, "emission", tex))
        strength = to_float(ev.input(shader, 'Emission Strength', 1.0))
        params["emission_front"] = tuple(c * strength for c in emission)
        params["emission_strength_front"] = strength
        _normal_map(ev, shader, params, tex)
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
    if "textures" in params and backfacing:
        params.pop("textures")  # one set of texture references, from the front side
    params["base_color"] = tuple(float(min(max(c, 0.0), 1.0)) for c in params["base_color"][:3])
    params["emission_front"] = tuple(float(max(c, 0.0)) for c in params["emission_front"][:3])
    return params


def _normal_map(ev, shader, params, texture):
    """Principled Normal <- Normal Map (tangent space) <- Image Texture."""
    socket = shader.inputs.get('Normal')
    if socket is None or not socket.is_linked:
        return
    node = socket.links[0].from_node
    if node.type != 'NORMAL_MAP':
        ev.warn(f"the Normal input is driven by '{node.name}' ({node.bl_idname}), which is not supported; "
                f"the mesh normals are used.")
        return
    if node.space != 'TANGENT':
        ev.warn(f"Normal Map '{node.name}' in {node.space} space is not supported; only tangent space is.")
        return
    found = image_texture_node(node.inputs['Color']) if texture is not None else None
    if found is None:
        ev.warn(f"Normal Map '{node.name}' is not fed by an image texture; the mesh normals are used.")
        return
    tex = texture(found[0])
    if tex is not None:
        params.setdefault("textures", {})["normal"] = (tex, 0)
        params["normal_strength"] = to_float(ev.input(node, 'Strength', 1.0))
