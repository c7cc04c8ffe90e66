"""Material flattening: node set-ups -> the engine's diffuse albedo and specular lobes, with the
values worked out by hand from Cycles 3.4's closure weights (svm_node_closure_bsdf, mix closure).
Glossy and Glass nodes name their distribution (the default is GGX / Beckmann in 3.4,
Multiscatter GGX from 4.0). The Principled BSDF values hold in Blender 3.4 (Principled v1); from 4.0 the Principled BSDF is v2
(Lambert diffuse under an energy-conserving specular layer, other inputs), so there these cases
print SKIP and the Principled materials are only built, wired for the preview and exported:

Principled BSDF, m = Metallic, t = Transmission, w = the weight reaching it:
    diffuse albedo  w (1 - m)(1 - t) Base Color
    specular layer  FRESNEL, weight w (1 - t (1 - m)), F0 = Specular x 0.08 x mix(1, tint, Specular
                    Tint) x (1 - m) + Base Color x m (tint = Base / (0.3 r + 0.6 g + 0.1 b)),
                    IOR 2 / (1 - sqrt(0.08 Specular)) - 1; lobe colour = weight x F0
    glass           GLASS w t (1 - m) x Base Color, IOR
    clearcoat       FRESNEL weight 0.25 w Clearcoat, F0 0.04, IOR 1.5
    alpha           TRANSPARENT w (1 - Alpha), the rest x Alpha
Mix Shader: (1 - Fac) first + Fac second; Add Shader: both.

Also: the reports (one line per material naming it and the approximations), the preview wiring
of a glass, a metal and a diffuse + specular material (their closures copied without the diffuse
part, the original untouched, preview off restores it exactly), and what an export hands to the
engine (the lobes through Scene.add_material_lobe where the bridge has it).
"""
import math
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

scenes.setup_paths()
from photonlm_blender.export import flatten  # noqa: E402
from photonlm_blender.export import materials  # noqa: E402
from photonlm_blender.writeback import wiring  # noqa: E402

checks = scenes.Checks("material_lobes")
TOL = 1e-5
V1 = not scenes.PRINCIPLED_V2  # Principled v1: the closure weights below (Blender 3.4)


def new_material(name):
    mat = scenes.node_material(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.bl_idname != 'ShaderNodeOutputMaterial':
            nt.nodes.remove(n)
    return mat, nt, nt.nodes["Material Output"]


def node(nt, idname, **inputs):
    n = nt.nodes.new(idname)
    for key, value in inputs.items():
        if key.startswith("_"):
            setattr(n, key[1:], value)
            continue
        sock = scenes.principled_input(n, key.replace("_", " ")) if idname == 'ShaderNodeBsdfPrincipled' \
            else n.inputs[key.replace("_", " ")]
        sock.default_value = tuple(value) + (1.0,) if isinstance(value, tuple) and len(value) == 3 \
            and len(sock.default_value) == 4 else value
    return n


def principled(nt, **inputs):
    """A Principled BSDF with Blender's defaults (Base 0.8, Specular 0.5, Roughness 0.5, IOR 1.45)."""
    return node(nt, 'ShaderNodeBsdfPrincipled', **inputs)


def to_output(nt, out, n, socket=0):
    nt.links.new(n.outputs[socket], out.inputs['Surface'])


def close(a, b, tol=TOL):
    if a is None or b is None:
        return a is None and b is None
    a, b = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float))
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= tol))


def lobes_match(got, want):
    """want: list of (kind, color, roughness, ior, weight) in any order."""
    if len(got) != len(want):
        return False
    left = list(got)
    for kind, color, rough, ior, weight in want:
        hit = next((g for g in left if g.kind == kind and close(g.color, color) and close(g.roughness, rough)
                    and close(g.ior, ior) and close(g.weight, weight)), None)
        if hit is None:
            return False
        left.remove(hit)
    return True


def case(label, mat, albedo, lobes, emission=(0.0, 0.0, 0.0), approx=(), no_approx=False):
    info = materials.read_material(mat)
    ok_albedo = close(info.albedo, albedo)
    ok_lobes = lobes_match(info.lobes, lobes)
    ok_emission = close(info.emission, emission)
    lines = [n for n in info.notes if "approximated" in n]
    ok_notes = all(any(a in n for n in lines) for a in approx)
    if approx or no_approx:
        ok_notes = ok_notes and len(lines) <= 1 and all(("'%s'" % mat.name) in n for n in lines)
    if no_approx:
        ok_notes = ok_notes and not lines
    checks.check(ok_albedo and ok_lobes and ok_emission and ok_notes,
                 "%s: albedo %s, lobes %s, emission %s, notes %s"
                 % (label, tuple(round(c, 5) for c in info.albedo), info.lobes,
                    tuple(round(c, 4) for c in info.emission), info.notes))
    return info


