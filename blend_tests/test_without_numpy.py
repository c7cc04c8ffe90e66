"""Without NumPy (Debian's `blender` package does not pull in python3-numpy) the add-on enables
without a traceback and its panel says what is missing and how to get it.

NumPy is made unimportable in this Blender process (sys.modules["numpy"] = None: `import numpy`
raises ImportError, as where it is not installed) before the add-on is imported from the source tree.
Expected:
- the add-on imports and registers; none of its modules that need NumPy is imported, and no bake
  operator or settings are registered;
- Render Properties > PhotonLM Lightmaps is there, and its text names NumPy and the Debian package
  python3-numpy;
- the add-on unregisters again.
"""
import os
import sys

sys.modules["numpy"] = None  # before anything imports it

import bpy  # noqa: E402

SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class Layout:
    """Collects what a panel's draw writes."""
    def __init__(self):
        self.texts = []

    def label(self, text="", **_):
        self.texts.append(text)

    def column(self, **_):
        return self

    def box(self):
        return self

    def row(self, **_):
        return self


def main():
    failed = []

    def check(ok, what):
        print("[%s] without_numpy: %s" % ("PASS" if ok else "FAIL", what), flush=True)
        if not ok:
            failed.append(what)

    try:
        import numpy  # noqa: F401
        check(False, "numpy is hidden")
    except ImportError:
        check(True, "numpy cannot be imported")
    sys.path.insert(0, os.path.join(SRC, "addon"))
    import photonlm_blender
    photonlm_blender.register()
    loaded = sorted(m for m in sys.modules if m.startswith("photonlm_blender."))
    check(loaded and all(m.split(".")[1] in ("version", "compat", "dependencies") for m in loaded),
          "no module that needs NumPy is imported: %s" % loaded)
    check(not hasattr(bpy.types.Scene, "photonlm") and "bake" not in dir(bpy.ops.photonlm),
          "no settings or bake operator are registered")
    panel = getattr(bpy.types, "PHOTONLM_PT_lightmaps", None)
    check(panel is not None and panel.bl_context == "render", "the PhotonLM panel is in Render Properties")
    if panel is not None:
        layout = Layout()

        from types import SimpleNamespace
        panel.draw(SimpleNamespace(layout=layout), SimpleNamespace(region=None, preferences=bpy.context.preferences))
        text = " ".join(layout.texts)
        check("NumPy" in text and "python3-numpy" in text, "the panel says what is missing and how to get it: %r"
              % text)
    photonlm_blender.unregister()
    check(getattr(bpy.types, "PHOTONLM_PT_lightmaps", None) is None, "the add-on unregisters")
    print("without_numpy: %d failed" % len(failed))
    if failed:
        raise AssertionError("without_numpy FAILED: " + "; ".join(failed))


main()
