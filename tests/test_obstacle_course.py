"""The linear shell obstacle course at small loads (bench/obstacle.py has the
full study and charts) and membrane locking, for both membrane metrics.

Observed displacement / reference at n x n elements on the symmetric part
(DKT metric / regge metric):
  Scordelis-Lo roof   n = 16, 32, 64:  0.952, 0.984, 0.992 / 0.996, 0.995, 0.994
  pinched cylinder    n = 16, 32, 64:  0.964, 0.998, 1.002 / 1.001, 1.005, 1.004
                      n = 128: 1.0020 / 1.0024
  pinched hemisphere  n = 16, 32, 64:  0.754, 0.984, 1.008 / 1.008, 1.012, 1.012
(both metrics converge to about 0.994 / 1.002 / 1.012 of the classical
references).  Locking (clamped cylindrical panel, linear response,
C E t^3 / q^2 against its converged value 5.047): DKT metric t/R = 1e-2
reaches 97 % at n = 16, 1e-3 99 % at n = 64, 1e-4 94 % at n = 128 (accurate
once the element size is about sqrt(t R)); regge metric within 1.2 % from
n = 8 at every thickness (0.38 at n = 4 for t/R = 1e-4), and accurate on
coarse meshes when the panel is membrane dominated (clamped along a curved
edge) too.
"""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from obstacle import leaf, locking_panel, pinched_cylinder, pinched_hemisphere, scordelis_lo  # noqa: E402

CONVERGED = 5.047


@pytest.mark.parametrize("fn, lo, hi", [(scordelis_lo, 0.975, 1.0),
                                        (pinched_cylinder, 0.99, 1.005),
                                        (pinched_hemisphere, 0.97, 1.0)])
def test_obstacle_course_at_32x32(fn, lo, hi):
    u, ref, _ = fn(32)
    assert lo < u / ref < hi


@pytest.mark.parametrize("fn, lo, hi", [(scordelis_lo, 0.99, 1.0),         # DKT: 0.9521
                                        (pinched_cylinder, 0.995, 1.005),  # DKT: 0.964
                                        (pinched_hemisphere, 0.98, 1.012)])  # DKT: 0.754
def test_obstacle_course_at_16x16_with_the_regge_metric(fn, lo, hi):
    u, ref, _ = fn(16, "regge")
    assert lo < u / ref < hi


@pytest.mark.slow
@pytest.mark.parametrize("fn, lo, hi", [(scordelis_lo, 0.985, 1.0),
                                        (pinched_cylinder, 0.995, 1.005),
                                        (pinched_hemisphere, 0.995, 1.015)])
def test_obstacle_course_at_64x64(fn, lo, hi):
    u, ref, _ = fn(64)
    assert lo < u / ref < hi


@pytest.mark.slow
def test_pinched_cylinder_metrics_meet_at_a_common_limit():
    """The regge metric converges from above (1.0053, 1.0035 at n = 32, 64),
    the DKT metric from below (0.9976, 1.0018): at n = 128 they agree to
    0.05 % (1.0020 / 1.0024), at n = 256 (bench/obstacle.py --fine) to
    0.012 % (1.00184 / 1.00196), about 0.18 % above the classical
    reference, so the regge values at 32 and 64 are off the limit, not the
    reference alone; the excess from above is the DKT bending's under a
    point load (test_shell_solutions.py, the point-loaded plates; README,
    Membrane locking)."""
    dkt, regge = (pinched_cylinder(128, m) for m in ("dkt", "regge"))
    assert abs(regge[0] / dkt[0] - 1) < 1e-3
    assert 1.0 < dkt[0] / dkt[1] < 1.004


def test_regge_metric_locks_on_elements_long_across_the_bending():
    """A limitation (README, Membrane locking): refining the bending-dominated
    panel along its generators only (8 elements along the arc, elements up
    to 5.6 times longer than wide) makes the regge metric lock at
    t/R = 1e-4: 0.996, 0.765, 0.239 of the converged compliance at
    8 x 8, 8 x 32, 8 x 64 (DKT 3e-4), whatever the blend (B = 0.2, 2, 8:
    0.25, 0.24, 0.20 at 8 x 64): the Regge field itself; 64 x 8 and 16 x 64
    are within 0.4 %.  The cause: the element mean's three constraints per
    element (without them, in a scratch copy: 0.979 at 8 x 64, but the
    patch test and the membrane-dominated panel fail)."""
    assert locking_panel(8, 1e-4, "regge", n_z=8) / CONVERGED > 0.99
    assert locking_panel(8, 1e-4, "regge", n_z=64) / CONVERGED < 0.3
    assert locking_panel(64, 1e-4, "regge", n_z=8) / CONVERGED > 0.99