def case_v1(label, *args, **kwargs):
    """case() for a Principled BSDF set-up whose values are Principled v1's (Blender 3.4)."""
    if V1:
        return case(label, *args, **kwargs)
    print("SKIP %s: Principled v1 closure weights (hold in Blender 3.4; this is %d.%d, Principled v2)"
          % (label, *scenes.BLENDER))
    return None


def spec_ior(specular):
    return 2.0 / (1.0 - math.sqrt(0.08 * specular)) - 1.0


# ---- single shaders ----------------------------------------------------------------------------

mat, nt, out = new_material("diffuse")
to_output(nt, out, node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.2, 0.4, 0.6)))
case("Diffuse BSDF", mat, (0.2, 0.4, 0.6), [], no_approx=True)

mat, nt, out = new_material("principled_default")
to_output(nt, out, principled(nt))
# F0 = 0.5 x 0.08 = 0.04, IOR = 2 / (1 - 0.2) - 1 = 1.5
case_v1("Principled defaults: diffuse 0.8 + specular layer F0 0.04", mat, (0.8, 0.8, 0.8),
     [("fresnel", (0.04,) * 3, 0.5, 1.5, 1.0)], no_approx=True)

mat, nt, out = new_material("principled_no_specular")
to_output(nt, out, principled(nt, Specular=0.0, Base_Color=(0.3, 0.5, 0.7)))
info = case_v1("Principled, Specular 0: purely diffuse", mat, (0.3, 0.5, 0.7), [], no_approx=True)
if info is not None:
    checks.check(info.purely_diffuse(), "Specular 0 and no metal or glass: purely diffuse")

GOLD = (1.0, 0.766, 0.336)
mat, nt, out = new_material("gold")
to_output(nt, out, principled(nt, Metallic=1.0, Base_Color=GOLD, Roughness=0.2))
case_v1("Principled metal: F0 = Base Color, no diffuse", mat, (0.0, 0.0, 0.0),
     [("fresnel", GOLD, 0.2, 1.5, 1.0)], no_approx=True)

mat, nt, out = new_material("metal_no_specular")
to_output(nt, out, principled(nt, Metallic=1.0, Specular=0.0, Base_Color=(0.9, 0.9, 0.9), Roughness=0.0))
case_v1("Principled metal, Specular 0: IOR 1 (constant F0)", mat, (0.0,) * 3, [("fresnel", (0.9,) * 3, 0.0, 1.0, 1.0)])

base = (0.5, 0.2, 0.1)
lum = 0.3 * 0.5 + 0.6 * 0.2 + 0.1 * 0.1
tmp = [0.5 + 0.5 * c / lum for c in base]
f0 = [0.04 * t * 0.5 + c * 0.5 for t, c in zip(tmp, base)]
if V1:  # Specular Tint is a float in v1, a colour in v2
    mat, nt, out = new_material("half_metal_tinted")
    to_output(nt, out, principled(nt, Metallic=0.5, Base_Color=base, Specular_Tint=0.5))
    case_v1("Principled Metallic 0.5, Specular Tint 0.5", mat, tuple(0.5 * c for c in base),
            [("fresnel", f0, 0.5, 1.5, 1.0)], no_approx=True)

mat, nt, out = new_material("specular_0.8")
to_output(nt, out, principled(nt, Specular=0.8, Roughness=0.1))
case_v1("Principled Specular 0.8: F0 0.064, IOR from Specular", mat, (0.8,) * 3,
     [("fresnel", (0.064,) * 3, 0.1, spec_ior(0.8), 1.0)], no_approx=True)

mat, nt, out = new_material("glass_principled")
to_output(nt, out, principled(nt, Transmission=1.0, Base_Color=(1.0, 1.0, 1.0), Roughness=0.0, IOR=1.5))
case_v1("Principled Transmission 1 (white): one GLASS lobe, no specular layer", mat, (0.0,) * 3,
     [("glass", (1.0,) * 3, 0.0, 1.5, None)], no_approx=True)

