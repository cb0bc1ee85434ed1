"""shellritz: equilibrium shapes of thin growing hyperelastic shells."""

from .materials import (CubicStretch, InvariantLaw, LinearIsotropic, NeoHookean,
                        PowerLawHardening, StVenantKirchhoff, invariant_law_from_sympy)
from .mesh import Mesh, MeshError
from .model import ShellError
from .shell import Result, Shell
from .solve import EvaluationError, SolveError

__all__ = ["NeoHookean", "CubicStretch", "StVenantKirchhoff", "LinearIsotropic", "PowerLawHardening",
           "InvariantLaw", "invariant_law_from_sympy", "Mesh", "MeshError", "Shell",
           "Result", "ShellError", "SolveError", "EvaluationError"]
