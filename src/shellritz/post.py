"""Output fields of a solved shell and the result files.

Fields, as the point kernel defines them (MODEL.md sections 3-4), at the
middle surface Z = 0:

per node (point data)
    ``displacement`` r - R; ``director`` y1 (eq:mm; the image of the unit
    normal, so a material fibre across the thickness) and
    ``thickness_stretch`` |y1|; ``G0``, ``G1`` the growth at the solved t
    (9 components, row-major, global).  At a node: the direction of the
    area-weighted mean of y1 over the quadrature points around it, with the
    mean of |y1| as its length.
per triangle (cell data, means over the quadrature points)
    ``principal_stretch`` (3, descending): the singular values of the
    deformation gradient F0 = grad r + y1 (x) n (total stretch, growth
    included: uniform growth G gives the stretches of G), and
    ``principal_direction_1..3`` the corresponding directions in the current
    configuration (left singular vectors, sign fixed so that the largest
    component is positive); ``first_piola_kirchhoff`` P = dWbar/dF at F0
    (per unit reference area, Wbar = det G W(F G^-1)); ``cauchy_stress``
    sigma = P F0^T / det F0; ``energy_density`` the element's energy L per
    unit reference area (with the load potentials of its face tractions).

On request (scene ``[output]``): the faces Z = +-h/2 of the deformed shell,
x = r +- (h/2) y1 + (h^2/12) y2 (eq:y, thickness average r), as two
surfaces, or the solid between them (wedge cells), and a PNG picture.
"""

import numpy as np
from numba import njit

from .discretize.dkt import apply_map, element_chart, gather_element, point_map
from .kernels.material import V_P, mat_prepare, new_state
from .kernels.point import _reference_geometry
from .kernels.small import det3, inv3, mm3


@njit(cache=True)
def _fields(kind, psi, params, tri, X, T, U, bary, wts, Y1, G0n, F_out, P_out, S_out, area_out):
    """Per triangle: the quadrature means of F0, P and sigma at Z = 0."""
    mv, mm, mp = new_state()
    Xe = np.zeros((3, 3))
    Te = np.zeros((3, 3, 2))
    Q, gl, et, el = np.zeros((3, 2, 2)), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3)
    b, C = np.zeros((5, 9)), np.zeros((2, 9))
    bref, bcur, ref, v = np.zeros((9, 3)), np.zeros((9, 3)), np.zeros(15), np.zeros(15)
    E, Lam, dg, na, kap, gup = (np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)),
                                np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((2, 3)))
    F, G, Gi, A, P, sig = (np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)),
                           np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)))
    for e in range(tri.shape[0]):
        gather_element(e, tri, X, T, U, Xe, Te, bref, bcur)
        area_out[e] = element_chart(Xe, Te, Q, gl, et, el)
        wsum = 0.0
        for iq in range(bary.shape[0]):
            lam = bary[iq]
            point_map(lam, Q, gl, et, el, b, C)
            apply_map(b, bref, ref)
            apply_map(b, bcur, v)
            _reference_geometry(ref, E, Lam, dg, na, kap, gup)
            n = E[:, 2]
            # F0 = r_a (x) g^a + y1 (x) n (global components); G at Z = 0 is G0
            for i in range(3):
                for j in range(3):
                    F[i, j] = v[i] * gup[0, j] + v[3 + i] * gup[1, j] + Y1[e, iq, i] * n[j]
                    G[i, j] = (lam[0] * G0n[tri[e, 0], i, j] + lam[1] * G0n[tri[e, 1], i, j]
                               + lam[2] * G0n[tri[e, 2], i, j])
            # A = F G^-1, P = det(G) dW/dA G^-T, sigma = P F^T / det(F)
            detG = inv3(G, Gi)
            mm3(F, Gi, A)
            mat_prepare(kind, psi, params, A, mv, mm, mp)
            PA = mv[V_P]
            for i in range(3):
                for j in range(3):
                    P[i, j] = detG * (PA[3 * i] * Gi[j, 0] + PA[3 * i + 1] * Gi[j, 1]
                                      + PA[3 * i + 2] * Gi[j, 2])
            detF = det3(F)
            for i in range(3):
                for j in range(3):
                    sig[i, j] = (P[i, 0] * F[j, 0] + P[i, 1] * F[j, 1] + P[i, 2] * F[j, 2]) / detF
            w = wts[iq]
            wsum += w
            for i in range(3):
                for j in range(3):
                    F_out[e, i, j] += w * F[i, j]
                    P_out[e, i, j] += w * P[i, j]
                    S_out[e, i, j] += w * sig[i, j]
        for i in range(3):
            for j in range(3):
                F_out[e, i, j] /= wsum
                P_out[e, i, j] /= wsum
                S_out[e, i, j] /= wsum


def _nodal(mesh, area, values):
    """Area-weighted nodal averages of per-element values (m, 3)."""
    out = np.zeros((mesh.n_nodes, 3))
    wsum = np.zeros(mesh.n_nodes)
    for k in range(3):
        np.add.at(out, mesh.triangles[:, k], area[:, None] * values)
        np.add.at(wsum, mesh.triangles[:, k], area)
    return out / wsum[:, None]


