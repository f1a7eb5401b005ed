"""Materials: the node graph behind each material's Surface output, flattened
into the core's closure list (Principled, Diffuse, Glossy, Glass and
Transparent BSDFs weighted by Mix and Add Shader nodes, Principled Alpha, and
emission per face side), with value nodes folded into constants and image
textures sampled per texel where they drive an input directly. Reads both the
Blender 3.x and 4.x names of the Principled inputs."""

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


class ImageAverages:
    """Mean linear RGBA of image texture nodes' images, or None, for one
    export: each image is read once per render. Not kept across renders: an
    image painted or reloaded since would keep its old average, and Blender
    gives a new image the address of one freed before, so a cache keyed by
    it handed one image's average to another."""

    def __init__(self):
        self._by_image = {}

    def __call__(self, node):
        img = node.image
        if img is None:
            return None
        key = img.as_pointer()
        if key not in self._by_image:
            try:
                px = image_pixels(img)
            except RuntimeError:
                px = None
            self.remember(img, None if px is None else px.reshape(-1, 4).mean(axis=0))
        return self._by_image[key]

    def remember(self, img, rgba):
        self._by_image[img.as_pointer()] = None if rgba is None else tuple(float(x) for x in rgba)


def image_read_back(img):
    """Blender's float RGBA (H, W, 4) of an image, rows bottom to top, or None;
    for an 8-bit image each channel is k / 255, still in the image's colour space."""
    w, h = img.size
    if w == 0 or h == 0:
        return None
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def byte_encoding(img):
    """How the core stores an 8-bit image's bytes ('sRGB' or 'linear'), or ''
    for a float image (kept as linear floats)."""
    if img.is_float:
        return ''
    return 'sRGB' if img.colorspace_settings.name == 'sRGB' else 'linear'


def image_pixels(img):
    """Linear RGBA float32 (H, W, 4) of a Blender image, rows bottom to top, or None."""
    px = image_read_back(img)
    if px is None:
        return None
    if byte_encoding(img) == 'sRGB':
        # 8-bit texels read back as k / 255 exactly: a 256-entry table
        # converts them (the power function over every texel took 0.5 s of
        # modern_hall's 0.66 s export).
        px[..., :3] = _SRGB_TO_LINEAR_8BIT[np.rint(px[..., :3] * 255.0).astype(np.uint8)]
    return px


_SRGB_TO_LINEAR_8BIT = srgb_to_linear(np.arange(256, dtype=np.float64) / 255.0).astype(np.float32)


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
    def __init__(self, scene_core, report, diffuse_texture_blur=0.0):
        self.scene = scene_core
        self.report = report
        self.diffuse_texture_blur = diffuse_texture_blur
        self.ids = {}
        self.textured = set()
        self.textures = {}
        self.averages = ImageAverages()

    def get(self, material):
        """Core material index of a Blender material (0, the default grey, for None)."""
        if material is None:
            return 0
        key = material.as_pointer()
        if key not in self.ids:
            params = material_params(material, self.report, self.texture, self.averages)
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
                px = image_read_back(img)
            except RuntimeError:
                px = None
            if px is None:
                self.report.warn(img.name, f"Image '{img.name}' could not be loaded (missing file?); materials "
                                           f"using it show Blender's missing-texture pink. Relink or pack the image.")
                self.textures[key] = None
            else:
                # 8-bit images go to the core as bytes, converted there per texel
                # (in Python the conversion took most of modern_hall's export).
                index = self.scene.add_texture(px, node.interpolation, node.extension, byte_encoding(img),
                                               self.diffuse_texture_blur)
                self.textures[key] = index
                # The material's constant needs the average next: from the core's texels.
                self.averages.remember(img, self.scene.texture_average(index))
        return self.textures[key]


def material_params(material, report, texture=None, image_average=None):
    image_average = image_average or ImageAverages()
    front = _side_params(material, report, False, texture, image_average)
    back = _side_params(material, report, True, texture, image_average)
    if _surface_key(front) != _surface_key(back):
        report.warn(material.name, f"Material '{material.name}': its surface shaders differ between front and back "
                                   f"faces (Geometry > Backfacing reaching a shader mix); Tessera shades both sides "
                                   f"with the front side's and keeps only the emission per side.")
    front["emission_back"] = back["emission_front"]
    front["emission_strength_back"] = back.get("emission_strength_front", 0.0)
    return front