# m 0.25, t 0.6: diffuse (0.75)(0.4) = 0.3; glass 0.6 x 0.75 = 0.45; specular 1 - 0.45 = 0.55,
# F0 = 0.04 x 0.75 + 0.9 x 0.25 = 0.255.
mat, nt, out = new_material("glass_metal_mix")
to_output(nt, out, principled(nt, Metallic=0.25, Transmission=0.6, Base_Color=(0.9, 0.9, 0.9), Roughness=0.0))
case_v1("Principled Metallic 0.25 + Transmission 0.6", mat, (0.27,) * 3,
     [("glass", (0.405,) * 3, 0.0, 1.45, None), ("fresnel", (0.55 * 0.255,) * 3, 0.0, 1.5, 0.55)],
     approx=("reflection is tinted",))

if V1:  # v2 has no Transmission Roughness
    mat, nt, out = new_material("rough_glass_principled")
    to_output(nt, out, principled(nt, Transmission=1.0, Base_Color=(1.0, 1.0, 1.0), Roughness=0.2,
                                  Transmission_Roughness=0.5))
    # Cycles 3.4, GGX: refraction roughness 1 - (1 - 0.2)(1 - 0.5) = 0.6
    case_v1("Principled glass with Transmission Roughness: one roughness 0.6, reported", mat, (0.0,) * 3,
            [("glass", (1.0,) * 3, 0.6, 1.45, None)], approx=("Transmission Roughness",))

mat, nt, out = new_material("alpha")
to_output(nt, out, principled(nt, Alpha=0.25, Specular=0.0))
case_v1("Principled Alpha 0.25: TRANSPARENT 0.75, the rest x 0.25", mat, (0.2,) * 3,
     [("transparent", (0.75,) * 3, 0.0, None, None)], no_approx=True)

mat, nt, out = new_material("clearcoat")
to_output(nt, out, principled(nt, Clearcoat=1.0, Clearcoat_Roughness=0.1))
case_v1("Principled Clearcoat 1: FRESNEL 0.25 x (F0 0.04, IOR 1.5), GTR1 reported", mat, (0.8,) * 3,
     [("fresnel", (0.04,) * 3, 0.5, 1.5, 1.0), ("fresnel", (0.01,) * 3, 0.1, 1.5, 0.25)],
     approx=("GTR1",))

mat, nt, out = new_material("emissive_principled")
to_output(nt, out, principled(nt, Emission=(1.0, 0.5, 0.25), Emission_Strength=4.0, Specular=0.0))
case_v1("Principled emission", mat, (0.8,) * 3, [], emission=(4.0, 2.0, 1.0), no_approx=True)

if V1:  # v2 has no Subsurface Color (subsurface takes the Base Color)
    mat, nt, out = new_material("sheen_aniso_sss")
    to_output(nt, out, principled(nt, Sheen=0.5, Anisotropic=0.5, Subsurface=0.5,
                                  Subsurface_Color=(0.2, 0.2, 0.2), Specular=0.0))
    case_v1("Principled sheen, anisotropy, subsurface: reported in one line", mat, (0.5,) * 3, [],
            approx=("sheen", "anisotropy", "subsurface"))

mat, nt, out = new_material("glossy")
to_output(nt, out, node(nt, 'ShaderNodeBsdfGlossy', Color=(0.9, 0.8, 0.7), Roughness=0.3, _distribution='GGX'))
case("Glossy BSDF (GGX)", mat, (0.0,) * 3, [("glossy", (0.9, 0.8, 0.7), 0.3, None, None)], no_approx=True)

if scenes.BLENDER < (4, 0):  # 4.0 removed the Sharp distribution (GGX at roughness 0 is the mirror)
    mat, nt, out = new_material("mirror")
    to_output(nt, out, node(nt, 'ShaderNodeBsdfGlossy', Color=(1.0, 1.0, 1.0), Roughness=0.7, _distribution='SHARP'))
    case("Glossy BSDF Sharp: roughness 0", mat, (0.0,) * 3, [("glossy", (1.0,) * 3, 0.0, None, None)], no_approx=True)

mat, nt, out = new_material("glass_bsdf")
to_output(nt, out, node(nt, 'ShaderNodeBsdfGlass', Color=(0.9, 1.0, 0.9), Roughness=0.0, IOR=1.52,
                        _distribution='BECKMANN'))
case("Glass BSDF (Beckmann, roughness 0: exact)", mat, (0.0,) * 3,
     [("glass", (0.9, 1.0, 0.9), 0.0, 1.52, None)], no_approx=True)

mat, nt, out = new_material("rough_glass_bsdf")
to_output(nt, out, node(nt, 'ShaderNodeBsdfGlass', Roughness=0.3, IOR=1.5, _distribution='BECKMANN'))
case("Glass BSDF Beckmann rough: GGX, reported", mat, (0.0,) * 3, [("glass", (1.0,) * 3, 0.3, 1.5, None)],
     approx=("Beckmann",))

