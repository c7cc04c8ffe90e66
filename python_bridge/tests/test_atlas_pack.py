"""The add-on's atlas packer (addon/photonlm_blender/uv/atlas_pack.py, pure Python): cells never overlap
or leave the page, pages are few for the area packed, a block too large is named, and place() keeps
what is placed where it is."""
import importlib.util
import math
import os
import random

import pytest

_PATH = os.path.join(os.path.dirname(__file__), "..", "..", "addon", "photonlm_blender", "uv", "atlas_pack.py")
_spec = importlib.util.spec_from_file_location("atlas_pack", _PATH)
atlas_pack = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(atlas_pack)


def _valid(placements, sizes, page, pad):
    pairs, outside = atlas_pack.overlapping(placements, pad, page)
    assert pairs == [] and outside == []
    assert [(p.w, p.h) for p in placements] == [tuple(s) for s in sizes]


def test_overlap_check_finds_overlaps():
    """The check the other tests lean on fails on a layout that overlaps or leaves the page."""
    a = atlas_pack.Placement(0, 2, 2, 10, 10)
    b = atlas_pack.Placement(0, 14, 2, 10, 10)   # cells [0, 14) and [12, 26) with pad 2: overlap
    c = atlas_pack.Placement(0, 30, 30, 10, 10)  # cell reaches 42 > 40
    assert atlas_pack.overlapping([a, b], 2, 40) == ([(0, 1)], [])
    assert atlas_pack.overlapping([a, b], 1, 40) == ([], [])
    assert atlas_pack.overlapping([c], 2, 40) == ([], [0])
    assert atlas_pack.overlapping([a, atlas_pack.Placement(1, 2, 2, 10, 10)], 2, 40) == ([], [])


@pytest.mark.parametrize("seed", range(6))
def test_random_blocks_pack_without_overlap_into_few_pages(seed):
    rng = random.Random(seed)
    page, pad = 256, 2
    sizes = [(rng.randint(1, 60), rng.randint(1, 60)) for _ in range(rng.randint(1, 120))]
    placements = atlas_pack.pack(sizes, page, pad)
    _valid(placements, sizes, page, pad)
    area = sum((w + 2 * pad) * (h + 2 * pad) for w, h in sizes)
    lower = math.ceil(area / page ** 2)
    count = atlas_pack.page_count(placements)
    assert lower <= count <= max(lower + 1, math.ceil(1.3 * lower))


def test_equal_squares_fill_pages_exactly():
    """64 cells of 32 x 32 (28 + 2 x 2) fill one 256 page exactly; one more opens a second page."""
    placements = atlas_pack.pack([(28, 28)] * 64, 256, 2)
    _valid(placements, [(28, 28)] * 64, 256, 2)
    assert atlas_pack.page_count(placements) == 1
    assert atlas_pack.page_count(atlas_pack.pack([(28, 28)] * 65, 256, 2)) == 2


def test_largest_first_and_scale_offset():
    p = atlas_pack.pack([(10, 10), (100, 50)], 128, 1)
    assert p[1].page == 0 and (p[1].x, p[1].y) == (1, 1)  # the large block first, at the corner
    su, sv, ou, ov = p[1].scale_offset(128)
    assert (su, sv, ou, ov) == (100 / 128, 50 / 128, 1 / 128, 1 / 128)


def test_block_too_large_is_named():
    with pytest.raises(atlas_pack.BlockTooLarge) as e:
        atlas_pack.pack([(10, 10), (125, 20)], 128, 2)
    assert e.value.index == 1 and "125 x 20" in str(e.value)
    atlas_pack.pack([(124, 124)], 128, 2)  # exactly fits
    with pytest.raises(ValueError):
        atlas_pack.pack([(0, 5)], 128, 2)


def test_place_keeps_layout_and_fills_free_space():
    page, pad = 128, 2
    sizes = [(30, 30)] * 9  # 3 x 3 cells of 34: one page, a strip 26 texels wide left at the right and top
    placed = atlas_pack.pack(sizes, page, pad)
    assert atlas_pack.page_count(placed) == 1
    before = list(placed)
    # Free block 3's spot, then place a block of its size, one that needs a page of its own and a
    # small one that fits the strip.
    kept = placed[:3] + placed[4:]
    new, pages = atlas_pack.place([(30, 30), (124, 124), (20, 20)], kept, page, pad, 1)
    assert kept == before[:3] + before[4:]
    pairs, outside = atlas_pack.overlapping(kept + new, pad, page)
    assert pairs == [] and outside == []
    assert new[0] == before[3]              # the freed spot
    assert new[1].page == 1 and pages == 2  # a whole page of its own
    assert new[2].page == 0                 # in the strip of the first page