def _surface_key(params):
    keys = ("kind", "weight", "base_color", "metallic", "roughness", "specular", "ior", "transmission", "alpha",
            "multiscatter", "specular_tint", "coat", "coat_roughness", "coat_ior", "coat_tint", "diffuse_roughness")
    return (tuple(params.get(k) for k in keys), tuple(tuple(sorted(c.items())) for c in params.get("closures", [])))


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


def shading_model(version=None):
    """Whose closures the core follows, from the running Blender's version:
    Cycles changed them in 4.0 (Principled v2, height-correlated masking,
    Fresnel at the microfacet, energy-compensated Multiscatter GGX) and 4.3
    (energy-preserving Oren-Nayar)."""
    version = tuple(bpy.app.version) if version is None else tuple(version)
    if version < (4, 0, 0):
        return "CYCLES_3"
    return "CYCLES_4" if version < (4, 3, 0) else "CYCLES_4_3"


MODEL = shading_model()

# Closure parameters in the core's order (add_material's keywords), with the
# Principled defaults; the other kinds read base_color as their Color.
_CLOSURE_DEFAULTS = dict(base_color=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5, specular=0.5, ior=1.45,
                         transmission=0.0, model=MODEL, multiscatter=False, specular_tint=(1.0, 1.0, 1.0),
                         coat=0.0, coat_roughness=0.03, coat_ior=1.5, coat_tint=(1.0, 1.0, 1.0),
                         diffuse_roughness=0.0)
MAX_CLOSURES = 8  # core/material.h kMaxClosures

# Shader nodes Tessera does not model, rendered as the closest one it does.
_APPROXIMATED = {
    'BSDF_ANISOTROPIC': ("GLOSSY", "an isotropic Glossy BSDF"),
    'BSDF_REFRACTION': ("GLASS", "a Glass BSDF (with its reflection)"),
}


def _linked_node(socket):
    """The node feeding a socket through reroutes and valid, unmuted links, or None."""
    while socket.is_linked:
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return None
        node = link.from_node
        if node.type != 'REROUTE':
            return node
        socket = node.inputs[0]
    return None


# Value nodes whose output is the same everywhere on the surface (for a
# constant input); anything else (textures, Fresnel, Layer Weight, ...)
# varies, and Tessera takes one value for it.
_CONSTANT_NODES = {'VALUE', 'RGB', 'MATH', 'MIX', 'MIX_RGB', 'SEPRGB', 'SEPARATE_COLOR', 'SEPARATE_RGB', 'COMBRGB',
                   'COMBINE_COLOR', 'COMBINE_RGB', 'REROUTE', 'CLAMP', 'MAP_RANGE', 'INVERT', 'GAMMA',
                   'BRIGHTCONTRAST', 'HUE_SAT'}


def _varying_source(socket, depth=0):
    """The first node upstream of a socket whose output varies over the
    surface, or None when the socket's value is one constant per face side."""
    node = _linked_node(socket)
    if node is None or depth > 64:
        return None
    if node.type == 'NEW_GEOMETRY':
        out = socket.links[0].from_socket.name if socket.is_linked else ''
        return None if out == 'Backfacing' else node
    if node.type not in _CONSTANT_NODES:
        return node
    for inp in node.inputs:
        found = _varying_source(inp, depth + 1)
        if found is not None:
            return found
    return None