mat, nt, out = new_material("refraction")
to_output(nt, out, node(nt, 'ShaderNodeBsdfRefraction', Color=(0.5, 0.6, 0.7), IOR=1.33, _distribution='GGX',
                        Roughness=0.1))
case("Refraction BSDF", mat, (0.0,) * 3, [("refraction", (0.5, 0.6, 0.7), 0.1, 1.33, None)], no_approx=True)

mat, nt, out = new_material("transparent")
to_output(nt, out, node(nt, 'ShaderNodeBsdfTransparent', Color=(0.3, 0.3, 0.9)))
case("Transparent BSDF", mat, (0.0,) * 3, [("transparent", (0.3, 0.3, 0.9), 0.0, None, None)], no_approx=True)

mat, nt, out = new_material("emission")
to_output(nt, out, node(nt, 'ShaderNodeEmission', Color=(1.0, 0.9, 0.8), Strength=10.0))
case("Emission", mat, (0.0,) * 3, [], emission=(10.0, 9.0, 8.0), no_approx=True)

# ---- Principled BSDF v2 (Blender 4.0+; Cycles 4's closures as docs/design/cycles-versions.md "Cycles versions" takes them):
# m = Metallic, t = Transmission Weight, ws = w (1 - m)(1 - t): diffuse albedo ws x Base Color under a
# SPECULAR layer of weight ws, F0 = ((IOR - 1) / (IOR + 1))^2 x 2 Specular IOR Level (its curve a
# dielectric's of the IOR with that F0); metal FRESNEL w m, F0 = Base Color (IOR 1.5 curve); glass
# GLASS w (1 - m) t x sqrt(Base Color); emission Emission Color x Strength.

if not V1:
    def f0_of(ior):
        return ((ior - 1.0) / (ior + 1.0)) ** 2

    mat, nt, out = new_material("v2_principled_default")
    p = principled(nt)
    to_output(nt, out, p)
    ior0 = p.inputs['IOR'].default_value
    case("Principled v2 defaults: diffuse 0.8 under a SPECULAR layer of F0(IOR %.2f)" % ior0, mat, (0.8,) * 3,
         [("specular", (f0_of(ior0),) * 3, 0.5, ior0, 1.0)], no_approx=True)

    mat, nt, out = new_material("v2_no_specular")
    to_output(nt, out, principled(nt, Specular=0.0, Base_Color=(0.3, 0.5, 0.7)))
    info = case("Principled v2, Specular IOR Level 0: purely diffuse", mat, (0.3, 0.5, 0.7), [], no_approx=True)
    checks.check(info.purely_diffuse(), "Principled v2, Specular IOR Level 0 and no metal or glass: purely diffuse")

    mat, nt, out = new_material("v2_gold")
    to_output(nt, out, principled(nt, Metallic=1.0, Base_Color=GOLD, Roughness=0.2))
    case("Principled v2 metal: FRESNEL, F0 = Base Color, no diffuse; multiscatter reported", mat, (0.0,) * 3,
         [("fresnel", GOLD, 0.2, 1.5, 1.0)], approx=("multiscatter",))

    mat, nt, out = new_material("v2_glass")
    to_output(nt, out, principled(nt, Transmission=1.0, Base_Color=(0.81, 1.0, 0.64), Roughness=0.0, IOR=1.5))
    case("Principled v2 Transmission 1: one GLASS lobe tinted sqrt(Base Color), reflection tint reported", mat,
         (0.0,) * 3, [("glass", (0.9, 1.0, 0.8), 0.0, 1.5, None)], approx=("tinted",))

    mat, nt, out = new_material("v2_alpha_emission")
    to_output(nt, out, principled(nt, Alpha=0.25, Specular=0.0, Emission=(1.0, 0.5, 0.25), Emission_Strength=4.0))
    case("Principled v2 Alpha 0.25 with emission: TRANSPARENT 0.75, the rest (emission too) x 0.25", mat,
         (0.2,) * 3, [("transparent", (0.75,) * 3, 0.0, None, None)], emission=(1.0, 0.5, 0.25), no_approx=True)

# ---- mixes -----------------------------------------------------------------------------------

mat, nt, out = new_material("mix_diffuse_glossy")
mix = node(nt, 'ShaderNodeMixShader', Fac=0.3)
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(1.0, 0.0, 0.0)).outputs[0], mix.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfGlossy', Color=(1.0, 1.0, 1.0), Roughness=0.2, _distribution='GGX').outputs[0],
             mix.inputs[2])
