"""The preview of a material that is not purely diffuse: its own closures without their diffuse part.

The lightmap holds the light a surface's diffuse part reflects; the specular part (glass,
mirrors, metal, a Principled BSDF's specular layer) still needs the material's own shading.
copy_closures copies the closure nodes reaching the Material Output (Mix and Add Shaders and
their leaves, each fed by the same links or values as the original) and leaves the diffuse part
out, so that the preview is lightmap x diffuse albedo (an Emission) + these closures:
    Diffuse BSDF and the leaves flatten.py bakes as diffuse (unknown nodes too): left out
        (a Mix / Add Shader with nothing left on one side passes the other on)
    Principled BSDF (v1, Blender 3.x): copied with Subsurface 1, Subsurface Color black and
        Subsurface Radius 0: Cycles and EEVEE then take its diffuse colour from the black
        subsurface colour (no diffuse closure), while its specular layer, metal, glass,
        clearcoat, sheen, alpha and emission stay as they are (svm_node_closure_bsdf, Cycles
        3.4; EEVEE's principled GLSL)
    Principled BSDF (v2, 4.0+: its subsurface takes the Base Color and turns diffuse at radius
        0, so the v1 way keeps the diffuse part): with Metallic and Transmission 0 copied with a
        black Base Color (no diffuse or subsurface part; specular, coat, sheen, alpha and
        emission as they are); where Metallic or Transmission is 1 copied as it is (it has no
        diffuse part); otherwise copied as it is, its diffuse part then shown lit by the scene
        too (reported)
    Glossy, Anisotropic, Metallic, Glass, Refraction, Transparent, Translucent, Ray Portal,
    Emission, Holdout: copied
    a node group with a specular part or emission: copied as it is (its diffuse part is then
        shown lit by the scene too; reported)
The copies are new nodes tagged closure_<n>; the original nodes are never changed.
"""
from .. import compat
from ..export import flatten

# Glossy is ShaderNodeBsdfAnisotropic from 4.0 (the two merged); Metallic BSDF and Ray Portal BSDF
# exist from 4.2 / 4.3.
COPIED = {'ShaderNodeBsdfGlossy', 'ShaderNodeBsdfAnisotropic', 'ShaderNodeBsdfGlass', 'ShaderNodeBsdfRefraction',
          'ShaderNodeBsdfTransparent', 'ShaderNodeBsdfTranslucent', 'ShaderNodeEmission', 'ShaderNodeHoldout',
          'ShaderNodeBsdfMetallic', 'ShaderNodeBsdfRayPortal'}
ROLE_PREFIX = "closure_"


def copy_closures(tree, surface, make_node, x0, y0):
    """Copy the closures feeding `surface` (a Material Output's Surface input of `tree`) without
    their diffuse part. make_node(role, bl_idname) makes a tagged node. Returns (the copy's
    output socket or None when nothing but diffuse is left, report strings)."""
    copier = _Copier(tree, make_node, x0, y0)
    out = copier.visit(surface, 0)
    return out, copier.notes


class _Copier:
    def __init__(self, tree, make_node, x0, y0):
        self.tree = tree
        self.make_node = make_node
        self.x0, self.y0 = x0, y0
        self.count = 0
        self.notes = []

    def visit(self, socket, depth):
        """The copied output for the closure reaching input `socket`, or None."""
        if depth > 64:
            return None
        node, out, _ = flatten.link_step(socket)
        if node is None:
            return None
        kind = node.bl_idname
        if kind in ('ShaderNodeMixShader', 'ShaderNodeAddShader'):
            first = 1 if kind == 'ShaderNodeMixShader' else 0
            a = self.visit(node.inputs[first], depth + 1)
            b = self.visit(node.inputs[first + 1], depth + 1)
            if a is None and b is None:
                return None
            if kind == 'ShaderNodeAddShader' and (a is None or b is None):
                return a if b is None else b
            copy = self.copy(node, depth)
            for target, src in ((copy.inputs[first], a), (copy.inputs[first + 1], b)):
                if src is not None:
                    self.tree.links.new(src, target)
            return copy.outputs[0]
        if kind == 'ShaderNodeBsdfPrincipled':
            copy = self.copy(node, depth)
            if compat.principled_v2(node):
                self._principled_v2(node, copy)
            else:
                for name, value in (('Subsurface', 1.0), ('Subsurface Color', (0.0, 0.0, 0.0, 1.0)),
                                    ('Subsurface Radius', (0.0, 0.0, 0.0))):
                    self._set_input(copy.inputs[name], value)
            return copy.outputs[0]
        if kind in COPIED:
            return self.copy(node, depth).outputs[list(node.outputs).index(out)]
        if kind == 'ShaderNodeGroup' and node.node_tree is not None:
            flat = flatten.flatten_output(out)
            if not flat.lobes and max(flat.emission) <= 0.0 and flat.emission_texture_socket is None:
                return None
            self.notes.append("node group '%s' in material '%s' is previewed with its own shading (its diffuse "
                              "part lit by the scene, not by the lightmap)" % (node.name, self.tree.name))
            return self.copy(node, depth).outputs[list(node.outputs).index(out)]
        return None  # diffuse: the lightmap shows it

    def _set_input(self, socket, value):
        for l in list(socket.links):
            self.tree.links.remove(l)
        socket.default_value = value

    def _principled_v2(self, node, copy):
        """Leave a v2 Principled BSDF's copy without its diffuse part where that is exact."""
        weights = [compat.principled_input(node, name) for name in ("Metallic", "Transmission")]
        if all(s is not None and not s.is_linked for s in weights):
            metallic, transmission = (float(s.default_value) for s in weights)
            if metallic <= 0.0 and transmission <= 0.0:
                self._set_input(copy.inputs['Base Color'], (0.0, 0.0, 0.0, 1.0))
                return
            if metallic >= 1.0 or transmission >= 1.0:
                return
        self.notes.append("material '%s': Principled BSDF '%s' has a linked or partial Metallic or "
                          "Transmission: previewed with its own shading (its diffuse part lit by the "
                          "scene, not by the lightmap)" % (self.tree.name, node.name))

    def copy(self, node, depth):
        """A tagged node of node's type with its settings and the same input links and values
        (closure inputs are left to the caller)."""
        n = self.make_node(ROLE_PREFIX + str(self.count), node.bl_idname)
        self.count += 1
        n.location = (self.x0 + 220.0 * (8 - min(depth, 8)), self.y0 - 180.0 * self.count)
        for prop in node.bl_rna.properties:
            ident = prop.identifier
            if prop.type == 'ENUM' and not prop.is_readonly and not ident.startswith("bl_") and ident != "type":
                try:
                    setattr(n, ident, getattr(node, ident))
                except (TypeError, AttributeError, ValueError):
                    pass
        if node.bl_idname == 'ShaderNodeGroup':
            n.node_tree = node.node_tree
        for src, dst in zip(node.inputs, n.inputs):
            if src.type == 'SHADER':
                continue
            for l in list(dst.links):
                self.tree.links.remove(l)
            if src.is_linked:
                link = src.links[0]
                new = self.tree.links.new(link.from_socket, dst)
                if link.is_muted:
                    new.is_muted = True
            elif hasattr(src, "default_value"):
                try:
                    dst.default_value = src.default_value
                except (TypeError, ValueError):
                    pass
        return n
