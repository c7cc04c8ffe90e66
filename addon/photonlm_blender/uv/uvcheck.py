"""Measures a lightmap UV layout the way the engine will use it (numpy only).

analyse(uv, res, positions) takes the lightmap UV of every triangle (T, 3, 2) and the
lightmap's resolution and returns what decides whether the layout bakes cleanly:

    zero_area       triangles with world area but no UV area (the engine stores no light for them)
    outside         triangles reaching outside the [0, 1] square (the part outside is lost)
    overlap_texels  texels whose covered area adds up to more than one texel (the engine's
                    'islands overlap' count: two surfaces share one value)
    shared_texels   texels touched by more than one UV island (surfaces that are not
                    neighbours on the mesh mix their light there: a leak)
    flipped         triangles whose UV winding is opposite to the rest of their island (folds)
    margin          the smallest distance between two islands, in texels (capped at
                    MARGIN_CAP; 0 when islands overlap)
    utilisation     the share of the map's area the islands cover
    islands         the number of UV islands

Coverage is exact: every triangle is clipped against the texel grid, as the engine does
(native/src/lightmap/texel_area.cpp). An island is a set of triangles connected through mesh
edges that have the same UV at both ends on both sides (corners of one vertex within
UV_TOLERANCE; which corners are one vertex comes from the triangles' positions).
"""
import numpy as np

MARGIN_CAP = 4.0       # texels: margins beyond this are reported as this
_MIN_COVER = 1e-3      # the engine treats a texel covered less than this as empty
_OVERLAP = 1.0 + 1e-4  # the engine's overlap threshold
_CHUNK = 200_000


UV_TOLERANCE = 1e-6  # UV units: corners of one vertex this close are one UV point


def _corner_ids(points):
    """An id per row of points (N, k): equal rows (bit for bit) get equal ids."""
    p = np.ascontiguousarray(points)
    _, ids = np.unique(p.view(np.dtype((np.void, p.dtype.itemsize * p.shape[1]))).ravel(), return_inverse=True)
    return ids.ravel()


def _edges(uv, vertex):
    """Every triangle edge once per triangle: (lo vertex, hi vertex, uv at lo, uv at hi, triangle),
    sorted so that the edges of one mesh edge are next to each other."""
    t = len(uv)
    tri = np.tile(np.arange(t), 3)
    va = np.concatenate([vertex[:, 0], vertex[:, 1], vertex[:, 2]])
    vb = np.concatenate([vertex[:, 1], vertex[:, 2], vertex[:, 0]])
    ua = np.concatenate([uv[:, 0], uv[:, 1], uv[:, 2]])
    ub = np.concatenate([uv[:, 1], uv[:, 2], uv[:, 0]])
    swap = va > vb
    lo, hi = np.where(swap, vb, va), np.where(swap, va, vb)
    ulo, uhi = np.where(swap[:, None], ub, ua), np.where(swap[:, None], ua, ub)
    order = np.lexsort((hi, lo))
    return lo[order], hi[order], ulo[order], uhi[order], tri[order]


def _glued(edges):
    """Indices (i, i + 1) of consecutive sorted edges that are one UV edge: the same mesh edge with
    the same UV at both ends (within UV_TOLERANCE)."""
    lo, hi, ulo, uhi, _ = edges
    same = (lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1])
    same &= (np.abs(ulo[1:] - ulo[:-1]) <= UV_TOLERANCE).all(axis=1)
    same &= (np.abs(uhi[1:] - uhi[:-1]) <= UV_TOLERANCE).all(axis=1)
    return np.flatnonzero(same)


def _vertex_ids(uv, positions):
    """Mesh vertex per triangle corner (T, 3): equal positions are one vertex (UVs without positions:
    equal UV points)."""
    t = len(uv)
    pts = positions.reshape(-1, 3) if positions is not None else uv.reshape(-1, 2)
    return _corner_ids(np.asarray(pts, np.float64)).reshape(t, 3)