to_output(nt, out, mix)
case("Mix 0.3 (Diffuse red, Glossy white)", mat, (0.7, 0.0, 0.0), [("glossy", (0.3,) * 3, 0.2, None, None)],
     no_approx=True)

mat, nt, out = new_material("mix_fac_value")
mix = node(nt, 'ShaderNodeMixShader')
val = nt.nodes.new('ShaderNodeValue')
val.outputs[0].default_value = 0.8
math_n = node(nt, 'ShaderNodeMath', _operation='MULTIPLY')
math_n.inputs[1].default_value = 0.5
nt.links.new(val.outputs[0], math_n.inputs[0])
nt.links.new(math_n.outputs[0], mix.inputs[0])  # Fac = 0.8 x 0.5 = 0.4 through a Math node
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.5, 0.5, 0.5)).outputs[0], mix.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfGlass', IOR=1.5).outputs[0], mix.inputs[2])
to_output(nt, out, mix)
case("Mix with Fac from Value x Math: evaluated (0.4), not reported", mat, (0.3,) * 3,
     [("glass", (0.4,) * 3, 0.0, 1.5, None)], no_approx=True)

mat, nt, out = new_material("mix_fac_fresnel")
mix = node(nt, 'ShaderNodeMixShader')
fres = node(nt, 'ShaderNodeFresnel', IOR=1.45)
nt.links.new(fres.outputs[0], mix.inputs[0])
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.5, 0.5, 0.5)).outputs[0], mix.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfGlossy', Color=(1.0, 1.0, 1.0), Roughness=0.0).outputs[0], mix.inputs[2])
to_output(nt, out, mix)
fa = flatten.hemisphere_fresnel(1.45)
checks.check(0.07 < fa < 0.12, "hemispherical Fresnel of IOR 1.45 is %.4f (between 0.07 and 0.12)" % fa)
# The same average by a plain midpoint sum over cos (independent of flatten's loop): 2 int F mu dmu.
mus = (np.arange(20000) + 0.5) / 20000
g = np.sqrt(1.45 ** 2 - 1 + mus ** 2)
F = 0.5 * ((g - mus) / (g + mus)) ** 2 * (1 + ((mus * (g + mus) - 1) / (mus * (g - mus) + 1)) ** 2)
checks.check(abs(fa - float(np.mean(2 * F * mus))) < 1e-4, "hemispherical Fresnel matches a fine sum %.5f"
             % float(np.mean(2 * F * mus)))
case("Mix with Fac from Fresnel: its hemispherical average, reported", mat, (0.5 * (1 - fa),) * 3,
     [("glossy", (fa,) * 3, 0.0, None, None)], approx=("Fresnel node",))

mat, nt, out = new_material("mix_fac_noise")
mix = node(nt, 'ShaderNodeMixShader')
nt.links.new(nt.nodes.new('ShaderNodeTexNoise').outputs[0], mix.inputs[0])
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.5, 0.5, 0.5)).outputs[0], mix.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfGlossy', Color=(1.0, 1.0, 1.0), Roughness=0.0).outputs[0], mix.inputs[2])
to_output(nt, out, mix)
case("Mix with Fac from a Noise Texture: 0.5, reported", mat, (0.25,) * 3,
     [("glossy", (0.5,) * 3, 0.0, None, None)], approx=("Noise Texture", "Mix Shader"))

mat, nt, out = new_material("add_over_one")
add = nt.nodes.new('ShaderNodeAddShader')
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.8, 0.8, 0.8)).outputs[0], add.inputs[0])
nt.links.new(node(nt, 'ShaderNodeBsdfGlossy', Color=(0.8, 0.8, 0.8), Roughness=0.0).outputs[0], add.inputs[1])
to_output(nt, out, add)
case("Add Shader summing to 1.6: scaled to 1, reported", mat, (0.5,) * 3,
     [("glossy", (0.5,) * 3, 0.0, None, None)], approx=("adding up to 1.6",))

# Two Principled BSDFs 50 / 50: their specular layers (same roughness and IOR) merge exactly.
mat, nt, out = new_material("mix_two_principled")
mix = node(nt, 'ShaderNodeMixShader', Fac=0.5)
nt.links.new(principled(nt, Base_Color=(1.0, 0.0, 0.0)).outputs[0], mix.inputs[1])
nt.links.new(principled(nt, Metallic=1.0, Base_Color=(0.0, 0.0, 1.0)).outputs[0], mix.inputs[2])
to_output(nt, out, mix)
case_v1("Mix of dielectric and metal Principled: one merged specular layer", mat, (0.5, 0.0, 0.0),
     [("fresnel", (0.02, 0.02, 0.02 + 0.5), 0.5, 1.5, 1.0)], no_approx=True)

