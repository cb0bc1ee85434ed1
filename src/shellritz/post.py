"""Output fields of a solved shell and mesh writing (meshio).

Per triangle (averaged over its quadrature points, at the middle surface
Z = 0): principal stretches of the middle surface (two in-plane, from the
metric r_a . r_b against R_a . R_b, and the normal stretch |y1|), the first
Piola-Kirchhoff stress P = dWbar/dF at F0 = grad r + y1 (x) n (per unit
reference area, MODEL.md section 4) and the Cauchy stress
sigma = P F0^T / det F0.  Per node: displacement, the unit director
y1/|y1| and the thickness stretch |y1| (area-weighted averages).
"""

import numpy as np
from numba import njit

from .discretize.dkt import apply_map, element_chart, point_map
from .kernels.material import M_AA, V_P, mat_prepare, new_state
from .kernels.point import _reference_geometry


@njit(cache=True)
def _fields(kind, psi, params, tri, X, T, U, bary, wts, Y1, G0n, stretch, P_out, S_out, area_out):
    mv, mm, mp = new_state()
    Xe = np.zeros((3, 3))
    Te = np.zeros((3, 3, 2))
    Q, gl, et, el = np.zeros((3, 2, 2)), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3)
    b, C = np.zeros((5, 9)), np.zeros((2, 9))
    bref, bcur, ref, v = np.zeros((9, 3)), np.zeros((9, 3)), np.zeros(15), np.zeros(15)
    E, Lam, dg, na, kap, gup = (np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)),
                                np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((2, 3)))
    F = np.zeros((3, 3))
    G = np.zeros((3, 3))
    for e in range(tri.shape[0]):
        for i in range(3):
            nd = tri[e, i]
            for c in range(3):
                Xe[i, c] = X[nd, c]
                Te[i, c, 0] = T[nd, c, 0]
                Te[i, c, 1] = T[nd, c, 1]
                bref[3 * i, c] = X[nd, c]
                bref[3 * i + 1, c] = T[nd, c, 0]
                bref[3 * i + 2, c] = T[nd, c, 1]
                for s in range(3):
                    bcur[3 * i + s, c] = U[nd, s, c]
        area = element_chart(Xe, Te, Q, gl, et, el)
        area_out[e] = area
        wsum = 0.0
        for iq in range(bary.shape[0]):
            lam = bary[iq]
            point_map(lam, Q, gl, et, el, b, C)
            apply_map(b, bref, ref)
            apply_map(b, bcur, v)
            _reference_geometry(ref, E, Lam, dg, na, kap, gup)
            n = E[:, 2]
            # F0 = r_a (x) g^a + y1 (x) n (global components)
            for i in range(3):
                for j in range(3):
                    F[i, j] = v[i] * gup[0, j] + v[3 + i] * gup[1, j] + Y1[e, iq, i] * n[j]
                    G[i, j] = (lam[0] * G0n[tri[e, 0], i, j] + lam[1] * G0n[tri[e, 1], i, j]
                               + lam[2] * G0n[tri[e, 2], i, j])
            Gi = np.linalg.inv(G)
            gdet = np.linalg.det(G)
            A = F @ Gi
            mat_prepare(kind, psi, params, A, mv, mm, mp)
            PA = mv[V_P].reshape(3, 3)
            P = gdet * PA @ Gi.T
            sig = P @ F.T / np.linalg.det(F)
            # in-plane stretches: eigenvalues of M_ref^-1 M_cur
            m00 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
            m01 = v[0] * v[3] + v[1] * v[4] + v[2] * v[5]
            m11 = v[3] * v[3] + v[4] * v[4] + v[5] * v[5]
            r00 = ref[0] * ref[0] + ref[1] * ref[1] + ref[2] * ref[2]
            r01 = ref[0] * ref[3] + ref[1] * ref[4] + ref[2] * ref[5]
            r11 = ref[3] * ref[3] + ref[4] * ref[4] + ref[5] * ref[5]
            dr = r00 * r11 - r01 * r01
            a00 = (r11 * m00 - r01 * m01) / dr
            a01 = (r11 * m01 - r01 * m11) / dr
            a10 = (-r01 * m00 + r00 * m01) / dr
            a11 = (-r01 * m01 + r00 * m11) / dr
            tr = a00 + a11
            dt = a00 * a11 - a01 * a10
            disc = np.sqrt(max(tr * tr / 4 - dt, 0.0))
            w = wts[iq]
            wsum += w
            stretch[e, 0] += w * np.sqrt(tr / 2 + disc)
            stretch[e, 1] += w * np.sqrt(max(tr / 2 - disc, 0.0))
            stretch[e, 2] += w * np.sqrt(Y1[e, iq, 0] ** 2 + Y1[e, iq, 1] ** 2 + Y1[e, iq, 2] ** 2)
            for i in range(3):
                for j in range(3):
                    P_out[e, i, j] += w * P[i, j]
                    S_out[e, i, j] += w * sig[i, j]
        for k in range(3):
            stretch[e, k] /= wsum
        for i in range(3):
            for j in range(3):
                P_out[e, i, j] /= wsum
                S_out[e, i, j] /= wsum


def fields(result):
    s = result.shell
    ne = s.mesh.n_triangles
    stretch = np.zeros((ne, 3))
    P = np.zeros((ne, 3, 3))
    S = np.zeros((ne, 3, 3))
    area = np.zeros(ne)
    G0, _ = s.growth_at(result.t if result.t is not None else 0.0)
    _fields(s.law.kind, s.law.psi, s.law.params, s.mesh.triangles, s.X, s.frames,
            np.ascontiguousarray(s.U), s.bary, s.wts, result.y1, np.ascontiguousarray(G0),
            stretch, P, S, area)
    # nodal director: area-weighted average of the element means
    y1e = result.y1.mean(axis=1)
    nodal = np.zeros((s.mesh.n_nodes, 3))
    wsum = np.zeros(s.mesh.n_nodes)
    for k in range(3):
        np.add.at(nodal, s.mesh.triangles[:, k], area[:, None] * y1e)
        np.add.at(wsum, s.mesh.triangles[:, k], area)
    nodal /= wsum[:, None]
    return {"stretch": stretch, "P": P, "cauchy": S, "director": nodal}


def write_result(result, path):
    import meshio
    f = fields(result)
    s = result.shell
    thick = np.linalg.norm(f["director"], axis=1)
    point_data = {"displacement": result.displacement,
                  "director": f["director"] / thick[:, None],
                  "thickness_stretch": thick}
    cell_data = {"principal_stretch": [f["stretch"]],
                 "first_piola_kirchhoff": [f["P"].reshape(-1, 9)],
                 "cauchy_stress": [f["cauchy"].reshape(-1, 9)]}
    mesh = meshio.Mesh(result.r, [("triangle", s.mesh.triangles)], point_data=point_data,
                       cell_data=cell_data)
    mesh.write(str(path))