def island_labels(uv, positions=None):
    """Island index per triangle (T,) for UV triangles (T, 3, 2): triangles sharing a mesh edge
    (positions (T, 3, 3) decide which corners are one vertex) with the same UV at both of its ends
    are in one island."""
    uv = np.asarray(uv, np.float64).reshape(-1, 3, 2)
    t = len(uv)
    if t == 0:
        return np.zeros(0, np.int64)
    edges = _edges(uv, _vertex_ids(uv, positions))
    tri = edges[4]
    same = _glued(edges)
    parent = np.arange(t)

    def find(x):
        while True:
            p = parent[x]
            if np.array_equal(p, x):
                return x
            parent[x] = parent[p]
            x = parent[x]

    # Union-find over the glued edges, vectorised: link roots until every pair shares one.
    ea, eb = tri[same], tri[same + 1]
    while len(ea):
        ra, rb = find(ea), find(eb)
        diff = ra != rb
        if not diff.any():
            break
        ra, rb = ra[diff], rb[diff]
        np.minimum.at(parent, np.maximum(ra, rb), np.minimum(ra, rb))
        ea, eb = ea[diff], eb[diff]
    roots = find(np.arange(t))
    _, labels = np.unique(roots, return_inverse=True)
    return labels


def _clip(poly, count, axis, value, keep_above):
    """Clip convex polygons (N, M, 2) with `count` vertices against x[axis] >= value
    (keep_above) or <= value. Returns the new (N, M', 2) array and counts."""
    n, m = poly.shape[0], poly.shape[1]
    idx = np.arange(m)
    valid = idx[None, :] < count[:, None]
    nxt = np.where(idx[None, :] + 1 < count[:, None], idx[None, :] + 1, 0)
    p = poly
    q = np.take_along_axis(poly, nxt[:, :, None], axis=1)
    value = np.broadcast_to(np.asarray(value, np.float64), (n,))[:, None]
    dp = p[:, :, axis] - value
    dq = q[:, :, axis] - value
    if not keep_above:
        dp, dq = -dp, -dq
    inside_p = dp >= 0
    inside_q = dq >= 0
    cross = valid & (inside_p != inside_q)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cross, dp / (dp - dq), 0.0)
    inter = p + t[:, :, None] * (q - p)
    out = np.empty((n, 2 * m, 2))
    out[:, 0::2] = p
    out[:, 1::2] = inter
    mask = np.empty((n, 2 * m), bool)
    mask[:, 0::2] = valid & inside_p
    mask[:, 1::2] = cross
    order = np.argsort(~mask, axis=1, kind="stable")
    out = np.take_along_axis(out, order[:, :, None], axis=1)
    new_count = mask.sum(axis=1)
    width = max(int(new_count.max()) if n else 0, 3)
    return out[:, :width], new_count


def _polygon_areas(poly, count):
    m = poly.shape[1]
    idx = np.arange(m)
    valid = idx[None, :] < count[:, None]
    nxt = np.where(idx[None, :] + 1 < count[:, None], idx[None, :] + 1, 0)
    q = np.take_along_axis(poly, nxt[:, :, None], axis=1)
    c = poly[:, :, 0] * q[:, :, 1] - q[:, :, 0] * poly[:, :, 1]
    return 0.5 * np.abs(np.where(valid, c, 0.0).sum(axis=1))