# Mix -> Add -> Mix: weights multiply along the way.
mat, nt, out = new_material("nested")
m1 = node(nt, 'ShaderNodeMixShader', Fac=0.25)
add = nt.nodes.new('ShaderNodeAddShader')
m2 = node(nt, 'ShaderNodeMixShader', Fac=0.5)
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.4, 0.4, 0.4)).outputs[0], m1.inputs[1])
nt.links.new(add.outputs[0], m1.inputs[2])
nt.links.new(m2.outputs[0], add.inputs[0])
nt.links.new(node(nt, 'ShaderNodeEmission', Color=(1.0, 1.0, 1.0), Strength=2.0).outputs[0], add.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfTransparent').outputs[0], m2.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfRefraction', IOR=1.33).outputs[0], m2.inputs[2])
to_output(nt, out, m1)
case("Mix(0.25: Diffuse, Add(Mix(0.5: Transparent, Refraction), Emission 2))", mat, (0.3,) * 3,
     [("transparent", (0.125,) * 3, 0.0, None, None), ("refraction", (0.125,) * 3, 0.0, 1.33, None)],
     emission=(0.5, 0.5, 0.5), no_approx=True)

# A muted Mix Shader passes its first shader on; a Reroute is followed.
mat, nt, out = new_material("muted_mix")
mix = node(nt, 'ShaderNodeMixShader', Fac=0.9)
reroute = nt.nodes.new('NodeReroute')
nt.links.new(node(nt, 'ShaderNodeBsdfDiffuse', Color=(0.6, 0.6, 0.6)).outputs[0], reroute.inputs[0])
nt.links.new(reroute.outputs[0], mix.inputs[1])
nt.links.new(node(nt, 'ShaderNodeBsdfGlossy').outputs[0], mix.inputs[2])
mix.mute = True
to_output(nt, out, mix)
case("muted Mix Shader: its first input, through a Reroute", mat, (0.6,) * 3, [], no_approx=True)

# ---- node groups, textures ----------------------------------------------------------------------

group = bpy.data.node_groups.new("metal_group", 'ShaderNodeTree')
scenes.group_socket(group, 'INPUT', 'NodeSocketColor', "Tint")
scenes.group_socket(group, 'INPUT', 'NodeSocketFloat', "Rough")
scenes.group_socket(group, 'OUTPUT', 'NodeSocketShader', "Shader")
gin, gout = group.nodes.new('NodeGroupInput'), group.nodes.new('NodeGroupOutput')
gp = principled(group, Metallic=1.0)
group.links.new(gin.outputs["Tint"], gp.inputs["Base Color"])
group.links.new(gin.outputs["Rough"], gp.inputs["Roughness"])
group.links.new(gp.outputs[0], gout.inputs["Shader"])
mat, nt, out = new_material("grouped_metal")
gnode = nt.nodes.new('ShaderNodeGroup')
gnode.node_tree = group
rgb = nt.nodes.new('ShaderNodeRGB')
rgb.outputs[0].default_value = (0.95, 0.64, 0.54, 1.0)
nt.links.new(rgb.outputs[0], gnode.inputs["Tint"])
gnode.inputs["Rough"].default_value = 0.35
to_output(nt, out, gnode)
case_v1("node group: a metal whose colour comes from an RGB node outside", mat, (0.0,) * 3,
     [("fresnel", (0.95, 0.64, 0.54), 0.35, 1.5, 1.0)], no_approx=True)


def flat_image(name, value, colorspace='Non-Color', size=8, float_buffer=False):
    img = bpy.data.images.new(name, size, size, alpha=True, float_buffer=float_buffer)
    img.colorspace_settings.name = colorspace
    px = np.empty((size, size, 4), np.float32)
    px[...] = value
    img.pixels.foreach_set(px.ravel())
    return img


mat, nt, out = new_material("metallic_map")
p = principled(nt, Base_Color=(0.5, 0.5, 0.5))
tex = node(nt, 'ShaderNodeTexImage')
tex.image = flat_image("metal_mask", (0.5, 0.5, 0.5, 1.0), float_buffer=True)
nt.links.new(tex.outputs["Color"], p.inputs["Metallic"])
to_output(nt, out, p)
# Metallic = mean 0.5: diffuse 0.25; F0 = 0.04 x 0.5 + 0.5 x 0.5 = 0.27
case_v1("Metallic from an image: its mean, reported", mat, (0.25,) * 3, [("fresnel", (0.27,) * 3, 0.5, 1.5, 1.0)],
     approx=("metal_mask",))