def _nodal_director(mesh, area, Y1):
    """Nodal director and thickness stretch from the quadrature values y1
    (m, nq, 3): the direction of the area-weighted mean of y1, and the mean
    of |y1| as its length (averaging the vectors alone would shorten them
    where the surface is curved)."""
    length = _nodal(mesh, area, np.repeat(np.linalg.norm(Y1, axis=2).mean(axis=1)[:, None], 3, axis=1))[:, 0]
    mean = _nodal(mesh, area, Y1.mean(axis=1))
    return mean * (length / np.linalg.norm(mean, axis=1))[:, None], length


def fields(result):
    """Point and cell fields of a result (module docstring), as dicts."""
    s = result.shell
    mesh = s.mesh
    ne = mesh.n_triangles
    t = result.t if result.t is not None else 0.0
    G0, G1 = s.growth_at(t)
    U = np.concatenate([result.r[:, None], result.derivatives], axis=1)
    F, P, S, area = np.zeros((ne, 3, 3)), np.zeros((ne, 3, 3)), np.zeros((ne, 3, 3)), np.zeros(ne)
    _fields(s.law.kind, s.law.psi, s.law.params, mesh.triangles, s.X, s.frames,
            np.ascontiguousarray(U), s.bary, s.wts, result.y1, np.ascontiguousarray(G0), F, P, S, area)
    Lu, stretch, _ = np.linalg.svd(F)
    # deterministic signs of the directions: largest component positive
    big = np.take_along_axis(Lu, np.argmax(np.abs(Lu), axis=1)[:, None, :], axis=1)
    Lu = Lu * np.sign(big)
    director, stretch_n = _nodal_director(mesh, area, result.y1)
    point = {"displacement": result.displacement, "director": director,
             "thickness_stretch": stretch_n,
             "G0": G0.reshape(-1, 9), "G1": G1.reshape(-1, 9)}
    cell = {"principal_stretch": stretch,
            "principal_direction_1": Lu[:, :, 0], "principal_direction_2": Lu[:, :, 1],
            "principal_direction_3": Lu[:, :, 2],
            "first_piola_kirchhoff": P.reshape(-1, 9), "cauchy_stress": S.reshape(-1, 9),
            "energy_density": _element_energies(s, U) / area}
    return point, cell


def _element_energies(shell, U):
    """Element energies at the state U (the shell's growth, loads and
    prescribed values at its current t: those of a result just computed)."""
    shell.evaluate(U.reshape(-1)[shell.free], 0)
    return shell._Le.copy()


def faces(result):
    """Nodal positions of the faces Z = -h/2 and Z = +h/2 (eq:y)."""
    s = result.shell
    area = s.mesh.areas
    y1, _ = _nodal_director(s.mesh, area, result.y1)
    y2 = _nodal(s.mesh, area, result.y2.mean(axis=1))
    h = s.h
    mid = result.r + (h * h / 12.0) * y2
    return mid - 0.5 * h * y1, mid + 0.5 * h * y1


def result_mesh(result, with_data=True):
    """The deformed middle surface as a meshio.Mesh with the fields."""
    import meshio
    tri = result.shell.mesh.triangles
    if not with_data:
        return meshio.Mesh(result.r, [("triangle", tri)])
    point, cell = fields(result)
    return meshio.Mesh(result.r, [("triangle", tri)], point_data=point,
                       cell_data={k: [v] for k, v in cell.items()})


def face_meshes(result):
    """(bottom, top) faces as meshio meshes (positions only)."""
    import meshio
    tri = result.shell.mesh.triangles
    bottom, top = faces(result)
    # the bottom face's outward normal is -n: reverse its triangles
    return (meshio.Mesh(bottom, [("triangle", tri[:, ::-1])]), meshio.Mesh(top, [("triangle", tri)]))


def solid_mesh(result):
    """The deformed shell as a solid: one wedge per triangle between the faces."""
    import meshio
    tri = result.shell.mesh.triangles
    n = result.shell.mesh.n_nodes
    bottom, top = faces(result)
    return meshio.Mesh(np.vstack([bottom, top]), [("wedge", np.hstack([tri, tri + n]))])


def write_result(result, path):
    """Write the deformed mesh with fields (any meshio format by extension;
    formats without data arrays get the geometry only)."""
    from .meshdata import FORMATS_WITH_DATA, file_format, write_mesh
    write_mesh(path, result_mesh(result, with_data=file_format(path) in FORMATS_WITH_DATA))


def picture(result, path, title=None):
    """A PNG of the deformed middle surface coloured by height (atomic)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .meshdata import atomic_path
    r = result.r
    fig = plt.figure(figsize=(7, 5.5))
    ax = fig.add_subplot(projection="3d")
    surf = ax.plot_trisurf(r[:, 0], r[:, 1], r[:, 2], triangles=result.shell.mesh.triangles,
                           cmap="viridis", linewidth=0.1, edgecolor=(0, 0, 0, 0.15), antialiased=True)
    fig.colorbar(surf, ax=ax, shrink=0.6, label="height z")
    span = np.ptp(r, axis=0).max() / 2
    c = 0.5 * (r.min(axis=0) + r.max(axis=0))
    ax.set_xlim(c[0] - span, c[0] + span)
    ax.set_ylim(c[1] - span, c[1] + span)
    ax.set_zlim(c[2] - span, c[2] + span)
    if title:
        ax.set_title(title)
    ax.view_init(elev=25, azim=-60)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
