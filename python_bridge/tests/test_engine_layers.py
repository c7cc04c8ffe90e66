"""The engine's folders, read from the #include lines of native/src (nothing is compiled): every
include points down the layers that LAYERS lists, so the folder-level include graph has no cycle,
neither between the folders that hold files (transport/'s and lsystem/'s sub-folders count as
folders of their own) nor between the top-level folders; and no folder holds more than
MAX_FLAT_FILES sources (.h and .cpp) of its own.

Run as a script, it prints the figures: folder-level include cycles, folder pairs on a cycle and the
largest flat folder."""
import os
import re
import sys

import pytest

from graphs import strong_groups

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "native")
SRC = os.path.join(ROOT, "src")
PUBLIC = os.path.join(ROOT, "include")
# Bottom to top (docs/design/README.md, "Layers of native/src"): a file includes files of its own
# folder and of the folders listed before its own, never after. A top-level folder's sub-folders sit
# together, so the top-level folders keep the same order.
LAYERS = (
    "util",
    "ol",
    "csg",
    "subdiv",
    "lsystem/language",
    "lsystem/graph",
    "lsystem",
    "scene",
    "accel",
    "lightmap",
    "transport/plan",
    "transport/lights",
    "transport/materials",
    "transport/rays",
    "transport/context",
    "transport/photons",
    "transport/film",
    "transport/direct",
    "transport/gather",
    "transport/output",
    "transport/farm",
    "transport/control",
    "transport/jobs",
    "api",
    "io",
)
MAX_FLAT_FILES = 20
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)


def sources():
    """Every .h and .cpp under native/src, as a path relative to it."""
    out = []
    for folder, _, files in os.walk(SRC):
        out += [os.path.relpath(os.path.join(folder, f), SRC) for f in files if f.endswith((".h", ".cpp"))]
    return sorted(p.replace(os.sep, "/") for p in out)


def folder(path):
    return path.rpartition("/")[0]


def top(node):
    return node.split("/")[0]


def includes(path):
    """(included source under native/src or None for the public header, the include as written, line)
    for each quoted include; a name that is neither resolves to "?" + the name."""
    text = open(os.path.join(SRC, path), encoding="utf-8").read()
    out = []
    for m in INCLUDE.finditer(text):
        name, line = m.group(1), text.count("\n", 0, m.start()) + 1
        local = os.path.normpath(os.path.join(folder(path), name)).replace(os.sep, "/")
        if os.path.isfile(os.path.join(SRC, name)):
            out.append((name, name, line))
        elif os.path.isfile(os.path.join(SRC, local)):
            out.append((local, name, line))
        elif os.path.isfile(os.path.join(PUBLIC, name)):
            out.append((None, name, line))
        else:
            out.append(("?" + name, name, line))
    return out


FILES = sources()
EDGES = {p: includes(p) for p in FILES}


def folder_graph(node=folder):
    """Folder -> {included folder: [(file, line, include)]}, own-folder includes left out."""
    graph = {}
    for p, incs in EDGES.items():
        graph.setdefault(node(p), {})
        for target, name, line in incs:
            if target and not target.startswith("?") and node(target) != node(p):
                graph[node(p)].setdefault(node(target), []).append((p, line, name))
    return graph


def cycles(graph):
    """Every elementary cycle of the graph, each once (from its smallest folder)."""
    out = []

    def walk(start, v, path, seen):
        for w in sorted(graph.get(v, {})):
            if w == start:
                out.append(path[:])
            elif w > start and w not in seen:
                seen.add(w)
                path.append(w)
                walk(start, w, path, seen)
                path.pop()
                seen.discard(w)
    for v in sorted(graph):
        walk(v, v, [v], {v})
    return out


def pairs_on_cycles(graph):
    """Pairs of folders each of which reaches the other through includes."""
    return sum(len(g) * (len(g) - 1) // 2 for g in strong_groups(graph))


def flat_counts():
    """Folder under native/src -> how many .h and .cpp files it holds itself (sub-folders apart)."""
    counts = {}
    for folder_path, _, files in os.walk(SRC):
        rel = os.path.relpath(folder_path, SRC).replace(os.sep, "/")
        counts[rel] = sum(f.endswith((".h", ".cpp")) for f in files)
    return counts


def _layer(node):
    assert node in LAYERS, "folder %s is in no layer of LAYERS" % node
    return LAYERS.index(node)


def test_every_include_names_a_file():
    missing = ["%s:%d %s" % (p, line, name) for p, incs in EDGES.items() for t, name, line in incs
               if t and t.startswith("?")]
    assert missing == []


def test_layers_name_the_folders():
    folders = {folder(p) for p in FILES}
    assert sorted(folders - set(LAYERS)) == [], "folders in no layer"
    assert sorted(set(LAYERS) - folders) == [], "layers without files"
    tops = [top(n) for n in LAYERS]
    split = [t for t in set(tops) if tops.index(t) + tops.count(t) != len(tops) - tops[::-1].index(t)]
    assert split == [], "a top-level folder's sub-folders are not together in LAYERS"


@pytest.mark.parametrize("node", LAYERS)
def test_includes_point_down(node):
    up = ["%s:%d includes %s" % (p, line, name) for target, refs in folder_graph().get(node, {}).items()
          if _layer(target) > _layer(node) for p, line, name in refs]
    assert up == [], "%s includes upwards: %s" % (node, "; ".join(up))


@pytest.mark.parametrize("node", [folder, lambda p: top(folder(p))], ids=["folders", "top-level folders"])
def test_no_folder_include_cycles(node):
    graph = folder_graph(node)
    assert strong_groups(graph) == []
    assert cycles(graph) == []


def test_folders_hold_at_most_20_files_flat():
    over = {f: n for f, n in flat_counts().items() if n > MAX_FLAT_FILES}
    assert over == {}


def main():
    for name, node in (("folders", folder), ("top-level folders", lambda p: top(folder(p)))):
        graph = folder_graph(node)
        found = cycles(graph)
        print("%s: %d, include cycles: %d, folder pairs on a cycle: %d"
              % (name, len(graph), len(found), pairs_on_cycles(graph)))
        for group in strong_groups(graph):
            print("  on a cycle together: " + " ".join(group))
    counts = flat_counts()
    largest = max(counts, key=lambda f: (counts[f], f))
    print("largest flat folder: %s, %d files" % (largest, counts[largest]))


if __name__ == "__main__":
    sys.exit(main())
