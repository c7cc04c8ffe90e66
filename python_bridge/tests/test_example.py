"""The numpy example (python_bridge/examples/bake_numpy_scene.py) runs and gives sane lightmaps."""
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples"))
import bake_numpy_scene  # noqa: E402


def test_example_bakes_and_writes_exrs(tmp_path):
    means = bake_numpy_scene.main([str(tmp_path), "--target-error", "0.05"])
    for name in ("floor", "wall_x", "wall_y", "ball"):
        assert (tmp_path / (name + "_lightmap.exr")).is_file()
        assert means[name] > 0.0
    # The sunlit floor is brighter than the walls, which only see the sky and bounced light;
    # the sun (3 W/m^2 at 35 degrees) alone gives the open floor 3 cos 35 / pi = 0.78.
    assert means["floor"] > means["wall_y"]
    assert 0.3 < means["floor"] < 1.5
