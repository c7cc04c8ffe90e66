"""Blender's Light Groups -> the engine's light groups: one lightmap layer per group, so that the
preview can relight the scene (a strength and tint per group) without baking again.

Blender decides the groups: the view layer's Light Groups (view_layer.lightgroups) name them, and
lights, emissive objects (object.lightgroup) and the world (world.lightgroup) join one by name.
An emitter whose lightgroup is empty, or names no Light Group of the view layer, is in the default
group (layer "default"). The export declares groups only where the view layer has Light Groups and
some emitter names one of them (else it bakes as without groups); it declares those named, in the
view layer's order.

No bpy here: the functions take Blender's objects (or stand-ins) as arguments, and the name check
is plain Python (python_bridge/tests/test_light_group_names.py).
"""
import re

DEFAULT_LAYER = "default"  # the engine's name of the default group's layer
MAX_NAME = 64              # the engine's longest group name
_NAME = re.compile(r"[A-Za-z0-9_-]+")


def name_problem(name):
    """Why the engine would refuse `name` as a light group name ("" where it takes it): letters,
    digits, '_' and '-', at most MAX_NAME characters, not "default"."""
    if not name:
        return "it is empty"
    if len(name) > MAX_NAME:
        return "it is longer than %d characters" % MAX_NAME
    if not _NAME.fullmatch(name):
        return "it holds characters other than letters, digits, '_' and '-'"
    if name == DEFAULT_LAYER:
        return "'%s' names the layer of the lights in no group" % DEFAULT_LAYER
    return ""


def check_names(names):
    """Raise ValueError naming the first light group the engine would refuse, and why."""
    for name in names:
        why = name_problem(name)
        if why:
            raise ValueError("light group '%s' cannot be baked: %s; rename it in View Layer Properties > "
                             "Light Groups (and on the lights and objects that name it)" % (name, why))


def view_layer_groups(view_layer):
    """The names of the view layer's Light Groups, in its order ([] where Blender has none)."""
    return [g.name for g in getattr(view_layer, "lightgroups", ())]


def lightgroup_of(idblock):
    """An object's or world's lightgroup name ("" where it has none)."""
    return str(getattr(idblock, "lightgroup", "") or "") if idblock is not None else ""


def plan(view_layer, emitters):
    """The groups to declare, in the view layer's order: those of its Light Groups that one of
    `emitters` (objects or the world that emit light) names; [] where none does."""
    declared = view_layer_groups(view_layer)
    named = {lightgroup_of(e) for e in emitters}
    return [g for g in declared if g in named]


class GroupIds:
    """The engine ids of the declared groups (1, 2, ...), and the lookup of an emitter's group."""

    def __init__(self, names, ids):
        self.names = list(names)
        self.ids = dict(zip(names, ids))

    def __bool__(self):
        return bool(self.names)

    def of(self, idblock):
        """The group id of an object or world: 0 (the default group) where it names none of ours."""
        return self.ids.get(lightgroup_of(idblock), 0)
