"""shellritz: equilibrium shapes of thin growing hyperelastic shells."""

from .materials import (CubicStretch, InvariantLaw, LinearIsotropic, NeoHookean,
                        StVenantKirchhoff, invariant_law_from_sympy)

__all__ = ["NeoHookean", "CubicStretch", "StVenantKirchhoff", "LinearIsotropic",
           "InvariantLaw", "invariant_law_from_sympy"]
