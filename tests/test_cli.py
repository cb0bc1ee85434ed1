"""The README's first command: ``shellritz`` solves the embedded default scene
and writes the result mesh, the picture and the summary."""

import json

import meshio
import numpy as np

from shellritz.cli import main


def test_main_job_writes_the_grown_leaf(tmp_path, capsys):
    assert main(["-o", str(tmp_path / "out"), "-q"]) == 0
    out = tmp_path / "out"
    for f in ("leaf.vtu", "leaf.png"):
        assert (out / f).stat().st_size > 10_000, f
    summary = json.loads((out / "leaf.json").read_text())
    assert summary["stable"] and all(ok for _, ok in summary["continuation_steps"])
    # excess rim growth buckles the flat disc into a saddle: the rim rises on
    # one axis and falls on the other, well beyond the thickness (0.02)
    lo, hi = summary["height_range"]
    assert lo < -0.1 and hi > 0.1
    mesh = meshio.read(out / "leaf.vtu")
    assert np.isfinite(mesh.points).all() and len(mesh.points) > 700
    assert "wrote" in capsys.readouterr().out