def texel_coverage(uv, res, labels=None, overlapping=None):
    """Exact covered area per texel (res, res) of UV triangles (T, 3, 2) on a res x res map (rows
    bottom first, like the engine), and with labels the number of distinct labels touching each
    texel with more than _MIN_COVER of its area. With `overlapping` (a bool array (T,)), the
    triangles that cover part of an overlapping texel are flagged in it."""
    tri = np.asarray(uv, np.float64).reshape(-1, 3, 2) * res
    cover = np.zeros(res * res)
    touching = np.zeros(res * res, np.int64) if labels is not None else None
    if len(tri) == 0 or res <= 0:
        return cover.reshape(res, res), (touching.reshape(res, res) if touching is not None else None)
    lo = np.clip(np.floor(tri.min(axis=1)), 0, res - 1).astype(np.int64)
    hi = np.clip(np.floor(tri.max(axis=1)), 0, res - 1).astype(np.int64)
    # Triangles entirely outside the square cover nothing.
    outside = (tri.max(axis=1) < 0).any(axis=1) | (tri.min(axis=1) > res).any(axis=1)
    nx = np.where(outside, 0, hi[:, 0] - lo[:, 0] + 1)
    ny = np.where(outside, 0, hi[:, 1] - lo[:, 1] + 1)
    per = nx * ny
    pair_tri = np.repeat(np.arange(len(tri)), per)
    start = np.concatenate([[0], np.cumsum(per)[:-1]])
    local = np.arange(int(per.sum())) - np.repeat(start, per)
    px = lo[pair_tri, 0] + local % np.repeat(nx, per)
    py = lo[pair_tri, 1] + local // np.repeat(nx, per)
    pieces_texel, pieces_area, pieces_label, pieces_tri = [], [], [], []
    # A texel whose four corners lie inside the triangle is covered completely; only the others
    # are clipped.
    e0, e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 1], tri[:, 0] - tri[:, 2]
    orient = np.sign(e0[:, 0] * (-e2[:, 1]) - e0[:, 1] * (-e2[:, 0]))
    for s in range(0, len(pair_tri), _CHUNK):
        tt, xx, yy = pair_tri[s:s + _CHUNK], px[s:s + _CHUNK], py[s:s + _CHUNK]
        full = np.ones(len(tt), bool)
        empty = np.zeros(len(tt), bool)
        for start, edge in ((0, e0), (1, e1), (2, e2)):
            v = tri[tt, start]
            beyond = np.ones(len(tt), bool)  # all four corners outside this edge
            for cx, cy in ((0, 0), (1, 0), (0, 1), (1, 1)):
                side = (edge[tt, 0] * (yy + cy - v[:, 1]) - edge[tt, 1] * (xx + cx - v[:, 0])) * orient[tt]
                full &= side > 0
                beyond &= side < 0
            empty |= beyond
        area = np.where(full, 1.0, 0.0)
        part = np.flatnonzero(~full & ~empty)
        poly = tri[tt[part]].copy()
        count = np.full(len(part), 3)
        poly, count = _clip(poly, count, 0, xx[part].astype(np.float64), True)
        poly, count = _clip(poly, count, 0, xx[part] + 1.0, False)
        poly, count = _clip(poly, count, 1, yy[part].astype(np.float64), True)
        poly, count = _clip(poly, count, 1, yy[part] + 1.0, False)
        area[part] = _polygon_areas(poly, count)
        texel = yy * res + xx
        keep = area > 0
        pieces_texel.append(texel[keep])
        pieces_area.append(area[keep])
        pieces_tri.append(tt[keep])
        if labels is not None:
            pieces_label.append(labels[tt[keep]])
    texel = np.concatenate(pieces_texel)
    area = np.concatenate(pieces_area)
    cover += np.bincount(texel, weights=area, minlength=res * res)
    if overlapping is not None:
        tris = np.concatenate(pieces_tri)
        overlapping[tris[cover[texel] > _OVERLAP]] = True
    if labels is not None:
        lab = np.concatenate(pieces_label)
        key = texel * (int(labels.max()) + 1) + lab
        per_key = np.bincount(np.unique(key, return_inverse=True)[1], weights=area)
        uniq = np.unique(key)
        big = uniq[per_key > _MIN_COVER]
        touching += np.bincount(big // (int(labels.max()) + 1), minlength=res * res)
    return cover.reshape(res, res), (touching.reshape(res, res) if touching is not None else None)


def _boundary_segments(uv, labels, positions=None):
    """UV edges not glued to another triangle of their island: (S, 2, 2) and their island labels."""
    edges = _edges(uv, _vertex_ids(uv, positions))
    lo, hi, ulo, uhi, tri = edges
    glued = np.zeros(len(lo), bool)
    same = _glued(edges)
    same = same[labels[tri[same]] == labels[tri[same + 1]]]
    glued[same] = True
    glued[same + 1] = True
    return np.stack([ulo[~glued], uhi[~glued]], axis=1).astype(np.float64), labels[tri[~glued]]


def _segment_distances(p0, p1, q0, q1):
    """Distances between 2D segments p0-p1 and q0-q1 (arrays (N, 2))."""
    def point_seg(p, a, b):
        ab = b - a
        denom = np.maximum((ab * ab).sum(axis=1), 1e-300)
        t = np.clip(((p - a) * ab).sum(axis=1) / denom, 0.0, 1.0)
        d = p - (a + t[:, None] * ab)
        return np.sqrt((d * d).sum(axis=1))

    def orient(a, b, c):
        return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])

    d = np.minimum(np.minimum(point_seg(p0, q0, q1), point_seg(p1, q0, q1)),
                   np.minimum(point_seg(q0, p0, p1), point_seg(q1, p0, p1)))
    o1, o2 = orient(p0, p1, q0), orient(p0, p1, q1)
    o3, o4 = orient(q0, q1, p0), orient(q0, q1, p1)
    crossing = (o1 * o2 < 0) & (o3 * o4 < 0)
    return np.where(crossing, 0.0, d)


