"""How large a lightmap is.

Lightmap resolution of an object (object.photonlm.resolution = 0, the default):
    n = clamp(next_power_of_two(sqrt(A) * density * scale), 16, 4096)
where A is the object's world-space surface area (modifiers and scale applied) in m^2,
density is scene.photonlm.texel_density in texels per metre and scale the object's
density_scale. The lightmap is n x n. In atlases (scene.photonlm.lightmap_layout = 'ATLAS')
n = clamp(ceil(sqrt(A) * density * scale), 16, page size - margin): one density for all
objects (ResolutionRule). UV packing leaves some space unused, so the real density on the
surface is somewhat lower.
"""
import math

# A bake holds about 240 bytes for every lightmap texel and 160 more for each covered one
# (the engine's memory estimate): an object's Resolution is capped where one lightmap alone
# would need tens of gigabytes.
RESOLUTION_MAX = 8192
RESOLUTION_SOFT_MAX = 4096

# AUTO chooses an OL above this many triangles per lightmap texel.
AUTO_TRIANGLES_PER_TEXEL = 4


def resolution_from_area(area, density, power_of_two=True, largest=4096):
    """Lightmap side length for a surface of `area` m^2 at `density` texels per metre: the next
    power of two (power_of_two), else the next whole texel, within [16, largest]."""
    want = math.sqrt(max(area, 0.0)) * max(density, 0.0)
    if power_of_two:
        n = 1 << max(0, math.ceil(math.log2(want))) if want > 1.0 else 1
    else:
        n = math.ceil(want) if math.isfinite(want) else largest
    return int(min(max(n, 16), largest))


def atlas_pad(settings):
    """Texels of edge repeated around each block of an atlas: half the margin, at least 1 (so that
    bilinear filtering at mip 0 never mixes two blocks)."""
    return max(1, (int(settings.lightmap_margin) + 1) // 2)


class ResolutionRule:
    """How an object's lightmap size follows from its surface area (scene settings `settings`):
    the object's Resolution where set, else texel density x the object's density scale, rounded up
    to a power of two for lightmaps of their own, to a whole texel in atlases (every object then gets
    the same density) and capped there so that the block with its margin fits a page."""

    def __init__(self, settings):
        self.density = float(settings.texel_density)
        self.atlas = getattr(settings, "lightmap_layout", 'OBJECT') == 'ATLAS'
        self.largest = int(settings.atlas_size) - 2 * atlas_pad(settings) if self.atlas else 4096

    def __call__(self, obj, area):
        if obj.photonlm.resolution > 0:
            return int(obj.photonlm.resolution)
        if callable(area):
            area = area()
        return resolution_from_area(area, self.density * float(obj.photonlm.density_scale),
                                    power_of_two=not self.atlas, largest=self.largest)
