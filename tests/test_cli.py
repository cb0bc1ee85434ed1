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
    # the scene file's locking-free membrane metric (with "dkt" the 16-ring
    # leaf's energy is 12 times too high: test_obstacle_course)
    assert summary["level"] == "consistent" and summary["membrane"] == "regge"
    # excess rim growth buckles the flat disc into a saddle: the rim rises on
    # one axis and falls on the other, well beyond the thickness (0.02)
    lo, hi = summary["extent"]["min"][2], summary["extent"]["max"][2]
    assert lo < -0.1 and hi > 0.1
    mesh = meshio.read(out / "leaf.vtu")
    assert np.isfinite(mesh.points).all() and len(mesh.points) > 700
    assert "wrote" in capsys.readouterr().out


def test_help_of_each_command(capsys):
    import pytest
    for argv in (["--help"], ["run", "--help"], ["convert", "--help"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "exit codes" in out and "--workers" in out and "--scheduler" in out


def test_run_a_scene_file_and_exit_codes(tmp_path, capsys):
    from shellritz import shapes
    m = shapes.disc(4)
    meshio.write(tmp_path / "d.vtu", meshio.Mesh(m.vertices, [("triangle", m.triangles)]))
    scene = tmp_path / "s.toml"
    scene.write_text('[mesh]\nfile = "d.vtu"\n[shell]\nthickness = 0.05\n[material]\nlaw = "NeoHookean"\n'
                     'C = 1.0\nnu = 0.3\n[growth]\nG0 = [1.2, 0, 0, 0, 1.0, 0, 0, 0, 1]\n'
                     '[boundary]\nsupports = "rigid"\n[output]\nfaces = true\nsolid = true\n')
    assert main(["run", str(scene), "-o", str(tmp_path / "o"), "-q"]) == 0
    out = capsys.readouterr().out
    assert "kernels ready in" in out and "solved in" in out
    r = meshio.read(tmp_path / "o" / "s.vtu")
    assert np.allclose(np.ptp(r.points, axis=0)[:2], [2.4, 2.0], atol=1e-9)      # grown 1.2 in x
    top, bottom = meshio.read(tmp_path / "o" / "s_top.vtu"), meshio.read(tmp_path / "o" / "s_bottom.vtu")
    assert np.allclose(top.points[:, 2] - bottom.points[:, 2], 0.05, atol=1e-9)  # flat: faces h apart
    assert meshio.read(tmp_path / "o" / "s_solid.vtu").cells[0].type == "wedge"
    scene.write_text(scene.read_text().replace("nu = 0.3", "nu = 0.6"))
    assert main(["run", str(scene), "-o", str(tmp_path / "o")]) == 2
    assert "Poisson ratio nu=0.6" in capsys.readouterr().err