def test_membrane_locking_is_bounded_by_sqrt_tR():
    assert locking_panel(16, 1e-2) / CONVERGED > 0.95      # h_e = 0.09 < 1.5 sqrt(tR) = 0.15
    assert locking_panel(16, 1e-3) / CONVERGED < 0.5       # h_e = 0.09 > 1.5 sqrt(tR) = 0.047: locks


def test_regge_metric_does_not_lock():
    """Targets of issue 12: >= 95 % at n = 16 for t/R = 1e-3, >= 90 % at n = 32
    for 1e-4 (observed 1.0035 and 1.0008)."""
    assert 0.95 < locking_panel(16, 1e-3, "regge") / CONVERGED < 1.01
    assert 0.9 < locking_panel(32, 1e-4, "regge") / CONVERGED < 1.01


def test_regge_metric_is_accurate_on_coarse_membrane_dominated_meshes():
    """Clamped along a curved edge (no inextensional motion of the
    continuum), t/R = 1e-4: C E t^3 / q^2 = 4.7e-4 converged (regge 4.685e-4,
    4.681e-4 at n = 128, 256; DKT 4.45e-4, 4.64e-4, still locking there).
    The regge metric is within 5 % from n = 4 (observed: 4.6e-4, 4.5e-4,
    4.8e-4 at n = 4, 8, 16) where the DKT metric locks (4.1e-6, 1.2e-5,
    4.4e-5); the earlier regge metric (the lowest-order Regge interpolant of
    the edge arcs) was 150x, 20x, 1.8x too soft there."""
    for n in (4, 8):
        assert abs(locking_panel(n, 1e-4, "regge", clamp="curved") / 4.7e-4 - 1) < 0.05


def test_the_default_leaf_locks_with_the_dkt_metric_not_with_the_regge_metric():
    """The default scene's buckled saddle is nearly isometric to the grown
    metric, so its energy is small and parasitic membrane energy dominates
    it (bench/obstacle.py --leaf): DKT metric 1.04e-5, 3.34e-6, 1.50e-6 at
    16, 32, 64 rings (falling like l^2 towards about 8.8e-7); regge metric
    8.754e-7, 8.752e-7, 8.756e-7.  Saddle height 0.5405 (DKT) and 0.5468
    (regge) at 16 rings, both 0.5467 at 64.  Both end stable in 17-18
    Newton iterations.  (So the scene file uses regge since 2026-12-07:
    test_cli.)"""
    dkt16, regge16, regge32 = leaf(16, "dkt"), leaf(16, "regge"), leaf(32, "regge")
    assert all(r["converged"] and r["stable"] for r in (dkt16, regge16, regge32))
    assert abs(regge16["energy"] / regge32["energy"] - 1) < 1e-3
    assert dkt16["energy"] > 10 * regge16["energy"]


@pytest.mark.slow
def test_membrane_locking_recovers_on_fine_meshes():
    assert locking_panel(64, 1e-3) / CONVERGED > 0.98
    assert locking_panel(128, 1e-4) / CONVERGED > 0.9


@pytest.mark.slow
def test_membrane_dominated_panel_converges_to_the_same_answer_with_both_metrics():
    """Clamped along a curved edge (no inextensional motion): the regge metric
    must not converge to another answer (the rejected attempt in shared/notes
    did).  Observed C E t^3 / q^2 at t/R = 1e-3, n = 64: 0.007913 (DKT) and
    0.007927 (regge); n = 128: 0.008151 and 0.008149; at n = 8 the DKT metric
    is 7x too stiff, the regge one 1.4x too soft."""
    dkt = locking_panel(64, 1e-3, "dkt", clamp="curved")
    regge = locking_panel(64, 1e-3, "regge", clamp="curved")
    assert abs(regge / dkt - 1) < 0.01