def island_margin(uv, labels, res, positions=None, cap=MARGIN_CAP):
    """Smallest distance in texels between the boundaries of two different islands (cap if none
    are closer than cap)."""
    if len(uv) == 0 or int(labels.max()) == 0:
        return float(cap)
    seg, lab = _boundary_segments(np.asarray(uv, np.float64), labels, positions)
    if len(seg) == 0:
        return float(cap)
    seg = seg * res
    # Split segments longer than cap/2 so that each lies within cap/4 of its midpoint.
    length = np.sqrt(((seg[:, 1] - seg[:, 0]) ** 2).sum(axis=1))
    parts = np.maximum(1, np.ceil(length / (0.5 * cap))).astype(np.int64)
    rep = np.repeat(np.arange(len(seg)), parts)
    k = np.arange(len(rep)) - np.repeat(np.concatenate([[0], np.cumsum(parts)[:-1]]), parts)
    f0 = (k / parts[rep])[:, None]
    f1 = ((k + 1) / parts[rep])[:, None]
    a = seg[rep, 0] + f0 * (seg[rep, 1] - seg[rep, 0])
    b = seg[rep, 0] + f1 * (seg[rep, 1] - seg[rep, 0])
    lab = lab[rep]
    # Segments within cap of each other have midpoints within 1.25 cap: cells of size cap,
    # neighbours up to two cells away.
    mid = 0.5 * (a + b)
    half = 0.5 * np.sqrt(((b - a) ** 2).sum(axis=1))
    cell = np.floor(mid / cap).astype(np.int64)
    cell -= cell.min(axis=0) - 2
    span = int(cell[:, 0].max()) + 3
    cid = cell[:, 1] * span + cell[:, 0]
    order = np.argsort(cid, kind="stable")
    sorted_cid = cid[order]
    best = float(cap)
    offsets = sorted(((y, x) for y in range(-2, 3) for x in range(-2, 3)), key=lambda o: abs(o[0]) + abs(o[1]))
    for dy, dx in offsets:
        target = cid + dy * span + dx
        first = np.searchsorted(sorted_cid, target, "left")
        last = np.searchsorted(sorted_cid, target, "right")
        cnt = last - first
        if not cnt.any():
            continue
        i = np.repeat(np.arange(len(cid)), cnt)
        j = order[np.repeat(first, cnt) + (np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt))]
        keep = (lab[i] != lab[j]) & (i < j)
        i, j = i[keep], j[keep]
        # A lower bound from the midpoints: most pairs are too far apart to matter.
        gap = np.sqrt(((mid[i] - mid[j]) ** 2).sum(axis=1)) - half[i] - half[j]
        keep = gap < best
        i, j = i[keep], j[keep]
        for s in range(0, len(i), _CHUNK):
            d = _segment_distances(a[i[s:s + _CHUNK]], b[i[s:s + _CHUNK]], a[j[s:s + _CHUNK]], b[j[s:s + _CHUNK]])
            if len(d):
                best = min(best, float(d.min()))
    return best


