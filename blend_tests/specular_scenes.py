"""Scenes with glass, mirrors and metal, shared by the Blender tests, the screenshots and the
benchmark (docs/make_specular_screenshots.py, docs/bench_glazed_room.py).

Every lightmapped surface has a fixed, texel-aligned lightmap layout (scenes.quads_object), so
that bakes in different Blender processes compare texel by texel; the glass and metal objects
are geometry only (they block, reflect and refract light but get no lightmap).
"""
import math

import bpy

import scenes


def glass_material(name, ior=1.5, color=(1.0, 1.0, 1.0), roughness=0.0):
    """A Glass BSDF (GGX: the engine's distribution, exact at any roughness)."""
    mat = scenes.node_material(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    glass.distribution = 'GGX'
    glass.inputs["Color"].default_value = tuple(color) + (1.0,)
    glass.inputs["Roughness"].default_value = roughness
    glass.inputs["IOR"].default_value = ior
    glass.location = (-300, 0)
    nt.links.new(glass.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    scenes.see_through_in_eevee(mat)
    return mat


def metal_material(name, color, roughness=0.2):
    """A Principled BSDF with Metallic 1: all its light is the specular layer of F0 = color."""
    mat = scenes.node_material(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = tuple(color) + (1.0,)
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = roughness
    return mat


GOLD = (1.0, 0.766, 0.336)


def sphere(name, material, radius, location, segments=64, rings=32):
    """A smooth-shaded UV sphere, geometry only (no lightmap)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=rings, radius=radius, location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name
    obj.data.polygons.foreach_set("use_smooth", [True] * len(obj.data.polygons))
    obj.data.update()
    obj.data.materials.append(material)
    obj.photonlm.enabled = False
    obj.select_set(False)
    return obj


def sun(elevation_deg, azimuth_deg, energy, angle_deg):
    """A sun shining from elevation / azimuth (degrees; azimuth 0 = from +x, 90 = from +y)."""
    return scenes.add_light("Sun", 'SUN', (0, 0, 6),
                            rotation=(math.radians(90.0 - elevation_deg), 0, math.radians(azimuth_deg + 90.0)),
                            energy=energy, angle=math.radians(angle_deg))


def glass_sphere_on_floor(res=64, ior=1.5, sun_angle=0.5):
    """A 4 m white floor, a glass sphere (radius 0.4 m) resting on it, a sun 35 degrees from the
    zenith, a black world: the sphere's shadow holds the caustic it focuses."""
    scenes.clear_scene()
    floor = scenes.plane("Floor", scenes.diffuse_material("floor", (0.8, 0.8, 0.8)), size=4.0, resolution=res)
    ball = sphere("GlassBall", glass_material("glass", ior), 0.4, (0.0, 0.0, 0.4))
    sun(55.0, 0.0, 3.0, sun_angle)
    return {"Floor": floor, "GlassBall": ball}


def gold_sphere_on_floor(res=64, roughness=0.15, sun_angle=1.0):
    """A 4 m white floor, a gold metal sphere (radius 0.4 m) resting on it, a sun 35 degrees from
    the zenith, a black world: the sphere throws gold light on the floor around it."""
    scenes.clear_scene()
    floor = scenes.plane("Floor", scenes.diffuse_material("floor", (0.8, 0.8, 0.8)), size=4.0, resolution=res)
    ball = sphere("GoldBall", metal_material("gold", GOLD, roughness), 0.4, (0.0, 0.0, 0.4))
    sun(55.0, 0.0, 3.0, sun_angle)
    return {"Floor": floor, "GoldBall": ball}


# ---- the glazed room -----------------------------------------------------------------------------

ROOM = 4.0        # inside: x, y in [-2, 2]
HEIGHT = 2.5      # z in [0, 2.5]
WINDOW = (-0.75, 0.75, 0.75, 2.0)   # the opening in the +x wall: y0, y1, z0, z1 (on texel lines)
PANE = 0.008      # the pane's thickness (Solidify)


def _wall_with_window(res):
    """The +x wall (normal -x, into the room) as four quads around the window opening, laid out
    in one square lightmap with the same texel density as the other walls (4 m per side)."""
    y0, y1, z0, z1 = WINDOW
    h = ROOM / 2
    t = ROOM / res  # metres per texel; the window edges lie on texel lines

    def quad(ya, yb, za, zb):
        # Seen from inside (from -x), +y runs left to right... normal (p1 - p0) x (p3 - p0) = -x:
        # p0 = (h, yb, za), p1 = (h, ya, za), p3 = (h, yb, zb).
        u0, u1 = (h - yb) / ROOM, (h - ya) / ROOM
        v0, v1 = za / ROOM, zb / ROOM
        return ((h, yb, za), (h, ya, za), (h, ya, zb), (h, yb, zb), (u0, v0, u1, v1))
    for v in (y0, y1, z0, z1):
        assert abs(v / t - round(v / t)) < 1e-9, "window edges must lie on texel lines"
    return [quad(-h, y0, 0.0, HEIGHT), quad(y1, h, 0.0, HEIGHT), quad(y0, y1, 0.0, z0), quad(y0, y1, z1, HEIGHT)]


def glazed_room(res=32, sun_angle=15.0, portal=True, with_objects=True):
    """A closed 4 x 4 x 2.5 m room (single-sided quads facing in, white 0.8 Diffuse BSDF) lit
    only through a 1.5 x 1.25 m window in its +x wall, glazed with an 8 mm pane (a quad with a
    Solidify modifier and a Glass BSDF of IOR 1.5); a sun (elevation 35 degrees, from +x,
    angle `sun_angle`) and a uniform sky colour shine in. Inside: a gold metal sphere (Principled
    Metallic 1, roughness 0.2) on the floor and a glass sphere (radius 0.3 m) 1 cm above it, both
    in the sun patch's way. A
    portal light fills the window (it helps Cycles sample the sky; the engine aims its sun and
    sky photons through it). Returns {name: object}."""
    scenes.clear_scene()
    h = ROOM / 2
    objs = {}
    white = (0.8, 0.8, 0.8)
    quads = {
        "Floor": [((-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0), (0, 0, 1, 1))],
        "Ceiling": [((-h, -h, HEIGHT), (-h, h, HEIGHT), (h, h, HEIGHT), (h, -h, HEIGHT), (0, 0, 1, 1))],
        "WallBack": [((-h, -h, 0), (-h, h, 0), (-h, h, HEIGHT), (-h, -h, HEIGHT), (0, 0, 1, HEIGHT / ROOM))],
        "WallLeft": [((h, -h, 0), (-h, -h, 0), (-h, -h, HEIGHT), (h, -h, HEIGHT), (0, 0, 1, HEIGHT / ROOM))],
        "WallRight": [((-h, h, 0), (h, h, 0), (h, h, HEIGHT), (-h, h, HEIGHT), (0, 0, 1, HEIGHT / ROOM))],
        "WallWindow": _wall_with_window(res),
    }
    for name, q in quads.items():
        objs[name] = scenes.quads_object(name, q, scenes.diffuse_material("mat_" + name, white), res)
    y0, y1, z0, z1 = WINDOW
    pane = scenes.quads_object("Pane", [((h, y1, z0), (h, y0, z0), (h, y0, z1), (h, y1, z1), (0, 0, 1, 1))],
                               glass_material("pane_glass", 1.5), 4)
    pane.photonlm.enabled = False
    mod = pane.modifiers.new("Solidify", 'SOLIDIFY')
    mod.thickness = PANE
    mod.offset = 0.0  # centred on the wall's plane
    objs["Pane"] = pane
    if with_objects:
        objs["GoldBall"] = sphere("GoldBall", metal_material("gold", GOLD, 0.2), 0.35, (0.2, 0.6, 0.35))
        objs["GlassBall"] = sphere("GlassBall", glass_material("ball_glass", 1.5), 0.3, (0.3, -0.6, 0.31))
    sun(35.0, 0.0, 4.0, sun_angle)
    scenes.set_world_color((0.4, 0.5, 0.7), 1.0)
    if portal:
        data = bpy.data.lights.new("WindowPortal", 'AREA')
        data.shape = 'RECTANGLE'
        data.size, data.size_y = y1 - y0, z1 - z0
        data.cycles.is_portal = True
        p = bpy.data.objects.new("WindowPortal", data)
        # An area light shines along its -Z: point it into the room (-x), just inside the pane.
        p.location = (h - 0.02, 0.5 * (y0 + y1), 0.5 * (z0 + z1))
        p.rotation_euler = (0.0, math.radians(90.0), 0.0)
        bpy.context.scene.collection.objects.link(p)
        objs["WindowPortal"] = p
    bpy.context.view_layer.update()
    return objs


ROOM_SURFACES = ("Floor", "Ceiling", "WallBack", "WallLeft", "WallRight", "WallWindow")
