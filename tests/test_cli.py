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
    assert summary["status"] == "ok" and summary["stability"]["stable"]
    assert summary["history"]["steps"][-1][0] == 1.0
    # excess rim growth buckles the flat disc into a saddle: the rim rises on
    # one axis and falls on the other, well beyond the thickness (0.02)
    lo, hi = summary["extent"]["min"][2], summary["extent"]["max"][2]
    assert lo < -0.1 and hi > 0.1
    mesh = meshio.read(out / "leaf.vtu")
    assert np.isfinite(mesh.points).all() and len(mesh.points) > 700
    assert "wrote" in capsys.readouterr().out