def analyse(uv, res, positions=None):
    """Measure a layout: uv (T, 3, 2) lightmap UV per triangle corner, res the lightmap's size,
    positions (T, 3, 3) the triangles in space (to skip degenerate ones). Returns a dict (see the
    module doc)."""
    uv = np.asarray(uv, np.float64).reshape(-1, 3, 2)
    t = len(uv)
    if positions is not None:
        positions = p = np.asarray(positions, np.float64).reshape(-1, 3, 3)
        world = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        solid = world > 0
    else:
        solid = np.ones(t, bool)
    finite = (np.abs(uv) < 1e3).all(axis=(1, 2))  # False for NaN and runaway values
    uv = np.where(finite[:, None, None], uv, 0.0)  # such triangles count as zero area and outside
    signed = _signed_areas(uv) * (res * res)
    zero = solid & ~(np.abs(signed) > 0)
    outside = ((uv < 0) | (uv > 1)).any(axis=(1, 2)) | ~finite
    labels = island_labels(uv, positions)
    n_islands = int(labels.max()) + 1 if t else 0
    # Folds: triangles wound against their island's (area-weighted) majority.
    flipped = 0
    if t:
        majority = np.bincount(labels, weights=signed, minlength=n_islands)
        flipped = int((solid & ~zero & (np.sign(signed) != np.sign(majority[labels]))).sum())
    cover, touching = texel_coverage(uv, res, labels)
    overlap = int((cover > _OVERLAP).sum())
    shared = int((touching > 1).sum())
    margin = island_margin(uv, labels, res, positions) if n_islands > 1 else MARGIN_CAP
    if ((cover > _OVERLAP) & (touching > 1)).any():
        margin = 0.0  # islands lie on top of each other
    return dict(triangles=t, zero_area=int(zero.sum()), outside=int(outside.sum()), overlap_texels=overlap,
                shared_texels=shared, flipped=flipped, margin=float(margin),
                utilisation=float(np.minimum(cover, 1.0).sum() / (res * res)),
                used_texels=float((cover >= _MIN_COVER).mean()), islands=n_islands)


def _signed_areas(uv):
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def bad_triangles(uv, res, positions=None, quads=False):
    """Triangles (T,) bool that keep a layout from baking cleanly: zero UV area, outside the
    square, folded against their island, or covering part of an overlapping texel. quads=True
    reads consecutive triangle pairs as quads split 0-1-2 / 0-2-3 (the engine's refined
    subdivision meshes) and also flags both triangles of a quad that is concave in UV, whose
    other split (1-2-3 / 1-3-0, which Blender may choose) would fold."""
    uv = np.asarray(uv, np.float64).reshape(-1, 3, 2)
    t = len(uv)
    finite = (np.abs(uv) < 1e3).all(axis=(1, 2))
    uv = np.where(finite[:, None, None], uv, 0.0)
    signed = _signed_areas(uv)
    solid = np.ones(t, bool)
    if positions is not None:
        p = np.asarray(positions, np.float64).reshape(-1, 3, 3)
        solid = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1) > 0
    labels = island_labels(uv, positions)
    majority = np.sign(np.bincount(labels, weights=signed))[labels] if t else np.zeros(0)
    bad = solid & ~(np.abs(signed) > 0)
    bad |= ((uv < 0) | (uv > 1)).any(axis=(1, 2)) | ~finite
    bad |= solid & (np.sign(signed) != majority)
    if quads and t % 2 == 0 and t:
        a, b = uv[0::2], uv[1::2]
        corners = np.stack([a[:, 0], a[:, 1], a[:, 2], b[:, 2]], axis=1)
        alt1 = _signed_areas(corners[:, [1, 2, 3]])
        alt2 = _signed_areas(corners[:, [1, 3, 0]])
        want = majority[0::2]
        concave = (np.sign(alt1) != want) | (np.sign(alt2) != want)
        bad |= np.repeat(concave, 2) & solid
    overlapping = np.zeros(t, bool)
    texel_coverage(uv, res, overlapping=overlapping)
    return bad | (overlapping & solid)


def clean(stats, min_margin=2.0):
    """True when a layout bakes cleanly: nothing lost, nothing shared, margins kept."""
    return (stats["zero_area"] == 0 and stats["outside"] == 0 and stats["overlap_texels"] == 0
            and stats["shared_texels"] == 0 and stats["flipped"] == 0 and stats["margin"] >= min_margin
            and not stats.get("concave_quads", 0))


def describe(stats):
    """One line for reports and logs."""
    text = ("%d islands, margin %.1f texels, %.0f %% of the map used, %d overlapping texels, %d shared texels, "
            "%d zero-area and %d outside triangles, %d folded"
            % (stats["islands"], stats["margin"], 100 * stats["utilisation"], stats["overlap_texels"],
               stats["shared_texels"], stats["zero_area"], stats["outside"], stats["flipped"]))
    if stats.get("concave_quads"):
        text += ", concave quads after subdivision"
    return text