class _Flattener:
    """Flattens the shader tree behind the Surface output into Cycles' closure
    list: Mix Shader weights its two inputs by 1 - Fac and Fac, Add Shader
    sums them, Principled Alpha mixes in a white Transparent BSDF. Emission
    closures become the side's emission. One closure (the first that an image
    texture drives, else the first) gets the core's per-texel textures."""

    def __init__(self, ev, params, texture):
        self.ev = ev
        self.params = params
        self.texture = texture
        self.closures = []
        self.emission = [0.0, 0.0, 0.0]
        self.emission_tex_strength = None
        self.textured = None  # index of the closure the textures belong to

    def socket(self, socket, weight, depth=0):
        node = _linked_node(socket)
        if node is None or weight <= 0.0:
            return  # an unconnected shader input adds nothing (as in Cycles)
        if depth > 64:
            self.ev.warn("its shader tree is nested too deeply; the rest is ignored.")
            return
        self.node(node, weight, depth)

    def node(self, node, weight, depth=0):
        t = node.type
        ev = self.ev
        if t == 'MIX_SHADER':
            fac = min(max(to_float(ev.socket(node.inputs[0])), 0.0), 1.0)
            varying = _varying_source(node.inputs[0])
            if varying is not None:
                ev.warn(f"the factor of Mix Shader '{node.name}' varies over the surface ('{varying.name}', "
                        f"{varying.bl_idname}), which Tessera does not evaluate per pixel; the shaders are mixed "
                        f"with the constant {fac:.3f} instead (an image's average, or the value of the nodes).")
            self.socket(node.inputs[1], weight * (1.0 - fac), depth + 1)
            self.socket(node.inputs[2], weight * fac, depth + 1)
        elif t == 'ADD_SHADER':
            self.socket(node.inputs[0], weight, depth + 1)
            self.socket(node.inputs[1], weight, depth + 1)
        elif t == 'BSDF_PRINCIPLED':
            self.principled(node, weight)
        elif t == 'BSDF_DIFFUSE':
            self.add(node, "DIFFUSE", weight, color='Color', roughness='Roughness')
        elif t in ('BSDF_GLOSSY', 'BSDF_ANISOTROPIC'):
            multiscatter = self.distribution(node)
            if t == 'BSDF_ANISOTROPIC':
                self.approximated(node)
            elif to_float(ev.input(node, 'Anisotropy', 0.0)) != 0.0:
                ev.warn(f"the Anisotropy of '{node.name}' is not modelled; it is rendered isotropic.")
            self.add(node, "GLOSSY", weight, color='Color', roughness='Roughness', multiscatter=multiscatter)
        elif t in ('BSDF_GLASS', 'BSDF_REFRACTION'):
            multiscatter = self.distribution(node)
            if t == 'BSDF_REFRACTION':
                self.approximated(node)
            self.add(node, "GLASS", weight, color='Color', roughness='Roughness', ior='IOR',
                     multiscatter=multiscatter and t == 'BSDF_GLASS')
        elif t == 'BSDF_TRANSPARENT':
            self.add(node, "TRANSPARENT", weight, color='Color')
        elif t == 'EMISSION':
            strength = to_float(ev.input(node, 'Strength', 1.0))
            color = to_color(ev.input(node, 'Color', (1.0, 1.0, 1.0)))
            for i in range(3):
                self.emission[i] += weight * strength * color[i]
        elif t == 'HOLDOUT':
            ev.warn(f"Holdout '{node.name}' is not supported; it adds nothing to the surface.")
        else:
            color = ev.input(node, 'Color', (0.8, 0.8, 0.8)) if 'Color' in node.inputs else (0.8, 0.8, 0.8)
            ev.warn(f"shader '{node.name}' ({node.bl_idname}) is not supported yet; it is rendered as a "
                    f"diffuse surface of its colour.")
            self.closures.append(dict(_CLOSURE_DEFAULTS, kind="DIFFUSE", weight=weight, base_color=to_color(color),
                                      roughness=0.0))

    def approximated(self, node):
        _, what = _APPROXIMATED[node.type]
        self.ev.warn(f"'{node.name}' ({node.bl_idname}) is not supported; it is rendered as {what}.")

    def distribution(self, node):
        """Whether the node's microfacet distribution is Multiscatter GGX, which
        Tessera models as Cycles 4.x does (energy compensation); on 3.x, and
        for the distributions it does not model, a warning."""
        d = getattr(node, 'distribution', 'GGX')
        if d == 'MULTI_GGX' and MODEL != "CYCLES_3":
            return True
        if d not in ('GGX', 'SHARP'):
            what = ("Cycles 3.x's random-walk Multiscatter GGX is not modelled" if d == 'MULTI_GGX'
                    else f"the {d} microfacet distribution is not modelled")
            self.ev.warn(f"'{node.name}': {what}; Tessera renders single-scattering GGX instead (rough "
                         f"surfaces come out darker). Choose GGX to compare like with like.")
        return False

    def _claim_textures(self, node):
        """Whether this node's inputs may use the core's per-texel textures
        (only one closure can): the first node with a directly connected
        image texture."""
        if self.texture is None or self.textured is not None:
            return False
        return any(image_texture_node(s) is not None for s in node.inputs if s.is_linked)

    def add(self, node, kind, weight, color=None, roughness=None, ior=None, multiscatter=False):
        ev = self.ev
        claim = self._claim_textures(node)
        tex = self.texture if claim else None
        c = dict(_CLOSURE_DEFAULTS, kind=kind, weight=weight, multiscatter=multiscatter)
        if color:
            c["base_color"] = to_color(_textured(ev, node, color, self.params, "base_color", tex))
        if roughness:
            c["roughness"] = 0.0 if getattr(node, 'distribution', '') == 'SHARP' else \
                to_float(_textured(ev, node, roughness, self.params, "roughness", tex))
        if ior:
            c["ior"] = to_float(ev.input(node, ior, 1.45))
        if claim and self.params.get("textures"):
            self.textured = len(self.closures)
        self.closures.append(c)

    def principled(self, node, weight):
        ev = self.ev
        claim = self._claim_textures(node) or (self.texture is not None and self.textured is None
                                               and _linked_node(node.inputs['Normal']) is not None)
        tex = self.texture if claim else None
        params = self.params
        c = dict(_CLOSURE_DEFAULTS, kind="PRINCIPLED", weight=weight)
        c["base_color"] = to_color(_textured(ev, node, 'Base Color', params, "base_color", tex))
        c["metallic"] = to_float(_textured(ev, node, 'Metallic', params, "metallic", tex))
        c["roughness"] = to_float(_textured(ev, node, 'Roughness', params, "roughness", tex))
        c["specular"] = to_float(ev.input(node, _find(node, "specular")))
        c["ior"] = to_float(ev.input(node, 'IOR', 1.45))
        c["transmission"] = to_float(ev.input(node, _find(node, "transmission")))
        if MODEL == "CYCLES_3":
            if getattr(node, 'distribution', 'GGX') == 'MULTI_GGX':
                self.distribution(node)
        else:
            self.principled_v2(node, c)
        # Alpha (Cycles: Mix Shader of a white Transparent BSDF by 1 - alpha):
        # per texel when an image drives it directly, else folded into weights.
        alpha_tex = image_texture_node(node.inputs['Alpha']) if (tex is not None and 'Alpha' in node.inputs) else None
        alpha = to_float(_textured(ev, node, 'Alpha', params, "alpha", tex)) if 'Alpha' in node.inputs else 1.0
        alpha = min(max(alpha, 0.0), 1.0)
        emission = to_color(_textured(ev, node, _find(node, "emission"), params, "emission", tex))
        strength = to_float(ev.input(node, 'Emission Strength', 1.0))
        # Emission is mixed like the closures it comes with, alpha included.
        for i in range(3):
            self.emission[i] += weight * alpha * strength * emission[i]
        if tex is not None and "emission" in params.get("textures", {}):
            self.emission_tex_strength = weight * alpha * strength
        if tex is not None:
            _normal_map(ev, node, params, tex)
        elif _linked_node(node.inputs['Normal']) is not None:
            ev.warn(f"the Normal input of '{node.name}' is ignored: only one shader of a mix (the first with "
                    f"image textures) gets per-pixel textures and normal maps.")
        if alpha_tex is not None and "alpha" in params.get("textures", {}):
            c["alpha"] = alpha  # the image's average; the core reads the texel
        elif alpha < 1.0:
            self.closures.append(dict(_CLOSURE_DEFAULTS, kind="TRANSPARENT", weight=weight * (1.0 - alpha),
                                      base_color=(1.0, 1.0, 1.0)))
            c["weight"] = weight * alpha
        if tex is not None and params.get("textures"):
            self.textured = len(self.closures)
        self.closures.append(c)

    def principled_v2(self, node, c):
        """The Principled v2 inputs (Blender 4.x) the core models: distribution,
        specular tint, coat, diffuse roughness; the ones it does not, when they
        are in use, named in a warning."""
        ev = self.ev
        c["multiscatter"] = getattr(node, 'distribution', 'MULTI_GGX') == 'MULTI_GGX'
        c["specular_tint"] = to_color(ev.input(node, 'Specular Tint', (1.0, 1.0, 1.0)))
        c["coat"] = to_float(ev.input(node, 'Coat Weight', 0.0))
        if c["coat"] > 0.0:
            c["coat_roughness"] = to_float(ev.input(node, 'Coat Roughness', 0.03))
            c["coat_ior"] = to_float(ev.input(node, 'Coat IOR', 1.5))
            c["coat_tint"] = to_color(ev.input(node, 'Coat Tint', (1.0, 1.0, 1.0)))
            if 'Coat Normal' in node.inputs and _linked_node(node.inputs['Coat Normal']) is not None:
                ev.warn(f"the Coat Normal of '{node.name}' is ignored; the coat uses the surface normal.")
        c["diffuse_roughness"] = to_float(ev.input(node, 'Diffuse Roughness', 0.0))
        unsupported = [(name, what) for name, what in (
            ('Subsurface Weight', "subsurface scattering (rendered as diffuse)"),
            ('Sheen Weight', "sheen (left out)"),
            ('Anisotropic', "anisotropy (rendered isotropic)"),
            ('Thin Film Thickness', "thin-film iridescence (left out)"))
            if name in node.inputs and to_float(ev.input(node, name, 0.0)) > 0.0]
        if unsupported:
            ev.warn(f"'{node.name}' uses " + ", ".join(w for _, w in unsupported) + ", which Tessera does not "
                    f"model yet.")
        if c["coat"] > 0.0 and to_float(ev.input(node, 'Emission Strength', 0.0)) > 0.0:
            ev.warn(f"'{node.name}' has emission under a coat: Cycles dims it by the coat's reflectance (a few "
                    f"percent), Tessera does not.")

    def result(self):
        """Closure 0 (the textured one first) and the rest, at most MAX_CLOSURES."""
        closures = [c for c in self.closures if c["weight"] > 0.0]
        textured = self.closures[self.textured] if self.textured is not None else None
        if textured is not None:
            closures = [textured] + [c for c in closures if c is not textured]
        if len(closures) > MAX_CLOSURES:
            keep = closures[:1] + sorted(closures[1:], key=lambda c: -c["weight"])[:MAX_CLOSURES - 1]
            dropped = len(closures) - len(keep)
            self.ev.warn(f"it mixes {len(closures)} shaders; Tessera keeps {MAX_CLOSURES} and drops the "
                         f"{dropped} of smallest weight.")
            closures = keep
        return closures


