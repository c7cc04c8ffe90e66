"""A material's shader nodes as the engine sees them: one diffuse albedo plus specular lobes.

Cycles (3.4) sums the closures a node tree makes, each weighted by the Mix Shader factors on its
way to the Material Output (Mix: (1 - Fac) x first + Fac x second, Fac clamped to [0, 1]; Add:
both at full weight). The flattening walks that tree with the same weights and turns each closure
into what the engine has (C API "Specular lobes"):
    Diffuse BSDF        diffuse albedo += w x Color
    Glossy, Anisotropic GLOSSY lobe w x Color (Sharp: roughness 0)
    Glass BSDF          GLASS lobe w x Color, IOR
    Refraction BSDF     REFRACTION lobe w x Color, IOR
    Transparent BSDF    TRANSPARENT lobe w x Color
    Emission            emission += w x Color x Strength
    Principled BSDF     Blender 4.0+ (its sockets have 'Specular IOR Level'): _principled_v2.
                        Blender 3.x (svm_node_closure_bsdf, Cycles 3.4) Alpha < 1 first: TRANSPARENT
                        w (1 - Alpha), then w *= Alpha; emission w x Emission x Strength;
                        m = Metallic, t = Transmission (clamped):
                        diffuse albedo += w (1 - m)(1 - t) Base Color, Burley's diffuse of the
                        node's Roughness (Flat.burley; with Lambert parts beside it, one
                        Burley of their weighted roughness);
                        specular layer (when Specular or Metallic > 0) = FRESNEL lobe of weight
                        w (1 - t (1 - m)), F0 = mix(Specular x 0.08 x mix(1, tint, Specular
                        Tint), Base Color, m) clamped to [0, 1] (tint = Base Color / its
                        luminance 0.3 r + 0.6 g + 0.1 b), IOR 2 / (1 - sqrt(0.08 Specular)) - 1
                        (the curve from F0 up to the weight at grazing angles);
                        glass (when t (1 - m) > 0) = GLASS lobe w t (1 - m) x Base Color, IOR;
                        clearcoat = FRESNEL lobe of weight w x 0.25 x Clearcoat, F0 0.04 x that,
                        IOR 1.5, roughness Clearcoat Roughness.
A FRESNEL lobe carries its F0 x weight as `color` and the weight it rises to at grazing as
`weight` (two layers with the same roughness and IOR merge exactly by summing both).

Inputs are read as constants: an unlinked socket's value, or a link from a node whose value is
known without shading (Value, RGB, Math, Mix RGB with constant inputs, Invert, Clamp; a Reroute,
a muted node, a node group's sockets are followed). An Image Texture into the Base Color / Color
of the diffuse part stays a texture for the engine (albedo = image x the weights); an Image
Texture elsewhere (Metallic, Roughness, a glass tint) counts as its mean, a Fresnel or Layer
Weight factor as its average over a cosine-weighted hemisphere, anything else as the socket's
own value (a Mix Shader's Fac: 0.5). Every such approximation, and what the engine does not have
(anisotropy, sheen, subsurface, clearcoat's GTR1 distribution, Beckmann and multiscatter
distributions of rough lobes, the tint of a Principled glass's reflection, unknown nodes), is
collected once per material in one report line.
"""
import math

CUTOFF = 1e-5          # Cycles' CLOSURE_WEIGHT_CUTOFF: closures lighter than this are skipped
FALLBACK_ALBEDO = (0.8, 0.8, 0.8)
MAX_LOBES = 8          # the engine's limit per material
MEAN_MAX_PIXELS = 4 * 1024 * 1024  # larger images on float sockets count as the socket's value
GRAY = (0.2126729, 0.7151522, 0.0721750)  # Cycles' colour -> float (scene linear Rec.709 luminance)

LOBE_KINDS = ("glossy", "fresnel", "glass", "refraction", "transparent", "specular")
LAYER_KINDS = ("fresnel", "specular")  # layers on top of the diffuse part: color = F0 x weight


# Closures baked as diffuse of their Color (Sheen BSDF is Velvet's successor from Blender 4.0).
DIFFUSE_LEAVES = {'ShaderNodeBsdfDiffuse', 'ShaderNodeSubsurfaceScattering', 'ShaderNodeBsdfVelvet',
                  'ShaderNodeBsdfSheen', 'ShaderNodeBsdfToon', 'ShaderNodeBsdfHair', 'ShaderNodeBsdfHairPrincipled'}


class Lobe:
    """One specular lobe: kind (LOBE_KINDS), color (linear RGB, the mix weights applied), Blender
    roughness, ior (None where the kind has none), abbe (0 = no dispersion) and, for FRESNEL,
    weight: the reflectance it rises to at grazing angles (color is F0 x weight); SPECULAR (Blender 4's
    Principled specular layer, which also dims the diffuse part below it) as FRESNEL."""
    __slots__ = ("kind", "color", "roughness", "ior", "abbe", "weight")

    def __init__(self, kind, color, roughness=0.0, ior=None, abbe=0.0, weight=None):
        self.kind = kind
        self.color = tuple(float(c) for c in color)
        self.roughness = float(roughness)
        self.ior = None if ior is None else float(ior)
        self.abbe = float(abbe)
        self.weight = None if weight is None else float(weight)

    def key(self):
        return (self.kind, round(self.roughness, 6), None if self.ior is None else round(self.ior, 6),
                round(self.abbe, 6))

    def __repr__(self):
        extra = "" if self.weight is None else ", weight=%.4g" % self.weight
        return "Lobe(%s, (%.4g, %.4g, %.4g), roughness=%.4g, ior=%s%s)" % (
            self.kind, *self.color, self.roughness, self.ior, extra)


