"""Axisymmetric shells: a meridian r(s) e_r + z(s) e_z (MODEL.md section 7,
paper section 6).

Local coordinates (phi, s) at phi = 0 (by symmetry every azimuth is alike):

    r_phi = (0, r, 0)      r_s = (r', 0, z')
    r_phiphi = (-r, 0, 0)  r_phis = (0, r', 0)  r_ss = (r'', 0, z'')

so the normal r_phi x r_s points outward for a meridian running upward on
the right half plane.  Growth and loads are given in the (e_r, e_phi, e_z)
components at phi = 0; their azimuthal derivatives follow from the rotation of
that frame.  Poles (r = 0 at a node) get the regularity conditions r = 0,
z' = 0 automatically.
"""

import numpy as np

from .line import LineShell


class AxisymmetricShell(LineShell):
    """Shell of revolution about the z axis; curve(s) -> (r, z, r', z')."""

    azimuthal = True
    weight_factor = 2 * np.pi
    _s_direction = 1            # s is the second local coordinate

    def __init__(self, s, curve, thickness, material, level="consistent"):
        super().__init__(s, curve, thickness, material, level, closed=False)
        scale = max(np.ptp(self.ref_nodes[:, 0]), np.ptp(self.ref_nodes[:, 2]))
        self.poles = np.where(np.abs(self.ref_nodes[:, 0]) <= 1e-12 * scale)[0]
        for i in self.poles:
            self._fix(i, [0, 3])          # r = 0, z' = 0: smooth through the axis

    def _rigid_modes(self, U):
        """The one rigid motion of a shell of revolution: translation along z."""
        B = np.zeros((len(U), 4, 1))
        B[:, 2, 0] = 1.0
        return B.reshape(-1, 1)

    def _kinematics(self, kin):
        K = np.zeros((15, 6))
        c = np.zeros(15)
        a, da, dda, b, db, ddb = range(6)
        K[1, a] = 1.0            # r_phi = (0, r, 0)
        K[3, da] = 1.0           # r_s = (r', 0, z')
        K[5, db] = 1.0
        K[6, a] = -1.0           # r_phiphi = (-r, 0, 0)
        K[10, da] = 1.0          # r_phis = (0, r', 0)
        K[12, dda] = 1.0         # r_ss = (r'', 0, z'')
        K[14, ddb] = 1.0
        return K, c

    def _edge_length(self, i):
        return 2 * np.pi * self.ref_nodes[i, 0]

    def _volume(self, U, mode):
        """V = pi int r^2 z' ds (exact for the Hermite fields with 5 Gauss points)."""
        xg, wg = np.polynomial.legendre.leggauss(5)
        xi, wg = 0.5 * (xg + 1), 0.5 * wg
        from .line import hermite
        V = 0.0
        ne = self.n_elements
        gV = np.zeros(4 * self.n_nodes)
        HV = np.zeros((len(self.sq), 8, 8))
        for e in range(ne):
            ell = self.s[e + 1] - self.s[e]
            d = self.elem_dofs[e]
            ue = U[d]
            for k, x in enumerate(xi):
                H, dH, _ = hermite(x, ell)
                pa = np.zeros(8)
                pdb = np.zeros(8)
                pa[[0, 1, 4, 5]] = H
                pdb[[2, 3, 6, 7]] = dH
                r, dz = pa @ ue, pdb @ ue
                w = np.pi * wg[k] * ell
                V += w * r * r * dz
                if mode >= 1:
                    np.add.at(gV, d, w * (2 * r * dz * pa + r * r * pdb))
                if mode >= 2:
                    q = e * 5 + k                # same 5-point rule as the energy
                    HV[q] = w * (2 * dz * np.outer(pa, pa) + 2 * r * (np.outer(pa, pdb) + np.outer(pdb, pa)))
        return V, gV, HV

    # -------------------------------------------------------------- builders
    @classmethod
    def sphere(cls, n, radius, thickness, material, level="consistent", s_range=(0.0, np.pi)):
        """Sphere (or a zone of it) of the paper's section 6: r = R sin s,
        z = R (1 - cos s), s from the south pole (0) to the north pole (pi)."""
        s = np.linspace(*s_range, n + 1)
        curve = lambda s: (radius * np.sin(s), radius * (1 - np.cos(s)),
                           radius * np.cos(s), radius * np.sin(s))
        return cls(s, curve, thickness, material, level)

    @classmethod
    def cylinder(cls, n, radius, length, thickness, material, level="consistent"):
        """Cylinder r = R, z = s in [0, length]."""
        s = np.linspace(0.0, length, n + 1)
        curve = lambda s: (np.full_like(s, radius), s, np.zeros_like(s), np.ones_like(s))
        return cls(s, curve, thickness, material, level)
