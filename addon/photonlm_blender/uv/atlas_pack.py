"""Packing lightmap blocks into square atlas pages (pure Python: no bpy, no numpy).

A block is one object's lightmap, w x h texels. In a page it occupies a cell of
(w + 2 pad) x (h + 2 pad) texels: the block's texels at (x, y) and a ring of `pad` texels
around them that repeats the block's edge texels, so that bilinear filtering at the page's
mip 0 never reaches into another block. Cells never overlap and stay inside the page.

pack() places every block anew, largest first, by skyline bottom-left packing: each page keeps
its skyline (the top of what is placed, as segments along x); a cell goes into the first page
with room, where its top is lowest (then leftmost), and a new page is opened when none has room.
place() adds blocks to an existing layout without moving what is there (free space found among
the cells already placed, else a new page).
"""


class BlockTooLarge(ValueError):
    """A block whose cell is larger than a page; .index is the block's index."""

    def __init__(self, index, size, page, pad):
        self.index = index
        super().__init__("a %d x %d block with a margin of %d texels on each side does not fit in a %d x %d page"
                         % (size[0], size[1], pad, page, page))


class Placement(tuple):
    """(page, x, y, w, h): a block's texels in page `page`, lower left corner (x, y), rows bottom first."""
    __slots__ = ()

    def __new__(cls, page, x, y, w, h):
        return tuple.__new__(cls, (int(page), int(x), int(y), int(w), int(h)))

    page = property(lambda s: s[0])
    x = property(lambda s: s[1])
    y = property(lambda s: s[2])
    w = property(lambda s: s[3])
    h = property(lambda s: s[4])

    def cell(self, pad):
        """(x0, y0, x1, y1) of the cell, half-open."""
        return (self.x - pad, self.y - pad, self.x + self.w + pad, self.y + self.h + pad)

    def scale_offset(self, page_size):
        """(su, sv, ou, ov): the block's UVs in the page are u' = u su + ou, v' = v sv + ov."""
        return (self.w / page_size, self.h / page_size, self.x / page_size, self.y / page_size)


def _check(sizes, page, pad):
    if page < 1 or pad < 0:
        raise ValueError("page size must be >= 1 and pad >= 0, got %r and %r" % (page, pad))
    for i, (w, h) in enumerate(sizes):
        if w < 1 or h < 1:
            raise ValueError("block %d has no texels (%r x %r)" % (i, w, h))
        if w + 2 * pad > page or h + 2 * pad > page:
            raise BlockTooLarge(i, (w, h), page, pad)


class _Skyline:
    """One page's skyline: segments [x, y, width] covering [0, page) left to right."""

    def __init__(self, page):
        self.page = page
        self.segments = [[0, 0, page]]

    def find(self, cw, ch):
        """(top, x, y, index) of the lowest-top, leftmost spot for a cw x ch cell, or None."""
        best = None
        segs = self.segments
        for i, (x, _, _) in enumerate(segs):
            if x + cw > self.page:
                break
            y, j, covered = 0, i, 0
            while covered < cw:
                y = max(y, segs[j][1])
                covered = segs[j][0] + segs[j][2] - x
                j += 1
            if y + ch > self.page:
                continue
            if best is None or (y + ch, x) < best[:2]:
                best = (y + ch, x, y, i)
        return best

    def add(self, x, y, cw, ch, index):
        """Raise the skyline over [x, x + cw) to y + ch (the spot find() returned at `index`)."""
        segs = self.segments
        new = [x, y + ch, cw]
        right = x + cw
        j = index
        while j < len(segs) and segs[j][0] < right:
            j += 1
        tail = segs[j - 1]
        rest = [] if tail[0] + tail[2] <= right else [[right, tail[1], tail[0] + tail[2] - right]]
        segs[index:j] = [new] + rest
        merged = []
        for s in segs:  # neighbours at the same height become one segment
            if merged and merged[-1][1] == s[1]:
                merged[-1][2] += s[2]
            else:
                merged.append(s)
        self.segments = merged