class Flat:
    """The flattened material: what read_material fills into MaterialInfo."""

    def __init__(self):
        self.albedo = [0.0, 0.0, 0.0]    # constant diffuse albedo (w x colour summed)
        self.texture_factor = 0.0       # weight multiplying the albedo texture (when there is one)
        self.texture_socket = None      # the diffuse colour input fed by the texture (or a link)
        self.preview_socket = None      # a diffuse colour input linked to something else (preview only)
        self.linked_factor = 0.0        # its weight
        self.emission = [0.0, 0.0, 0.0]
        self.emission_texture_socket = None   # (color socket, path) of an Image Texture emission
        self.emission_texture_strength = 0.0
        self.emission_sockets = None    # (color, strength) of the emission when its weight is 1
        self.emission_leaves = 0
        self.lobes = []
        # Burley diffuse (Blender 3.x's Principled BSDF): its roughness, None for Lambert; the
        # weights of the Burley and of all diffuse parts (_finish sets burley from them).
        self.burley = None
        self.burley_weight = 0.0
        self.burley_roughness_sum = 0.0
        self.diffuse_weight = 0.0
        self.approximations = []        # what was approximated (joined into one report)
        self.notes = []                 # other reports (textures, unsupported nodes)

    def approx(self, text):
        if text not in self.approximations:
            self.approximations.append(text)

    def add_lobe(self, lobe):
        if max(lobe.color) <= 0.0 and not (lobe.weight or 0.0) > 0.0:
            return
        for other in self.lobes:
            if other.key() == lobe.key():
                other.color = tuple(a + b for a, b in zip(other.color, lobe.color))
                if other.weight is not None:
                    other.weight += lobe.weight
                return
        self.lobes.append(lobe)


# ---- following links -------------------------------------------------------------------------

def source(socket, path=()):
    """(output socket, path) feeding an input socket, following reroutes, muted nodes and node
    groups (path: the group nodes entered, outermost first); None when unlinked (see resolve)."""
    out, path, _ = resolve(socket, path)
    return None if out is None else (out, path)


def link_step(socket):
    """(node, output socket, input) one link up from input `socket`, past reroutes and muted nodes
    (a muted node passes its internal link's input on); (None, None, the last input reached) where
    nothing feeds it: unlinked, or a muted or invalid link."""
    for _ in range(256):
        if socket is None or not socket.is_linked:
            return None, None, socket
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None, None, socket
        node, out = link.from_node, link.from_socket
        if node.bl_idname == 'NodeReroute':
            socket = node.inputs[0]
            continue
        if node.mute:
            socket = next((l.from_socket for l in node.internal_links if l.to_socket == out), None)
            continue
        return node, out, socket
    return None, None, None


def resolve(socket, path=()):
    """(output socket or None, path, the input whose own value applies when unlinked): a group's
    input socket stands for the group node's, a muted link or node counts as no link."""
    for _ in range(256):
        node, out, socket = link_step(socket)
        if node is None:
            return None, path, socket
        if node.bl_idname == 'NodeGroupInput':
            if not path:
                return None, path, socket
            index = list(node.outputs).index(out)
            group = path[-1]
            socket, path = (group.inputs[index] if index < len(group.inputs) else None), path[:-1]
            continue
        if node.bl_idname == 'ShaderNodeGroup' and node.node_tree is not None:
            inner = _group_output(node.node_tree)
            index = list(node.outputs).index(out)
            if inner is None or index >= len(inner.inputs):
                return None, path, None
            socket, path = inner.inputs[index], path + (node,)
            continue
        return out, path, None
    return None, path, None


def _group_output(tree):
    outs = [n for n in tree.nodes if n.bl_idname == 'NodeGroupOutput']
    return next((n for n in outs if n.is_active_output), outs[0] if outs else None)


def _default(socket):
    """An input's own value as a float or an RGB tuple."""
    v = getattr(socket, "default_value", 0.0)
    try:
        return tuple(float(c) for c in v[:3])
    except TypeError:
        return float(v)


def _as_float(v):
    return v if isinstance(v, float) else sum(g * c for g, c in zip(GRAY, v))


def _as_rgb(v):
    return v if isinstance(v, tuple) else (v, v, v)


# ---- constant values ---------------------------------------------------------------------------

class Unknown(Exception):
    """A value that is not known without shading; the message says where it came from."""


