"""What the add-on needs from Blender's Python beyond bpy: NumPy.

Blender from blender.org bundles NumPy. Debian's (and Ubuntu's) `blender` package runs the
system's Python, where NumPy is the package python3-numpy, which `blender` does not pull in.
Without NumPy the add-on still enables: it registers only this module's panel (Render
Properties > PhotonLM Lightmaps), which says what is missing and how to get it. No other module
of the add-on is imported then (they use NumPy at import).
"""
import sys
import textwrap

import bpy


def missing():
    """A sentence saying what is missing and how to get it, or None when nothing is."""
    try:
        import numpy  # noqa: F401
    except ImportError as e:
        return ("PhotonLM needs NumPy, which this Blender's Python %d.%d cannot import (%s). "
                "On Debian or Ubuntu install it with 'sudo apt install python3-numpy' and restart "
                "Blender. Blender from blender.org includes NumPy."
                % (sys.version_info[0], sys.version_info[1], e))
    return None


class PHOTONLM_PT_missing(bpy.types.Panel):
    bl_label = "PhotonLM Lightmaps"
    bl_idname = "PHOTONLM_PT_lightmaps"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"

    def draw(self, context):
        text = missing() or "NumPy is available now: disable and enable the add-on, or restart Blender."
        width = context.region.width if getattr(context, "region", None) is not None else 300
        chars = max(20, int(width / (7.0 * context.preferences.view.ui_scale)) - 6)
        col = self.layout.column(align=True)
        for i, line in enumerate(textwrap.wrap(text, chars)):
            col.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')


def register():
    bpy.utils.register_class(PHOTONLM_PT_missing)
    print("PhotonLM: %s" % missing())


def unregister():
    bpy.utils.unregister_class(PHOTONLM_PT_missing)