checker = bpy.data.images.new("base_checker", 4, 4, alpha=True)
mat, nt, out = new_material("textured_metal_mix")
p = principled(nt, Metallic=0.5)
tex = node(nt, 'ShaderNodeTexImage')
tex.image = flat_image("base_srgb", (0.5, 0.5, 0.5, 1.0), colorspace='sRGB')
nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
to_output(nt, out, p)
lin = ((128 / 255 + 0.055) / 1.055) ** 2.4  # the byte image's sRGB 128 / 255 decoded
info = case_v1("Image into Base Color, Metallic 0.5: texture x 0.5 for the diffuse part, the mean (linear) "
            "for the metal's F0", mat, (0.5,) * 3, [("fresnel", (0.02 + 0.5 * lin,) * 3, 0.5, 1.5, 1.0)],
            approx=("base_srgb",))
if info is not None:
    checks.check(info.albedo_texture is not None and info.albedo_texture.image.name == "base_srgb",
                 "the image stays the albedo texture")

# ---- reports ----------------------------------------------------------------------------------

mat, nt, out = new_material("toon_and_more")
add = nt.nodes.new('ShaderNodeAddShader')
nt.links.new(node(nt, 'ShaderNodeBsdfToon', Color=(0.5, 0.5, 0.5)).outputs[0], add.inputs[0])
nt.links.new(principled(nt, Sheen=1.0, Specular=0.0, Base_Color=(0.1, 0.1, 0.1)).outputs[0], add.inputs[1])
to_output(nt, out, add)
info = materials.read_material(mat)
approx_lines = [n for n in info.notes if "approximated" in n]
checks.check(len(approx_lines) == 1 and "'toon_and_more'" in approx_lines[0] and "Toon" in approx_lines[0]
             and "sheen" in approx_lines[0], "several approximations, one report line naming the material: %s"
             % approx_lines)

# ---- the preview ------------------------------------------------------------------------------


def state(mat, active=True):
    nt = mat.node_tree
    nodes = sorted((n.name, n.bl_idname, getattr(n, "is_active_output", None) if active else None) for n in nt.nodes
                   if n.get("photonlm") is None)
    links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in nt.links if l.from_node.get("photonlm") is None and l.to_node.get("photonlm") is None)
    values = sorted((n.name, s.identifier, str(tuple(s.default_value) if hasattr(s.default_value, "__len__")
                                                 else s.default_value))
                    for n in nt.nodes if n.get("photonlm") is None for s in n.inputs if hasattr(s, "default_value"))
    return nodes, links, values


lm = bpy.data.images.new("lm", 4, 4, float_buffer=True)
for name in ("gold", "glass_bsdf", "mix_diffuse_glossy", "principled_default", "diffuse", "nested"):
    mat = bpy.data.materials[name]
    before, state_inactive = state(mat), state(mat, False)
    notes = wiring.wire_material(mat, lm, 'CYCLES')
    nt = mat.node_tree
    ours = {n.get("photonlm"): n for n in nt.nodes if n.get("photonlm") is not None}
    copies = [n for r, n in ours.items() if str(r).startswith("closure_")]
    info = materials.read_material(mat)
    wiring.set_preview(mat, 'LIGHTMAP')
    active = nt.get_output_node('CYCLES')
    if info.purely_diffuse():
        checks.check(not copies and "add_closures" not in ours, "%s: purely diffuse, no closure copies" % name)
    else:
        src = active.inputs['Surface'].links[0].from_node if active.inputs['Surface'].is_linked else None
        checks.check(src == ours.get("add_closures") and copies
                     and not any(n.bl_idname == 'ShaderNodeBsdfDiffuse' for n in copies),
                     "%s: preview = lightmap emission + copied closures %s (no Diffuse BSDF)"
                     % (name, sorted(n.bl_idname for n in copies)))
        emit0 = ours["emission_original"]
        checks.check(not emit0.inputs['Strength'].is_linked and emit0.inputs['Strength'].default_value == 0.0,
                     "%s: the original Emission is off (the copies carry the emission)" % name)
        for c in copies:
            if c.bl_idname == 'ShaderNodeBsdfPrincipled' and V1:  # v1's inputs
                checks.check(c.inputs['Subsurface'].default_value == 1.0
                             and tuple(c.inputs['Subsurface Color'].default_value)[:3] == (0.0, 0.0, 0.0)
                             and tuple(c.inputs['Subsurface Radius'].default_value) == (0.0, 0.0, 0.0),
                             "%s: the copied Principled BSDF has no diffuse part (black subsurface)" % name)
    mul = ours["multiply"]
    checks.check(close(mul.inputs['Color1'].default_value[:3], info.albedo),
                 "%s: the lightmap is multiplied by the diffuse albedo %s" % (name, info.albedo))
    checks.check(state(mat, False) == state_inactive,
                 "%s: original nodes, links and values untouched with the preview on" % name)
    n_nodes = len(nt.nodes)
    wiring.wire_material(mat, lm, 'CYCLES')
    checks.check(len(nt.nodes) == n_nodes, "%s: wiring again reuses the nodes (%d)" % (name, n_nodes))
    wiring.set_preview(mat, 'OFF')
    checks.check(state(mat) == before and nt.get_output_node('CYCLES').get("photonlm") is None,
                 "%s: preview off restores the original output" % name)
    wiring.remove_wiring(mat)
    checks.check(state(mat) == before and not any(n.get("photonlm") is not None for n in nt.nodes),
                 "%s: removing the wiring leaves the material as it was" % name)