def _side_params(material, report, backfacing, texture, image_average):
    params = dict(base_color=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5, specular=0.5, ior=1.45,
                  transmission=0.0, emission_front=(0.0, 0.0, 0.0), model=MODEL)
    # Blender 5.0 always uses a material's nodes (use_nodes is deprecated there, to go in 6.0).
    if material.node_tree is None or (bpy.app.version < (5, 0, 0) and not material.use_nodes):
        params["base_color"] = tuple(material.diffuse_color)[:3]
        params["metallic"] = material.metallic
        params["roughness"] = material.roughness
        return params
    out = output_node(material.node_tree, 'OUTPUT_MATERIAL')
    if out is None or not out.inputs['Surface'].is_linked:
        params["base_color"] = (0.0, 0.0, 0.0)  # Cycles renders a material without surface as black
        return params
    ev = Evaluator(material.name, report, backfacing, image_average)
    flat = _Flattener(ev, params, texture)
    flat.socket(out.inputs['Surface'], 1.0)
    closures = flat.result()
    params["emission_front"] = tuple(flat.emission)
    if flat.emission_tex_strength is not None:
        params["emission_strength_front"] = flat.emission_tex_strength
    if closures:
        first = closures[0]
        params["kind"] = first["kind"]
        params["weight"] = float(first["weight"])
        for key in _CLOSURE_DEFAULTS:
            params[key] = first.get(key, _CLOSURE_DEFAULTS[key])
        if "alpha" in first:
            params["alpha"] = float(first["alpha"])
        params["closures"] = [{k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v)
                               for k, v in c.items() if k != "alpha"} for c in closures[1:]]
    else:  # only emission, or nothing: no scattering
        params.update(weight=0.0, base_color=(0.0, 0.0, 0.0), specular=0.0)
    if "textures" in params and backfacing:
        params.pop("textures")  # one set of texture references, from the front side
    params["base_color"] = tuple(float(min(max(c, 0.0), 1.0)) for c in params["base_color"][:3])
    params["emission_front"] = tuple(float(max(c, 0.0)) for c in params["emission_front"][:3])
    for c in params.get("closures", []):
        c["base_color"] = tuple(float(min(max(x, 0.0), 1.0)) for x in c["base_color"][:3])
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
