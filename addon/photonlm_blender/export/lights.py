"""Lights -> engine lights: point, spot, sun, area (square/rectangle -> AREA_RECT, disk/ellipse ->
AREA_DISK) and Cycles portal lights (square/rectangle -> PORTAL). Colour and power are what
Cycles emits (compat.light_emission: temperature, exposure, normalize); a light whose node tree
is more than the default Emission is reported (its nodes are not baked)."""
import numpy as np

from .. import compat


def add_light(plm, obj_eval, matrix, reports, group=0):
    """Add an evaluated light (or portal) to the bridge scene, in light group `group` (an engine id;
    0: the default group); False where it emits nothing or is skipped."""
    light = obj_eval.data
    m = [list(row) for row in matrix]
    if light.type == 'AREA' and getattr(getattr(light, "cycles", None), "is_portal", False):
        if light.shape not in ('SQUARE', 'RECTANGLE'):
            reports.warning("portal '%s': only square and rectangle portals are supported: skipped" % obj_eval.name)
            return False
        sy = light.size_y if light.shape == 'RECTANGLE' else light.size
        try:
            plm.add_light('PORTAL', name=obj_eval.name, matrix=m, size=light.size, size_y=sy)
        except Exception as e:
            reports.warning("portal '%s' skipped: %s" % (obj_eval.name, getattr(e, "message", e)))
            return False
        reports.info("portal '%s': sun and sky light are sampled through it" % obj_eval.name)
        return True
    color, power = compat.light_emission(light, lambda: area_light_area(light, matrix))
    if power <= 0.0 or max(color) <= 0.0:
        return False
    if compat.light_nodes_differ(light):
        reports.warning("light '%s': light nodes are ignored (colour and power come from the light's "
                        "settings)" % obj_eval.name)
    kw = dict(name=obj_eval.name, color=color, power=power, matrix=m)
    t = light.type
    try:
        if t == 'POINT':
            lid = plm.add_light('POINT', radius=light.shadow_soft_size, **kw)
        elif t == 'SPOT':
            lid = plm.add_light('SPOT', radius=light.shadow_soft_size, spot_size=light.spot_size,
                          spot_blend=light.spot_blend, **kw)
        elif t == 'SUN':
            lid = plm.add_light('SUN', angle=light.angle, **kw)
        elif t == 'AREA':
            shape = light.shape
            sy = light.size_y if shape in ('RECTANGLE', 'ELLIPSE') else light.size
            lid = plm.add_light('AREA_RECT' if shape in ('SQUARE', 'RECTANGLE') else 'AREA_DISK',
                          size=light.size, size_y=sy, **kw)
        else:
            reports.warning("light '%s': type %s is not supported: skipped" % (obj_eval.name, t))
            return False
        if group:
            plm.set_light_group(group, light=lid)
    except Exception as e:
        reports.warning("light '%s' skipped: %s" % (obj_eval.name, getattr(e, "message", e)))
        return False
    return True


def area_light_area(light, matrix):
    """World-space area of an area light as Cycles measures it: its size along the object's scaled
    X and Y axes, x pi/4 for disks and ellipses."""
    m = np.array(matrix, dtype=np.float64)
    sy = light.size_y if light.shape in ('RECTANGLE', 'ELLIPSE') else light.size
    area = float(light.size) * np.linalg.norm(m[:3, 0]) * float(sy) * np.linalg.norm(m[:3, 1])
    return area * (np.pi / 4.0 if light.shape in ('DISK', 'ELLIPSE') else 1.0)
