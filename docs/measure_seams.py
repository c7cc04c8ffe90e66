"""The jump across seams, baked through the Python bridge; each lightmap is read bilinearly at 400
points along the seam from both sides, and the RMS of the difference is reported relative to the
mean ("jump"), with the RMS of the two sides' mean against the truth where one is known.

- sphere: a smooth UV sphere (32 x 16, one island whose left and right edges meet at the seam,
  smooth normals) under a sun and a sky: the seam within one object.
- hemispheres: the same sphere as two objects, the northern and the southern half, each its own
  island (64 x 64): the seam between them is the equator. Truth: a lone convex sphere under a sun
  of irradiance E towards s and a uniform sky L has irradiance / pi = E max(0, n.s) / pi + L.
- plane: a 4 x 2 m plane as two objects (x < 0 and x > 0, 64 x 64 texels each) under a sun and a
  sky, the shadow of a black bar crossing the shared edge x = 0. Reference: the same plane as one
  object (128 x 64, the same texel size) baked alike, read at the same points.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so /usr/bin/python3 docs/measure_seams.py python_bridge 300000

With a third argument `tiles GAP` it bakes only a floor of 20 x 20 tiles as 400 objects (32 x 32
texels each), GAP metres apart (0: 760 shared edges), for the cost of stitching between objects:

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so perf record -o /tmp/perf.data /usr/bin/python3 \
        docs/measure_seams.py python_bridge 200000 tiles 0 && perf report -i /tmp/perf.data --sort symbol
"""
import sys
import time

import numpy as np

sys.path.insert(0, sys.argv[1])
import photonlm  # noqa: E402

PHOTONS = int(sys.argv[2])
SUN_E, SKY = 3.0, (0.2, 0.25, 0.3)


def sun_matrix(a):
    m = np.eye(4)
    m[:3, :3] = [[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]]
    return m


def P(i, j, nu, nv):
    return (np.cos(2*np.pi*i/nu)*np.sin(np.pi*j/nv), np.sin(2*np.pi*i/nu)*np.sin(np.pi*j/nv), np.cos(np.pi*j/nv))


def sphere_rows(j0, j1, nu=32, nv=16):
    """Rows j0..j1 of a UV sphere as one mesh; its island spans [0.02, 0.98] in u and v."""
    pos, idx, uv, nrm = [], [], [], []
    vid = {}

    def v(i, j):
        key = (i % nu if 0 < j < nv else 0, j)
        if key not in vid:
            vid[key] = len(pos)
            pos.append(P(*key, nu, nv))
        return vid[key]
    for j in range(j0, j1):
        for i in range(nu):
            for tri in (((i, j), (i+1, j+1), (i+1, j)), ((i, j), (i, j+1), (i+1, j+1))):
                idx.append([v(*c) for c in tri])
                uv.append([[0.02 + 0.96*c[0]/nu, 0.02 + 0.96*(c[1] - j0)/(j1 - j0)] for c in tri])
                nrm.append([P(*c, nu, nv) for c in tri])
    return np.array(pos, np.float32), np.array(idx), np.array(uv, np.float32), np.array(nrm, np.float32)


def look(L, u, v):
    h, w = L.shape
    x, y = u*w - 0.5, v*h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    c = lambda a, n: np.clip(a, 0, n-1).astype(int)  # noqa: E731
    X0, X1, Y0, Y1 = c(x0, w), c(x0+1, w), c(y0, h), c(y0+1, h)
    return (1-fx)*(1-fy)*L[Y0, X0] + fx*(1-fy)*L[Y0, X1] + (1-fx)*fy*L[Y1, X0] + fx*fy*L[Y1, X1]


def report(name, a, b, truth=None, r=None, label="truth"):
    mean = np.mean(0.5*(a + b))
    line = "%-12s jump %.4f" % (name, np.sqrt(np.mean((a - b)**2)) / mean)
    if truth is not None:
        line += "  vs %s %.4f" % (label, np.sqrt(np.mean((0.5*(a + b) - truth)**2)) / mean)
    if r is not None:
        line += "  error estimate %.4f" % r.stats["error_estimate"]
    print(line, flush=True)


def scene():
    s = photonlm.Scene()
    s.add_material((0.8, 0.8, 0.8))
    return s