_MATH = {
    'ADD': lambda a, b, c: a + b, 'SUBTRACT': lambda a, b, c: a - b, 'MULTIPLY': lambda a, b, c: a * b,
    'DIVIDE': lambda a, b, c: a / b if b != 0.0 else 0.0, 'MULTIPLY_ADD': lambda a, b, c: a * b + c,
    'POWER': lambda a, b, c: _safe_pow(a, b), 'MINIMUM': lambda a, b, c: min(a, b),
    'MAXIMUM': lambda a, b, c: max(a, b), 'ABSOLUTE': lambda a, b, c: abs(a),
    'SQRT': lambda a, b, c: math.sqrt(a) if a > 0.0 else 0.0,
    'INVERSE_SQRT': lambda a, b, c: 1.0 / math.sqrt(a) if a > 0.0 else 0.0,
    'LESS_THAN': lambda a, b, c: 1.0 if a < b else 0.0, 'GREATER_THAN': lambda a, b, c: 1.0 if a > b else 0.0,
    'SIGN': lambda a, b, c: math.copysign(1.0, a) if a != 0.0 else 0.0,
    'ROUND': lambda a, b, c: math.floor(a + 0.5), 'FLOOR': lambda a, b, c: math.floor(a),
    'CEIL': lambda a, b, c: math.ceil(a), 'FRACT': lambda a, b, c: a - math.floor(a),
    'SNAP': lambda a, b, c: math.floor(a / b) * b if b != 0.0 else 0.0,
    'EXPONENT': lambda a, b, c: math.exp(min(a, 80.0)),
}


def _safe_pow(a, b):
    if a >= 0.0:
        return a ** b if a > 0.0 or b > 0.0 else 0.0
    return a ** b if float(b).is_integer() else 0.0


class Reader:
    """Reads constant values of sockets for one material; images' means are cached."""

    def __init__(self, flat, image_means=None):
        self.flat = flat
        self.image_means = image_means if image_means is not None else {}

    def value(self, socket, path, what, fallback=None):
        """A float input's value; an unknown link gives `fallback` (None: the socket's own value)
        and an approximation note naming `what`."""
        out, opath, own = resolve(socket, path)
        if out is None:
            return _as_float(_default(own)) if own is not None else (0.0 if fallback is None else fallback)
        try:
            return _as_float(self._eval(out, opath, what))
        except Unknown as e:
            v = _as_float(_default(socket)) if fallback is None else fallback
            self.flat.approx("%s comes from %s: %.3g used" % (what, e, v))
            return v

    def color(self, socket, path, what, fallback=None):
        """An RGB input's value (see value)."""
        out, opath, own = resolve(socket, path)
        if out is None:
            return _as_rgb(_default(own)) if own is not None else (fallback or (0.0, 0.0, 0.0))
        try:
            return _as_rgb(self._eval(out, opath, what))
        except Unknown as e:
            v = _as_rgb(_default(socket)) if fallback is None else fallback
            self.flat.approx("%s comes from %s: (%.3g, %.3g, %.3g) used" % (what, e, *v))
            return v

    def _eval(self, out, path, what, depth=0):
        if depth > 64:
            raise Unknown("a chain of more than 64 nodes")
        node = out.node
        kind = node.bl_idname

        def arg(socket):
            src, spath, own = resolve(socket, path)
            if src is None:
                return _default(own) if own is not None else 0.0
            return self._eval(src, spath, what, depth + 1)

        if kind in ('ShaderNodeValue', 'ShaderNodeRGB'):
            return _default(out)
        if kind == 'ShaderNodeMath':
            a, b, c = (_as_float(arg(s)) for s in list(node.inputs)[:3])
            op = _MATH.get(node.operation)
            if op is None:
                raise Unknown("a Math node (%s)" % node.operation.title())
            v = op(a, b, c)
            return min(max(v, 0.0), 1.0) if node.use_clamp else v
        if kind == 'ShaderNodeMixRGB' and node.blend_type in ('MIX', 'MULTIPLY', 'ADD', 'SUBTRACT'):
            f = min(max(_as_float(arg(node.inputs['Fac'])), 0.0), 1.0)
            a, b = _as_rgb(arg(node.inputs['Color1'])), _as_rgb(arg(node.inputs['Color2']))
            op = {'MIX': lambda x, y: y, 'MULTIPLY': lambda x, y: x * y, 'ADD': lambda x, y: x + y,
                  'SUBTRACT': lambda x, y: x - y}[node.blend_type]
            v = tuple(x + f * (op(x, y) - x) for x, y in zip(a, b))
            return tuple(min(max(c, 0.0), 1.0) for c in v) if node.use_clamp else v
        if kind == 'ShaderNodeInvert':
            f = _as_float(arg(node.inputs['Fac']))
            v = _as_rgb(arg(node.inputs['Color']))
            return tuple(c + f * ((1.0 - c) - c) for c in v)
        if kind == 'ShaderNodeClamp':
            v, lo, hi = (_as_float(arg(node.inputs[n])) for n in ('Value', 'Min', 'Max'))
            if node.clamp_type == 'RANGE' and lo > hi:
                lo, hi = hi, lo
            return min(max(v, lo), hi)
        if kind == 'ShaderNodeTexImage':
            return self._image_mean(node, out.name, what)
        if kind == 'ShaderNodeFresnel':
            ior = _as_float(arg(node.inputs['IOR']))
            v = hemisphere_fresnel(ior)
            self.flat.approx("%s from a Fresnel node (IOR %.3g): its hemispherical average %.3g" % (what, ior, v))
            return v
        if kind == 'ShaderNodeLayerWeight':
            blend = _as_float(arg(node.inputs['Blend']))
            v = layer_weight_average(out.name, blend)
            self.flat.approx("%s from a Layer Weight node (%s, blend %.3g): its hemispherical average %.3g"
                             % (what, out.name, blend, v))
            return v
        raise Unknown("a %s node" % node.bl_label)

    def _image_mean(self, node, output, what):
        image = node.image
        if image is None:
            raise Unknown("an Image Texture without an image")
        mean = self.image_means.get(image.name_full)
        if mean is None:
            mean = image_mean(image)
            self.image_means[image.name_full] = mean
        if mean is None:
            raise Unknown("the image '%s' (too large to average here)" % image.name)
        rgb, alpha = mean
        v = alpha if output == 'Alpha' else rgb
        shown = v if isinstance(v, float) else _as_float(v)
        self.flat.approx("%s from the image '%s': its mean %.3g" % (what, image.name, shown))
        return v


