"""Plane strain: strips and rings in cylindrical bending (MODEL.md section 7,
paper section 4.3).  The section curve x(s) e_x + z(s) e_z; the generator
direction e_y keeps a prescribed stretch (1 by default).

Local coordinates (s, Y):

    r_s = (x', 0, z')    r_Y = (0, stretch, 0)
    r_ss = (x'', 0, z'') r_sY = r_YY = 0

so the normal r_s x r_Y = (-z', 0, x') is +z for a strip along +x.  Energies
are per unit width (Y).
"""

import numpy as np

from .line import LineShell, hermite


class PlaneStrainShell(LineShell):
    """Section curve(s) -> (x, z, x', z'); closed=True for a ring."""

    azimuthal = False
    weight_factor = 1.0
    _s_direction = 0

    def __init__(self, s, curve, thickness, material, level="consistent", closed=False,
                 stretch=1.0):
        if not (np.isfinite(stretch) and stretch > 0):
            raise ValueError("the generator stretch must be positive")
        self.stretch = float(stretch)
        super().__init__(s, curve, thickness, material, level, closed=closed)

    def _rigid_modes(self, U):
        """Translations along x and z, rotation about y: (x, z) -> (z, -x)
        (slopes turn alike), in the nodal DOFs (x, x', z, z')."""
        B = np.zeros((len(U), 4, 3))
        B[:, 0, 0] = 1.0
        B[:, 2, 1] = 1.0
        B[:, [0, 1, 2, 3], 2] = np.c_[U[:, 2], U[:, 3], -U[:, 0], -U[:, 1]]
        return B.reshape(-1, 3)

    def _kinematics(self, kin):
        K = np.zeros((15, 6))
        c = np.zeros(15)
        a, da, dda, b, db, ddb = range(6)
        K[0, da] = 1.0           # r_s = (x', 0, z')
        K[2, db] = 1.0
        c[4] = self.stretch      # r_Y = (0, stretch, 0)
        K[6, dda] = 1.0          # r_ss = (x'', 0, z'')
        K[8, ddb] = 1.0
        return K, c

    def _volume(self, U, mode):
        """Area per unit width A = int x z' ds (closed curves or fixed ends)."""
        xg, wg = np.polynomial.legendre.leggauss(5)
        xi, wg = 0.5 * (xg + 1), 0.5 * wg
        A = 0.0
        gA = np.zeros(4 * self.n_nodes)
        HA = np.zeros((len(self.sq), 8, 8))
        for e in range(self.n_elements):
            ell = self.s[e + 1] - self.s[e]
            d = self.elem_dofs[e]
            ue = U[d]
            for k, x in enumerate(xi):
                H, dH, _ = hermite(x, ell)
                pa = np.zeros(8)
                pdb = np.zeros(8)
                pa[[0, 1, 4, 5]] = H
                pdb[[2, 3, 6, 7]] = dH
                w = wg[k] * ell
                A += w * (pa @ ue) * (pdb @ ue)
                if mode >= 1:
                    np.add.at(gA, d, w * ((pdb @ ue) * pa + (pa @ ue) * pdb))
                if mode >= 2:
                    HA[e * 5 + k] = w * (np.outer(pa, pdb) + np.outer(pdb, pa))
        return A, gA, HA

    # -------------------------------------------------------------- builders
    @classmethod
    def strip(cls, n, length, thickness, material, level="consistent", x0=0.0):
        """Straight strip x = s in [x0, x0 + length], z = 0."""
        s = np.linspace(x0, x0 + length, n + 1)
        curve = lambda s: (s.copy(), np.zeros_like(s), np.ones_like(s), np.zeros_like(s))
        return cls(s, curve, thickness, material, level)

    @classmethod
    def ring(cls, n, radius, thickness, material, level="consistent"):
        """Circular ring of radius R with outward normal (-z', 0, x'):
        x = R cos s, z = -R sin s."""
        s = np.linspace(0.0, 2 * np.pi, n + 1)
        curve = lambda s: (radius * np.cos(s), -radius * np.sin(s),
                           -radius * np.sin(s), -radius * np.cos(s))
        return cls(s, curve, thickness, material, level, closed=True)
