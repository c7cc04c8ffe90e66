"""The jump across a UV seam: a smooth UV sphere (32 x 16, one island whose left and right edges
meet at the seam, smooth normals) under a sun and a sky, baked through the Python bridge; the
lightmap is read bilinearly at 400 points along the seam from both sides, and the RMS of the
difference is reported relative to the mean.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so /usr/bin/python3 docs/measure_seams.py python_bridge 300000
"""
import sys

import numpy as np

sys.path.insert(0, sys.argv[1])
import photonlm  # noqa: E402
def sphere(nu=32, nv=16):
    # vertices per (i, j) with i in 0..nu (seam duplicated in UV only: positions shared by index)
    pos, idx, uv, nrm = [], [], [], []
    P = lambda i, j: (np.cos(2*np.pi*i/nu)*np.sin(np.pi*j/nv), np.sin(2*np.pi*i/nu)*np.sin(np.pi*j/nv), np.cos(np.pi*j/nv))
    vid = {}
    def v(i, j):
        key = (i % nu if 0 < j < nv else 0, j)
        if key not in vid: vid[key] = len(pos); pos.append(P(*key))
        return vid[key]
    for j in range(nv):
        for i in range(nu):
            for tri in (((i, j), (i+1, j+1), (i+1, j)), ((i, j), (i, j+1), (i+1, j+1))):
                if (tri[0][1] == 0 and tri[1][1] == 0) or (tri[2][1] == nv and tri[1][1] == nv): pass
                idx.append([v(*c) for c in tri])
                uv.append([[0.02 + 0.96*c[0]/nu, 0.02 + 0.96*c[1]/nv] for c in tri])
                nrm.append([P(*c) for c in tri])
    return np.array(pos, np.float32), np.array(idx), np.array(uv, np.float32), np.array(nrm, np.float32)
pos, idx, uv, nrm = sphere()
s = photonlm.Scene()
s.add_material((0.8, 0.8, 0.8))
m = s.add_mesh("sphere", pos, idx, lightmap_uv=uv, resolution=64)
s.set_mesh_normals(m, nrm)
sun = np.eye(4); a = 0.7; sun[:3, :3] = [[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]]
s.add_light("SUN", power=3.0, matrix=sun)
s.set_world((0.2, 0.25, 0.3))
r = s.bake(photons=int(sys.argv[2]), seed=1, direct_samples=16)
lm = r.lightmap(m); L = lm.rgb.mean(axis=2); h, w = L.shape
def look(u, v):
    x, y = u*w - 0.5, v*h - 0.5; x0, y0 = np.floor(x), np.floor(y); fx, fy = x-x0, y-y0
    c = lambda a, n: np.clip(a, 0, n-1).astype(int)
    X0, X1, Y0, Y1 = c(x0, w), c(x0+1, w), c(y0, h), c(y0+1, h)
    return (1-fx)*(1-fy)*L[Y0, X0] + fx*(1-fy)*L[Y0, X1] + (1-fx)*fy*L[Y1, X0] + fx*fy*L[Y1, X1]
# the seam: u = 0.02 (i = 0) and u = 0.98 (i = nu) for v in the interior
t = np.linspace(0.02 + 0.96/16, 0.98 - 0.96/16, 400)
a, b = look(np.full_like(t, 0.02), t), look(np.full_like(t, 0.98), t)
jump = np.sqrt(np.mean((a - b)**2)) / np.mean(0.5*(a + b))
print("seam jump %.4f  error estimate %.4f" % (jump, r.stats["error_estimate"]))