# ---- export: what the engine gets ----------------------------------------------------------------

from photonlm_blender import bridge  # noqa: E402
from photonlm_blender.export import scene as export  # noqa: E402
import types  # noqa: E402

case_materials = [m for m in bpy.data.materials if m.users == 0 and m.node_tree is not None]
for i, mat in enumerate(case_materials):
    x = 3.0 * i
    scenes.quads_object("plane_%s" % mat.name, [((x, 0, 0), (x + 2, 0, 0), (x + 2, 2, 0), (x, 2, 0), (0, 0, 1, 1))],
                        mat, 4)
scenes.add_light("sun", 'SUN', (0, 0, 5), energy=3.0)
photonlm = bridge.get()
from photonlm.scene_file import SceneFileWriter  # noqa: E402

writer = SceneFileWriter()
reports = export.Reports()
result = export.export_scene(bpy.context, types.SimpleNamespace(Scene=lambda: writer), reports)
by_name = {m.get("name"): m for m in writer.materials}
if not V1:
    print("SKIP scene-file lobes of the gold, glass_metal_mix and clearcoat materials: Principled v1 values "
          "(hold in Blender 3.4)")
else:
    gold = by_name.get("gold", {}).get("lobes", [])
    checks.check(len(gold) == 1 and gold[0]["type"] == "fresnel" and close(gold[0]["color"], GOLD)
                 and close(gold[0]["weight"], 1.0) and close(gold[0]["roughness"], 0.2) and close(gold[0]["ior"], 1.5),
                 "scene file: the gold metal is one FRESNEL lobe, F0 = its Base Color: %s" % gold)
    gm = by_name.get("glass_metal_mix", {})
    fres = [l for l in gm.get("lobes", []) if l["type"] == "fresnel"]
    checks.check(len(fres) == 1 and close(fres[0]["color"], (0.255,) * 3) and close(fres[0]["weight"], 0.55)
                 and close(gm["albedo"], (0.27,) * 3),
                 "scene file: a FRESNEL lobe goes as F0 = colour / weight (0.255) and weight 0.55: %s" % fres)
    cc = [l for l in by_name.get("clearcoat", {}).get("lobes", []) if close(l["roughness"], 0.1)]
    checks.check(len(cc) == 1 and close(cc[0]["color"], (0.04,) * 3) and close(cc[0]["weight"], 0.25),
                 "scene file: clearcoat F0 0.04, weight 0.25: %s" % cc)
checks.check(not by_name.get("diffuse", {}).get("lobes"), "scene file: a Diffuse BSDF has no lobes")
engine_scene = photonlm.Scene()
reports2 = export.Reports()
try:
    export.export_scene(bpy.context, types.SimpleNamespace(Scene=lambda: engine_scene), reports2)
finally:
    engine_scene.close()
refused = [t for t in reports2.texts() if "left out:" in t]
checks.check(not refused, "the engine takes every lobe of every test material: %s" % refused)
approx_reports = [t for t in reports2.texts() if "approximated for the bake" in t]
names = [t.split("'")[1] for t in approx_reports]
checks.check(len(names) == len(set(names)), "one approximation report per material (%d)" % len(names))

checks.finish()