# Orders tried by pack(): largest first by height, by area, by longer side, by width.
_ORDERS = (lambda w, h: (-h, -w), lambda w, h: (-w * h, -h), lambda w, h: (-max(w, h), -w * h),
           lambda w, h: (-w, -h))


def _pack_in_order(sizes, order, page, pad):
    pages = []
    out = [None] * len(sizes)
    for i in order:
        w, h = sizes[i]
        cw, ch = w + 2 * pad, h + 2 * pad
        best = None
        for k, sky in enumerate(pages):  # the first page with room: pages fill one after another
            spot = sky.find(cw, ch)
            if spot is not None:
                best = (spot, k)
                break
        if best is None:
            pages.append(_Skyline(page))
            best = (pages[-1].find(cw, ch), len(pages) - 1)
        (_, x, y, index), k = best
        pages[k].add(x, y, cw, ch, index)
        out[i] = Placement(k, x + pad, y + pad, w, h)
    return out


def pack(sizes, page, pad):
    """Place blocks of `sizes` [(w, h), ...] into as few page x page pages as the packing finds.
    Returns a list of Placement in the order of `sizes`. Raises BlockTooLarge for a block whose
    cell does not fit a page.

    Blocks go largest first; "largest" is tried as tallest, of most area, of longest side and
    widest, and the layout with the fewest pages (then the least filled last page) is kept."""
    _check(sizes, page, pad)
    best, best_key = [], None
    for rank in _ORDERS:
        order = sorted(range(len(sizes)), key=lambda i: rank(*sizes[i]) + (i,))
        placed = _pack_in_order(sizes, order, page, pad)
        count = page_count(placed)
        last = sum((p.w + 2 * pad) * (p.h + 2 * pad) for p in placed if p.page == count - 1)
        if best_key is None or (count, last) < best_key:
            best, best_key = placed, (count, last)
    return best


def _overlaps(a, b):
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def place(sizes, placed, page, pad, pages):
    """Place new blocks of `sizes` beside the Placements `placed` (which stay where they are), each in
    the free spot lowest in the first page that has one (spots are tried at the page's corner and
    at the right and top edges of the cells there), else in a new page. `pages` is the number of
    pages the layout has. Returns (list of Placement in the order of sizes, page count)."""
    _check(sizes, page, pad)
    cells = [(p.page, p.cell(pad)) for p in placed]
    out = []
    for w, h in sizes:
        cw, ch = w + 2 * pad, h + 2 * pad
        found = None
        for k in range(pages):
            mine = [c for q, c in cells if q == k]
            xs = sorted({0} | {c[2] for c in mine})
            ys = sorted({0} | {c[3] for c in mine})
            for y in ys:
                for x in xs:
                    cell = (x, y, x + cw, y + ch)
                    if cell[2] <= page and cell[3] <= page and not any(_overlaps(cell, c) for c in mine):
                        found = (k, x, y)
                        break
                if found:
                    break
            if found:
                break
        if found is None:
            found = (pages, 0, 0)
            pages += 1
        k, x, y = found
        p = Placement(k, x + pad, y + pad, w, h)
        cells.append((k, p.cell(pad)))
        out.append(p)
    return out, pages


def page_count(placements):
    return 1 + max((p.page for p in placements), default=-1)


def overlapping(placements, pad, page):
    """Pairs (i, j) of placements whose cells overlap, and indices whose cell leaves the page:
    (pairs, outside). Both empty for a valid layout."""
    cells = [(p.page, p.cell(pad)) for p in placements]
    pairs = [(i, j) for i in range(len(cells)) for j in range(i + 1, len(cells))
             if cells[i][0] == cells[j][0] and _overlaps(cells[i][1], cells[j][1])]
    outside = [i for i, (_, c) in enumerate(cells) if c[0] < 0 or c[1] < 0 or c[2] > page or c[3] > page]
    return pairs, outside