def tiles(gap, n=20):
    s = scene()
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    q = [[0.02, 0.02], [0.98, 0.02], [0.98, 0.98], [0.02, 0.98]]
    uv = np.array([[q[a] for a in tr] for tr in quad], np.float32)
    for i in range(n):
        for j in range(n):
            x0, y0 = i*(1 + gap), j*(1 + gap)
            p = np.array([[x0, y0, 0], [x0 + 1, y0, 0], [x0 + 1, y0 + 1, 0], [x0, y0 + 1, 0]], np.float32)
            s.add_mesh("tile%d_%d" % (i, j), p, quad, lightmap_uv=uv, resolution=32)
    s.add_light("SUN", power=SUN_E, matrix=sun_matrix(0.5))
    s.set_world(SKY)
    start = time.time()
    s.bake(photons=PHOTONS, seed=1, direct_samples=4)
    print("tiles %g m apart: bake %.2f s" % (gap, time.time() - start))


if len(sys.argv) > 3 and sys.argv[3] == "tiles":
    tiles(float(sys.argv[4]))
    sys.exit(0)

# The seam within one object.
pos, idx, uv, nrm = sphere_rows(0, 16)
s = scene()
m = s.add_mesh("sphere", pos, idx, lightmap_uv=uv, resolution=64)
s.set_mesh_normals(m, nrm)
s.add_light("SUN", power=SUN_E, matrix=sun_matrix(0.7))
s.set_world(SKY)
r = s.bake(photons=PHOTONS, seed=1, direct_samples=16)
L = r.lightmap(m).rgb.mean(axis=2)
t = np.linspace(0.02 + 0.96/16, 0.98 - 0.96/16, 400)
report("sphere", look(L, np.full_like(t, 0.02), t), look(L, np.full_like(t, 0.98), t), r=r)

# Two hemispheres as two objects: the equator between them.
s = scene()
ids = []
for j0, j1 in ((0, 8), (8, 16)):
    pos, idx, uv, nrm = sphere_rows(j0, j1)
    ids.append(s.add_mesh("half%d" % j0, pos, idx, lightmap_uv=uv, resolution=64))
    s.set_mesh_normals(ids[-1], nrm)
s.add_light("SUN", power=SUN_E, matrix=sun_matrix(0.7))
s.set_world(SKY)
r = s.bake(photons=PHOTONS, seed=1, direct_samples=16)
north, south = (r.lightmap(i).rgb.mean(axis=2) for i in ids)
u = np.linspace(0.02 + 0.5*0.96/32, 0.98 - 0.5*0.96/32, 400)
phi = 2*np.pi*(u - 0.02)/0.96
sun_dir = sun_matrix(0.7)[:3, 2]  # towards the sun: the light's local +Z
truth = SUN_E*np.maximum(0.0, np.cos(phi)*sun_dir[0] + np.sin(phi)*sun_dir[1]) / np.pi + np.mean(SKY)
report("hemispheres", look(north, u, np.full_like(u, 0.98)), look(south, u, np.full_like(u, 0.02)), truth, r)

# A plane as two objects, a bar's shadow across the shared edge; against the plane as one object.
def plane_scene(split):
    s = scene()
    s.add_material((0.0, 0.0, 0.0))
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    out = []
    for x0, x1, res, u0, u1 in (((-2, 0, 64, 0.02, 0.98), (0, 2, 64, 0.02, 0.98)) if split
                                else ((-2, 2, (128, 64), 0.01, 0.99),)):
        p = np.array([[x0, -1, 0], [x1, -1, 0], [x1, 1, 0], [x0, 1, 0]], np.float32)
        q = [[u0, 0.02], [u1, 0.02], [u1, 0.98], [u0, 0.98]]
        out.append(s.add_mesh("plane%d" % x0, p, quad, lightmap_uv=np.array([[q[a] for a in tr] for tr in quad],
                                                                             np.float32), resolution=res))
    # A black bar 0.3 m wide along x, 0.5 m above the plane: its shadow crosses x = 0.
    lo, hi = np.array([-1.5, -0.15, 0.5]), np.array([1.5, 0.15, 0.6])
    c = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])], np.float32)
    faces = [[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4], [2, 6, 7], [2, 7, 3],
             [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]]
    s.add_mesh("bar", c, np.array(faces), material_ids=np.ones(12, np.int32))
    s.add_light("SUN", power=SUN_E, matrix=sun_matrix(0.4))
    s.set_world(SKY)
    return s, out


s, (left, right) = plane_scene(True)
r = s.bake(photons=PHOTONS, seed=1, direct_samples=16)
A, B = r.lightmap(left).rgb.mean(axis=2), r.lightmap(right).rgb.mean(axis=2)
v = np.linspace(0.03, 0.97, 400)
a, b = look(A, np.full_like(v, 0.98), v), look(B, np.full_like(v, 0.02), v)
s1, (whole,) = plane_scene(False)
r1 = s1.bake(photons=PHOTONS, seed=2, direct_samples=16)
reference = look(r1.lightmap(whole).rgb.mean(axis=2), np.full_like(v, 0.5), v)
report("plane", a, b, reference, r, "one object")