def image_mean(image):
    """((r, g, b) linear, alpha) mean of an image's pixels, None when it has none or more than
    MEAN_MAX_PIXELS."""
    import numpy as np
    w, h = image.size
    if w * h == 0 or w * h > MEAN_MAX_PIXELS:
        return None
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(-1, image.channels).astype(np.float64)
    rgb = px[:, :3] if image.channels >= 3 else np.repeat(px[:, :1], 3, axis=1)
    if not image.is_float and image.colorspace_settings.name == 'sRGB':
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    alpha = float(px[:, 3].mean()) if image.channels == 4 else 1.0
    return tuple(float(c) for c in rgb.mean(axis=0)), alpha


def fresnel_dielectric_cos(cosi, eta):
    """Cycles' fresnel_dielectric_cos: unpolarised reflectance of a dielectric of relative ior eta."""
    c = abs(cosi)
    g = eta * eta - 1.0 + c * c
    if g <= 0.0:
        return 1.0
    g = math.sqrt(g)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


def hemisphere_fresnel(ior, n=512):
    """Cosine-weighted hemispherical average of fresnel_dielectric_cos (the front side)."""
    eta = max(ior, 1e-5)
    return sum(fresnel_dielectric_cos((i + 0.5) / n, eta) * 2.0 * (i + 0.5) / n for i in range(n)) / n


def layer_weight_average(output, blend, n=512):
    """Cosine-weighted hemispherical average of a Layer Weight node's output (Cycles'
    svm_node_layer_weight, front side)."""
    blend = min(max(blend, 0.0), 1.0 - 1e-5)
    if output == 'Fresnel':
        return hemisphere_fresnel(1.0 / max(1.0 - blend, 1e-5), n)
    b = 2.0 * blend if blend < 0.5 else 0.5 / (1.0 - blend)
    return 1.0 - 2.0 / (b + 2.0)  # 1 - mean of cos^b under 2 cos d(cos)


