"""Geometry and analytic helpers shared by the bridge tests (truth computed here, not by the engine)."""
import numpy as np

# Corner uvs of a quad's two triangles (0,1,2) and (0,2,3): c0 (0,0), c1 (1,0), c2 (1,1), c3 (0,1).
QUAD_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
QUAD_UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)


def plane(half=2.0, z=0.0):
    """Square x, y in [-half, half] at height z, normal +Z; u = (x + half) / 2 half, v likewise."""
    pos = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], np.float32)
    return pos, QUAD_TRIANGLES, QUAD_UV


def box_faces():
    """The 6 faces of the unit cube as quads (4, 3) ordered so that their normals point inward."""
    faces = []
    for axis in range(3):
        b, c = (axis + 1) % 3, (axis + 2) % 3
        for side in (0.0, 1.0):
            corners = np.zeros((4, 3), np.float32)
            corners[:, axis] = side
            for k, (pb, pc) in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]):
                corners[k, b], corners[k, c] = pb, pc
            n = np.cross(corners[1] - corners[0], corners[3] - corners[0])
            if np.dot(n, 0.5 - corners[0]) < 0:  # not facing the centre: reverse the winding
                corners = corners[[0, 3, 2, 1]]
            faces.append(corners)
    return faces


def translation(x, y, z):
    m = np.eye(4, dtype=np.float32)
    m[:3, 3] = (x, y, z)
    return m


def rotation_x(theta):
    c, s = np.cos(theta), np.sin(theta)
    m = np.eye(4, dtype=np.float32)
    m[1:3, 1:3] = [[c, -s], [s, c]]
    return m


def cycles_fold(x, y, cx, cy, quad):
    """Where Cycles 3.4 bakes the point (x, y) of a texel centred at (cx, cy) on the square
    quad = (x0, x1, y0, y1) split into QUAD_TRIANGLES: in the triangle that owns the centre (the
    second one on the diagonal), the point folded back into it by mirror repeat of the barycentric
    coordinates, u (corner 0) into [0, 1], then v (corner 1) into [0, 1 - u]."""
    qx0, qx1, qy0, qy1 = quad
    s, t = (x - qx0) / (qx1 - qx0), (y - qy0) / (qy1 - qy0)
    sc, tc = (cx - qx0) / (qx1 - qx0), (cy - qy0) / (qy1 - qy0)

    def mirror(a, rng):
        rng = np.maximum(rng, 1e-300)
        q = a / rng
        f = np.floor(q)
        r = q - f
        return np.where(f.astype(np.int64) & 1, 1.0 - r, r) * rng
    upper = tc >= sc                       # triangle (0, 2, 3): s = v, t = 1 - u
    u2 = mirror(1.0 - t, 1.0)
    v2 = mirror(s, 1.0 - u2)
    u1 = mirror(1.0 - s, 1.0)              # triangle (0, 1, 2): s = 1 - u, t = 1 - u - v
    v1 = mirror(s - t, 1.0 - u1)
    s2 = np.where(upper, v2, 1.0 - u1)
    t2 = np.where(upper, 1.0 - u2, 1.0 - u1 - v1)
    return qx0 + s2 * (qx1 - qx0), qy0 + t2 * (qy1 - qy0)


def texel_average(f, x0, x1, y0, y1, width, height, sub=8, window=1.0, fold_quad=None):
    """Average of f(x, y) over each texel of a (height, width) grid on [x0,x1] x [y0,y1], row 0 at y0;
    window < 1: over the texel's central window x window part only; fold_quad: the points are
    folded as Cycles folds them into the quad's triangle that owns the texel centre (cycles_fold)."""
    def coords(lo, hi, n):
        k = np.arange(n * sub)
        frac = 0.5 - window / 2 + window * ((k % sub) + 0.5) / sub
        return lo + (k // sub + frac) * (hi - lo) / n, lo + (k // sub + 0.5) * (hi - lo) / n
    (xs, cxs), (ys, cys) = coords(x0, x1, width), coords(y0, y1, height)
    X, Y = np.meshgrid(xs, ys)
    if fold_quad is not None:
        CX, CY = np.meshgrid(cxs, cys)
        X, Y = cycles_fold(X, Y, CX, CY, fold_quad)
    v = f(X, Y)
    return v.reshape(height, sub, width, sub).mean(axis=(1, 3))


def clip_area(poly, u0, u1, v0, v1):
    """Area of a convex polygon (n, 2) clipped to the box [u0,u1] x [v0,v1] (Sutherland-Hodgman)."""
    def clip(pts, inside, cross):
        out = []
        for i in range(len(pts)):
            p, q = pts[i], pts[(i + 1) % len(pts)]
            if inside(p):
                out.append(p)
            if inside(p) != inside(q):
                out.append(cross(p, q))
        return out

    def at(k, val):
        return lambda p, q: p + (q - p) * ((val - p[k]) / (q[k] - p[k]))

    pts = [np.asarray(p, float) for p in poly]
    for k, val, sign in ((0, u0, 1), (0, u1, -1), (1, v0, 1), (1, v1, -1)):
        pts = clip(pts, lambda p, k=k, val=val, sign=sign: sign * (p[k] - val) >= 0, at(k, val))
        if not pts:
            return 0.0
    x, y = np.array(pts).T
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
