"""shellritz: equilibrium shapes of thin growing hyperelastic shells."""

import os

# OpenMP threads (MKL's PARDISO) sleep when idle instead of spinning: spinning
# threads slow the assembly's threads that run next, and any other load of the
# machine, by factors of 2-8 (README "Threads").  Set
# OMP_WAIT_POLICY before importing shellritz to choose otherwise.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .materials import (CubicStretch, InvariantLaw, LinearIsotropic, NeoHookean,
                        PowerLawHardening, StVenantKirchhoff, invariant_law_from_sympy)
from .mesh import Mesh, MeshError
from .model import ShellError
from .shell import Result, Shell
from .solve import EvaluationError, SolveError, StabilityWarning
from .nested import coarsen, solve_nested

__all__ = ["NeoHookean", "CubicStretch", "StVenantKirchhoff", "LinearIsotropic", "PowerLawHardening",
           "InvariantLaw", "invariant_law_from_sympy", "Mesh", "MeshError", "Shell",
           "Result", "ShellError", "SolveError", "EvaluationError", "StabilityWarning", "coarsen", "solve_nested"]