def f0_from_ior(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


# ---- the walk ----------------------------------------------------------------------------------

def flatten(surface_socket, image_means=None):
    """Flat for the closures reaching a Material Output's Surface input."""
    flat = Flat()
    reader = Reader(flat, image_means)
    src = source(surface_socket)
    if src is not None:
        _walk(reader, src, 1.0, 0)
    _finish(flat)
    return flat


def flatten_output(out_socket, image_means=None):
    """Flat for the closure leaving one node's output (a node group's, say)."""
    flat = Flat()
    node = out_socket.node
    src = (out_socket, ())
    if node.bl_idname == 'ShaderNodeGroup' and node.node_tree is not None:
        inner = _group_output(node.node_tree)
        index = list(node.outputs).index(out_socket)
        src = source(inner.inputs[index], (node,)) if inner is not None and index < len(inner.inputs) else None
    if src is not None:
        _walk(Reader(flat, image_means), src, 1.0, 0)
    _finish(flat)
    return flat


def _walk(reader, src, w, depth):
    out, path = src
    node = out.node
    flat = reader.flat
    if w <= CUTOFF or depth > 64:
        return
    kind = node.bl_idname
    if kind == 'ShaderNodeGroup':  # source() enters groups; only an empty or broken one gets here
        flat.approx("node group '%s' gives no shader: left out" % node.name)
        return
    if kind == 'ShaderNodeMixShader':
        f = min(max(reader.value(node.inputs[0], path, "Mix Shader '%s' factor" % node.name, 0.5), 0.0), 1.0)
        for socket, weight in ((node.inputs[1], w * (1.0 - f)), (node.inputs[2], w * f)):
            child = source(socket, path)
            if child is not None:
                _walk(reader, child, weight, depth + 1)
        return
    if kind == 'ShaderNodeAddShader':
        for socket in (node.inputs[0], node.inputs[1]):
            child = source(socket, path)
            if child is not None:
                _walk(reader, child, w, depth + 1)
        return
    if kind == 'ShaderNodeBsdfPrincipled':
        _principled(reader, node, path, w)
        return
    if kind == 'ShaderNodeBsdfDiffuse':
        _diffuse(reader, node.inputs['Color'], path, w, node)
        if reader.value(node.inputs['Roughness'], path, "Roughness") > 0.0:
            flat.approx("Diffuse BSDF '%s': Oren-Nayar roughness baked as Lambert" % node.name)
        return
    if kind == 'ShaderNodeEmission':
        _emission(reader, node.inputs['Color'], node.inputs['Strength'], path, w, node)
        return
    if kind in ('ShaderNodeBsdfGlossy', 'ShaderNodeBsdfAnisotropic'):
        col = _scaled(reader.color(node.inputs['Color'], path, "%s Color" % node.name), w)
        rough = _roughness(reader, node, path)
        if kind == 'ShaderNodeBsdfAnisotropic' and rough > 0.0 and abs(
                reader.value(node.inputs['Anisotropy'], path, "%s Anisotropy" % node.name)) > CUTOFF:
            flat.approx("Anisotropic BSDF '%s': isotropic roughness %.3g" % (node.name, rough))
        flat.add_lobe(Lobe("glossy", col, rough))
        return
    if kind in ('ShaderNodeBsdfGlass', 'ShaderNodeBsdfRefraction'):
        col = _scaled(reader.color(node.inputs['Color'], path, "%s Color" % node.name), w)
        rough = _roughness(reader, node, path)
        ior = max(reader.value(node.inputs['IOR'], path, "%s IOR" % node.name), 1e-5)
        flat.add_lobe(Lobe("glass" if kind == 'ShaderNodeBsdfGlass' else "refraction", col, rough, ior))
        return
    if kind == 'ShaderNodeBsdfTransparent':
        flat.add_lobe(Lobe("transparent", _scaled(reader.color(node.inputs['Color'], path,
                                                                "%s Color" % node.name), w)))
        return
    if kind == 'ShaderNodeBsdfTranslucent':
        col = _scaled(reader.color(node.inputs['Color'], path, "%s Color" % node.name), w)
        flat.add_lobe(Lobe("transparent", col))
        flat.approx("Translucent BSDF '%s': light passes straight through (not scattered)" % node.name)
        return
    if kind == 'ShaderNodeHoldout':
        flat.approx("Holdout '%s': absorbs light" % node.name)
        return
    if kind in DIFFUSE_LEAVES and 'Color' in node.inputs:
        _diffuse(reader, node.inputs['Color'], path, w, node)
        flat.approx("%s '%s': baked as a diffuse surface of its colour" % (node.bl_label, node.name))
        return
    flat.albedo = [a + w * c for a, c in zip(flat.albedo, FALLBACK_ALBEDO)]
    flat.approx("%s '%s' is not supported: baked as diffuse grey 0.8" % (node.bl_label, node.name))


def _scaled(rgb, w):
    return tuple(w * max(c, 0.0) for c in rgb)


def _roughness(reader, node, path):
    """A Glossy / Glass / Refraction node's roughness for a GGX lobe (Sharp: 0), noting
    distributions the engine approximates."""
    dist = getattr(node, "distribution", 'GGX')
    if dist == 'SHARP':
        return 0.0
    rough = min(max(reader.value(node.inputs['Roughness'], path, "%s Roughness" % node.name), 0.0), 1.0)
    if rough > 0.0 and dist != 'GGX':
        names = {'BECKMANN': "Beckmann", 'MULTI_GGX': "Multiscatter GGX", 'ASHIKHMIN_SHIRLEY': "Ashikhmin-Shirley"}
        reader.flat.approx("%s '%s': %s distribution traced as GGX of the same roughness"
                           % (node.bl_label, node.name, names.get(dist, dist)))
    return rough


def _diffuse(reader, color_socket, path, w, node):
    """Add w x colour to the diffuse albedo; an Image Texture stays a texture."""
    flat = reader.flat
    flat.diffuse_weight += w
    src = source(color_socket, path)
    if src is not None and src[0].node.bl_idname == 'ShaderNodeTexImage' and src[0].name == 'Color':
        if flat.texture_socket is None:
            flat.texture_socket = (color_socket, path)
            flat.texture_factor += w
            return
        if flat.texture_socket[0] == color_socket and flat.texture_socket[1] == path:
            flat.texture_factor += w
            return
        flat.approx("a second textured diffuse colour ('%s'): its image's mean" % node.name)
    elif src is not None:
        try:
            rgb = _as_rgb(reader._eval(*src, "%s colour" % node.name))
        except Unknown as e:
            if flat.preview_socket is None:  # the preview still multiplies by the linked colour
                flat.preview_socket = (color_socket, path)
                flat.linked_factor += w
            flat.notes.append(("linked", "%s comes from %s (not an Image Texture): baked as grey 0.8"
                               % ("Base Color" if node.bl_idname == 'ShaderNodeBsdfPrincipled' else
                                  "Color of '%s'" % node.name, e)))
            rgb = FALLBACK_ALBEDO
        flat.albedo = [a + w * max(c, 0.0) for a, c in zip(flat.albedo, rgb)]
        return
    rgb = reader.color(color_socket, path, "%s colour" % node.name)
    flat.albedo = [a + w * max(c, 0.0) for a, c in zip(flat.albedo, rgb)]


def _emission(reader, color, strength, path, w, node):
    flat = reader.flat
    flat.emission_leaves += 1
    if w == 1.0 and not path:
        flat.emission_sockets = (color, strength)
    src = source(color, path)
    s = reader.value(strength, path, "%s emission strength" % node.name)
    if s <= 0.0:
        return
    if src is not None and src[0].node.bl_idname == 'ShaderNodeTexImage' and src[0].name == 'Color':
        if flat.emission_texture_socket is None:
            flat.emission_texture_socket = (color, path)
            flat.emission_texture_strength += w * max(s, 0.0)
            return
        flat.approx("a second emission texture ('%s'): its image's mean" % node.name)
    elif src is not None:
        try:
            rgb = _as_rgb(reader._eval(*src, "%s emission colour" % node.name))
        except Unknown as e:
            flat.notes.append(("emission", "emission colour comes from %s: baked without this emission" % e))
            return
        flat.emission = [a + w * s * max(c, 0.0) for a, c in zip(flat.emission, rgb)]
        return
    rgb = reader.color(color, path, "%s emission colour" % node.name)
    flat.emission = [a + w * s * max(c, 0.0) for a, c in zip(flat.emission, rgb)]


def _base_constant(reader, node, path, name):
    """base_constant(why): a Principled BSDF's Base Color as one constant (a texture's mean), read on
    first use (why says what needs it, for the report) and kept."""
    cache = []

    def base_constant(why):
        if not cache:
            cache.append(reader.color(node.inputs['Base Color'], path, "%s Base Color (%s)" % (name, why),
                                      FALLBACK_ALBEDO))
        return cache[0]
    return base_constant


def _principled(reader, node, path, w):
    if 'Specular IOR Level' in node.inputs:
        _principled_v2(reader, node, path, w)
    else:
        _principled_v1(reader, node, path, w)


def _f0_from_ior(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def _ior_from_f0(f0):
    r = math.sqrt(min(max(f0, 0.0), 0.99))
    return (1.0 + r) / (1.0 - r)


def _principled_v2(reader, node, path, w):
    """Blender 4.0+'s Principled BSDF (Cycles 4 svm_node_closure_bsdf, docs/design/cycles-versions.md "Cycles
    versions"): Alpha < 1 first (TRANSPARENT w (1 - Alpha), w *= Alpha); emission w x Emission Color
    x Strength; m = Metallic, t = Transmission Weight:
        metal     FRESNEL lobe of weight w m, F0 Base Color (Cycles' F82-tint curve as a
                  dielectric's of IOR 1.5), its Specular Tint left out
        glass     GLASS lobe w (1 - m) t x sqrt(Base Color) (Cycles tints the refraction by
                  sqrt(Base Color) each way), IOR
        specular  SPECULAR lobe of weight ws = w (1 - m)(1 - t): F0 = F0(IOR) x 2 Specular IOR
                  Level x Specular Tint, its curve a dielectric's of the IOR that has that F0
        diffuse   albedo += ws x Base Color (the engine dims it by the SPECULAR layer's albedo)
        coat      FRESNEL lobe of weight w x Coat Weight, F0 from Coat IOR, Coat Roughness, on top
    Sheen, subsurface (baked as diffuse of the Base Color), Diffuse Roughness (Lambert), anisotropy
    and thin film are approximations the report names."""
    flat = reader.flat
    inp = node.inputs
    name = "Principled BSDF '%s'" % node.name

    def has(key):
        return key in inp

    def val(key, default=0.0):
        return reader.value(inp[key], path, "%s %s" % (name, key)) if has(key) else default

    alpha = min(max(val('Alpha', 1.0), 0.0), 1.0)
    if alpha < 1.0:
        flat.add_lobe(Lobe("transparent", (w * (1.0 - alpha),) * 3))
        w *= alpha
        if w <= CUTOFF:
            return
    coat = max(val('Coat Weight'), 0.0)
    sheen = max(val('Sheen Weight'), 0.0)
    _emission(reader, inp['Emission Color'], inp['Emission Strength'], path, w, node)
    if (coat > CUTOFF or sheen > CUTOFF) and val('Emission Strength') > 0.0:
        flat.approx("%s: emission not dimmed by its coat and sheen" % name)
    metallic = min(max(val('Metallic'), 0.0), 1.0)
    transmission = min(max(val('Transmission Weight'), 0.0), 1.0)
    rough = min(max(val('Roughness', 0.5), 0.0), 1.0)
    ior = max(val('IOR', 1.5), 1e-5)
    level = max(val('Specular IOR Level', 0.5), 0.0)
    tint = reader.color(inp['Specular Tint'], path, "%s Specular Tint" % name) if has('Specular Tint') \
        else (1.0, 1.0, 1.0)
    if not isinstance(tint, (tuple, list)):
        tint = (float(tint),) * 3
    metal_w = w * metallic
    glass_w = w * (1.0 - metallic) * transmission
    spec_w = w * (1.0 - metallic) * (1.0 - transmission)
    distribution = getattr(node, "distribution", 'MULTI_GGX')
    base_constant = _base_constant(reader, node, path, name)

    if abs(val('Anisotropic')) > CUTOFF and rough > 0.0:
        flat.approx("%s: anisotropy traced as isotropic roughness %.3g" % (name, rough))
    if val('Thin Film Thickness') > 0.1:
        flat.approx("%s: thin film left out" % name)
    if sheen > CUTOFF:
        flat.approx("%s: sheen left out" % name)

    if metal_w > CUTOFF:
        b = tuple(min(max(c, 0.0), 1.0) for c in base_constant("metal F0"))
        flat.add_lobe(Lobe("fresnel", tuple(metal_w * c for c in b), rough, 1.5, weight=metal_w))
        if rough > 0.075:
            flat.approx("%s: metal's multiscatter GGX traced as single-scattering GGX" % name)
        if max(abs(t - 1.0) for t in tint) > 1e-6:
            flat.approx("%s: Specular Tint of the metal (F82) left out" % name)
    if glass_w > CUTOFF:
        b = base_constant("glass tint")
        flat.add_lobe(Lobe("glass", tuple(glass_w * math.sqrt(max(c, 0.0)) for c in b), rough, ior))
        if max(b) - min(b) > 1e-6 or abs(b[0] - 1.0) > 1e-6:
            flat.approx("%s: its glass's reflection is tinted by the Base Color too (Cycles tints only "
                        "the refraction)" % name)
        if distribution == 'MULTI_GGX' and rough > 0.05:
            flat.approx("%s: Multiscatter GGX glass traced as GGX" % name)
        if has('Thin Wall') and getattr(inp['Thin Wall'], "default_value", False):
            flat.approx("%s: Thin Wall glass traced as a solid's surface" % name)
    if spec_w > CUTOFF:
        # Cycles 4: f0 = F0(ior), scaled by 2 x Specular IOR Level, and the curve of the ior with that f0.
        f0 = _f0_from_ior(ior)
        eta = ior
        if level != 0.5:
            f0 *= 2.0 * level
            eta = _ior_from_f0(f0)
            if ior < 1.0:
                eta = 1.0 / eta
        f0c = tuple(min(max(f0 * max(t, 0.0), 0.0), 1.0) for t in tint)
        if abs(eta - 1.0) > 1e-6 and max(f0c) > 0.0:
            flat.add_lobe(Lobe("specular", tuple(spec_w * c for c in f0c), rough, eta, weight=spec_w))
        if distribution == 'GGX' and rough > 0.075:
            flat.approx("%s: single-scattering GGX traced as Multiscatter GGX" % name)
        _diffuse(reader, inp['Base Color'], path, spec_w, node)
        if val('Subsurface Weight') > CUTOFF:
            flat.approx("%s: subsurface scattering baked as diffuse of the Base Color" % name)
        if val('Diffuse Roughness') > CUTOFF:
            flat.approx("%s: Oren-Nayar Diffuse Roughness baked as Lambert" % name)
    if coat > CUTOFF:
        cw = w * min(coat, 1.0)
        cr = min(max(val('Coat Roughness', 0.03), 0.0), 1.0)
        cior = max(val('Coat IOR', 1.5), 1.0)
        flat.add_lobe(Lobe("fresnel", (cw * _f0_from_ior(cior),) * 3, cr, cior, weight=cw))
        flat.approx("%s: coat added on top (the layers below it are not dimmed by it)" % name)


def _principled_v1(reader, node, path, w):
    flat = reader.flat
    inp = node.inputs
    name = "Principled BSDF '%s'" % node.name

    def val(key):
        return reader.value(inp[key], path, "%s %s" % (name, key))

    alpha = min(max(val('Alpha'), 0.0), 1.0)
    if alpha < 1.0:
        flat.add_lobe(Lobe("transparent", (w * (1.0 - alpha),) * 3))
        w *= alpha
        if w <= CUTOFF:
            return
    _emission(reader, inp['Emission'], inp['Emission Strength'], path, w, node)
    metallic = min(max(val('Metallic'), 0.0), 1.0)
    transmission = min(max(val('Transmission'), 0.0), 1.0)
    specular = val('Specular')
    spec_tint = val('Specular Tint')
    rough = val('Roughness')
    ior = max(val('IOR'), 1e-5)
    diffuse_w = (1.0 - metallic) * (1.0 - transmission)
    glass_w = transmission * (1.0 - metallic)
    spec_w = 1.0 - glass_w
    subsurface = min(max(val('Subsurface'), 0.0), 1.0)

    # The base colour: a texture for the diffuse part, its mean wherever a constant is needed.
    base_constant = _base_constant(reader, node, path, name)

    if diffuse_w > CUTOFF:
        # Cycles 3.4's Principled diffuse is Burley's, of the node's Roughness.
        flat.burley_weight += w * diffuse_w
        flat.burley_roughness_sum += w * diffuse_w * min(max(rough, 0.0), 1.0)
        if subsurface > CUTOFF:
            ss = reader.color(inp['Subsurface Color'], path, "%s Subsurface Color" % name)
            mixed = tuple((1.0 - subsurface) * b + subsurface * s for b, s in zip(base_constant("subsurface"), ss))
            flat.diffuse_weight += w * diffuse_w
            flat.albedo = [a + w * diffuse_w * max(c, 0.0) for a, c in zip(flat.albedo, mixed)]
            flat.approx("%s: subsurface scattering baked as diffuse of the mixed colour" % name)
        else:
            _diffuse(reader, inp['Base Color'], path, w * diffuse_w, node)
        if val('Sheen') > CUTOFF:
            flat.approx("%s: sheen left out" % name)
    if abs(val('Anisotropic')) > CUTOFF and rough > 0.0:
        flat.approx("%s: anisotropy traced as isotropic roughness %.3g" % (name, min(max(rough, 0.0), 1.0)))
    rough = min(max(rough, 0.0), 1.0)
    distribution = getattr(node, "distribution", 'GGX')

    if spec_w > CUTOFF and (specular > CUTOFF or metallic > CUTOFF):
        b = base_constant("specular colour") if (metallic > CUTOFF or spec_tint != 0.0) else (1.0, 1.0, 1.0)
        lum = 0.3 * b[0] + 0.6 * b[1] + 0.1 * b[2]
        ctint = tuple(c / lum for c in b) if lum > 0.0 else (1.0, 1.0, 1.0)
        tmp = tuple((1.0 - spec_tint) + t * spec_tint for t in ctint)
        f0 = tuple(min(max(specular * 0.08 * t * (1.0 - metallic) + c * metallic, 0.0), 1.0)
                   for t, c in zip(tmp, b))
        s = min(max(specular, 0.0), 1.0)
        spec_ior = 2.0 / (1.0 - math.sqrt(0.08 * s)) - 1.0
        if distribution == 'MULTI_GGX' and rough > 0.075:
            flat.approx("%s: Multiscatter GGX traced as GGX" % name)
        ww = w * spec_w
        flat.add_lobe(Lobe("fresnel", tuple(ww * c for c in f0), rough, spec_ior, weight=ww))
    if glass_w > CUTOFF:
        b = base_constant("glass tint")
        trough = rough
        if distribution == 'GGX':
            tr = min(max(val('Transmission Roughness'), 0.0), 1.0)
            trough = 1.0 - (1.0 - rough) * (1.0 - tr)
            if abs(trough - rough) > 1e-6:
                flat.approx("%s: one roughness %.3g (Transmission Roughness) for its glass's reflection "
                            "and refraction" % (name, trough))
        elif rough > 0.05:
            flat.approx("%s: Multiscatter GGX glass traced as GGX" % name)
        if max(b) - min(b) > 1e-6 or abs(b[0] - 1.0) > 1e-6:
            flat.approx("%s: its glass's reflection is tinted by the Base Color too (Cycles tints only "
                        "the refraction)" % name)
        if spec_tint != 0.0:
            flat.approx("%s: Specular Tint on glass left out" % name)
        flat.add_lobe(Lobe("glass", tuple(w * glass_w * max(c, 0.0) for c in b), trough, ior))
    clearcoat = val('Clearcoat')
    if clearcoat > CUTOFF:
        cw = w * 0.25 * clearcoat
        cr = min(max(val('Clearcoat Roughness'), 0.0), 1.0)
        flat.add_lobe(Lobe("fresnel", (cw * 0.04,) * 3, cr, 1.5, weight=cw))
        if cr > 0.0:
            flat.approx("%s: clearcoat's GTR1 distribution traced as GGX" % name)


def _finish(flat):
    """Clamp to what the engine takes: colours in [0, 1], albedo + non-FRESNEL lobes <= 1 per
    channel (scaled down together), FRESNEL weights <= 1, at most MAX_LOBES lobes; one diffuse
    model (Burley of the weight-averaged roughness where a Principled v1 diffuse part is)."""
    if flat.burley_weight > CUTOFF:
        flat.burley = flat.burley_roughness_sum / flat.burley_weight
        if flat.diffuse_weight - flat.burley_weight > CUTOFF:
            flat.approx("Lambert and Principled (Burley) diffuse parts baked as one Burley diffuse of roughness %.3g"
                        % flat.burley)
    for lobe in flat.lobes:
        if lobe.kind in LAYER_KINDS:
            if lobe.weight > 1.0:
                flat.approx("specular layers adding up to %.3g: scaled to 1" % lobe.weight)
                lobe.color = tuple(c / lobe.weight for c in lobe.color)
                lobe.weight = 1.0
            lobe.color = tuple(min(max(c, 0.0), lobe.weight) for c in lobe.color)
        elif max(lobe.color) > 1.0:
            flat.approx("%s colour %s clamped to 1" % (lobe.kind, tuple(round(c, 3) for c in lobe.color)))
            lobe.color = tuple(min(c, 1.0) for c in lobe.color)
    total = [a + flat.texture_factor for a in flat.albedo]
    for lobe in flat.lobes:
        if lobe.kind not in LAYER_KINDS:
            total = [t + c for t, c in zip(total, lobe.color)]
    peak = max(total)
    if peak > 1.0 + 1e-6:
        flat.approx("diffuse and specular parts adding up to %.3g: scaled to 1" % peak)
        flat.albedo = [a / peak for a in flat.albedo]
        flat.texture_factor /= peak
        flat.linked_factor /= peak
        for lobe in flat.lobes:
            if lobe.kind not in LAYER_KINDS:
                lobe.color = tuple(c / peak for c in lobe.color)
    flat.lobes = [l for l in flat.lobes if max(l.color) > 0.0 or (l.weight or 0.0) > 0.0]
    if len(flat.lobes) > MAX_LOBES:
        flat.lobes.sort(key=lambda l: -(l.weight if l.weight is not None else max(l.color)))
        dropped = flat.lobes[MAX_LOBES:]
        flat.lobes = flat.lobes[:MAX_LOBES]
        flat.approx("%d more lobes than the engine's %d left out" % (len(dropped), MAX_LOBES))
