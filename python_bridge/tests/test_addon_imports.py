"""The Blender add-on's imports, read from its source with ast (nothing is imported, so no bpy):
no import cycles, no add-on import inside a function, and every import points down the layers
that addon/photonlm_blender/__init__.py lists (base modules, export, uv, writeback, gltf, bake, preview,
properties, operators, ui); __init__.py names every module for registration and reloading."""
import ast
import os

import pytest

from graphs import strong_groups

ADDON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "addon", "photonlm_blender")
PACKAGE = "photonlm_blender"
# Bottom to top: a module imports from its own layer's package or from layers below.
LAYERS = (("version", "compat", "dependencies", "bridge", "stages"), ("export",), ("uv",), ("writeback",), ("gltf",), ("bake",),
          ("preview",), ("properties",), ("operators",), ("ui",))
SCRIPTS = {"export.world_render_child"}  # run as a script by a child Blender, not imported


def _modules():
    out = {}
    for folder, _, files in os.walk(ADDON):
        for f in files:
            if f.endswith(".py"):
                rel = os.path.relpath(os.path.join(folder, f), ADDON)[:-3].replace(os.sep, ".")
                name = rel[:-len(".__init__")] if rel.endswith(".__init__") else ("" if rel == "__init__" else rel)
                out[name] = os.path.join(folder, f)
    return out


MODULES = _modules()


def _imports(name, path):
    """(target module, line, inside a function) for each import of an add-on module."""
    tree = ast.parse(open(path, encoding="utf-8").read(), path)
    in_function = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            in_function.update(id(n) for n in ast.walk(node))
    package = name if path.endswith("__init__.py") else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level:
            parts = package.split(".") if package else []
            base = parts[:len(parts) - node.level + 1]
            target = ".".join(base + ([node.module] if node.module else []))
            for alias in node.names:
                full = (target + "." if target else "") + alias.name
                out.append((full if full in MODULES else target, node.lineno, id(node) in in_function))
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == PACKAGE:
            out.append((node.module[len(PACKAGE) + 1:], node.lineno, id(node) in in_function))
    return [(t, line, late) for t, line, late in out if t in MODULES and t != name]


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _layer(name):
    top = name.split(".")[0]
    for i, layer in enumerate(LAYERS):
        if top in layer:
            return i
    raise AssertionError("module %s is in no layer of LAYERS" % name)


def cycles():
    """The strongly connected groups of more than one module."""
    return strong_groups({v: [w for w, _, _ in edges] for v, edges in GRAPH.items()})


def test_no_import_cycles():
    assert cycles() == []


def test_no_imports_inside_functions():
    late = ["%s:%d imports %s" % (m, line, t) for m, edges in GRAPH.items() for t, line, inside in edges if inside]
    assert late == []


@pytest.mark.parametrize("name", sorted(n for n in MODULES if n and n not in SCRIPTS))
def test_imports_point_down(name):
    up = ["%s (line %d)" % (t, line) for t, line, _ in GRAPH[name]
          if _layer(t) > _layer(name) or (_layer(t) == _layer(name) and LAYERS[_layer(name)] != LAYERS[0]
                                          and t.split(".")[0] != name.split(".")[0])]
    assert up == [], "%s imports upwards: %s" % (name, ", ".join(up))


def test_registration_names_every_module():
    tree = ast.parse(open(MODULES[""], encoding="utf-8").read())
    names = next(ast.literal_eval(n.value) for n in tree.body
                 if isinstance(n, ast.Assign) and getattr(n.targets[0], "id", "") == "MODULE_NAMES")
    packages = {n for n, p in MODULES.items() if p.endswith("__init__.py")}
    assert sorted(names) == sorted(set(MODULES) - packages - SCRIPTS)
    # a module comes after every module it imports (the order reloading needs)
    position = {n: i for i, n in enumerate(names)}
    late = ["%s before %s" % (n, t) for n in names for t, _, _ in GRAPH[n] if t in position and position[t] > position[n]]
    assert late == []


def test_bl_info_is_a_literal_with_the_add_on_version():
    """Blender's add-on list (3.4-4.1: the legacy zip) reads bl_info with ast.literal_eval; a name in
    it hides the add-on from Edit > Preferences > Add-ons. Its version is version.VERSION's and the
    extension manifest's."""
    tree = ast.parse(open(MODULES[""]).read())
    value = next(node.value for node in tree.body if isinstance(node, ast.Assign)
                 and any(isinstance(t, ast.Name) and t.id == "bl_info" for t in node.targets))
    bl_info = ast.literal_eval(value)
    version_tree = ast.parse(open(MODULES["version"]).read())
    version = next(ast.literal_eval(node.value) for node in version_tree.body if isinstance(node, ast.Assign)
                   and any(isinstance(t, ast.Name) and t.id == "VERSION" for t in node.targets))
    assert bl_info["version"] == version
    manifest = open(os.path.join(ADDON, "blender_manifest.toml")).read()
    assert 'version = "%s"' % ".".join(map(str, version)) in manifest
