"""Regression tests of the stability map (bench/stability_map.py) at tiny
sizes: every configuration succeeds (the arc-length scenes with AMG by
falling back to the direct solver, said in the history).  Observed values (2-core AMD EPYC, 1 thread)
in the comments."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import stability_map as smap  # noqa: E402

TINY = {"thin panel": 4, "incompressible disc": 4, "grown strip": 8, "leaf": 3,
        "snapping cap": 10, "pulled cylinder": 4}
ARC = ("snapping cap", "pulled cylinder")
MUST_SUCCEED = [(s, c) for s in TINY for c in smap.CONFIGS]


@pytest.fixture(scope="module")
def rows():
    return {}


def _row(rows, scene, config):
    if (scene, config) not in rows:
        rows[scene, config] = smap.run_one(scene, config, TINY[scene])
    return rows[scene, config]


@pytest.mark.parametrize("scene,config", MUST_SUCCEED)
def test_configuration_succeeds(rows, scene, config):
    r = _row(rows, scene, config)
    assert r["converged"], r["error"]
    assert r["t_reached"] == 1.0 and r["newton_its"] > 0
    if scene in ARC and config.endswith("/amg"):
        # the path is followed with the factorization the arc length needs
        assert r["linear_used"] in ("amg->pardiso", "amg->superlu")
        assert any("arc length needs a factorization" in n for n in r["notes"])
    if config.endswith("/direct") or r["linear_used"].startswith("amg->"):
        # the inertia is known from the factorization: every scene ends stable
        assert r["stable"] is True and r["unstable_modes"] == 0
    elif r["linear_used"] == "amg":
        assert r["stable"] is None          # stability "auto" is off with AMG
    if scene in ARC:
        assert r["path_points"] > 5


@pytest.mark.parametrize("scene", ["thin panel", "incompressible disc", "grown strip", *ARC])
def test_configurations_reach_the_same_equilibrium(rows, scene):
    """Same energy from every configuration (observed: within 2e-12 for the
    thin panel, whose energy 1e-8 sits near round-off, 2e-15 for the
    others).  Not asserted for the leaf: at 4 rings line search + direct
    ends on another stable state, 0.27 % higher in energy."""
    E = np.array([_row(rows, scene, c)["energy"] for c in smap.CONFIGS])
    assert np.all(np.abs(E / E[0] - 1) < 1e-9)


REGGE = [(s, c) for s in TINY if s != "snapping cap" for c in smap.CONFIGS]


@pytest.mark.parametrize("scene,config", REGGE)
def test_configuration_succeeds_with_the_regge_metric(scene, config):
    """The triangle scenes with membrane="regge" (bench/stability_map.py
    --membrane regge): every configuration converges, the direct ones (and
    AMG falling back to them) to stable states."""
    r = smap.run_one(scene, config, TINY[scene], membrane="regge")
    assert r["membrane"] == "regge"
    assert r["converged"], r["error"]
    assert r["t_reached"] == 1.0 and r["newton_its"] > 0
    if config.endswith("/direct") or r["linear_used"].startswith("amg->"):
        assert r["stable"] is True and r["unstable_modes"] == 0
