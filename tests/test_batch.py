"""``shellritz convert``: batches of meshes with growth arrays, bad inputs,
resuming, and the same results serially, with --workers 2 and on a Dask
cluster (two small discs of 150 triangles, two continuation steps)."""

import json
import os
import signal
import subprocess
import sys
import time

import meshio
import numpy as np
import pytest

from shellritz import shapes
from shellritz.cli import main

SCENE = """
description = "test batch"
[shell]
thickness = { relative = 0.01 }
[material]
law = "neo-hookean"
C = 1.0
nu = 0.4
[growth]
from_mesh_data = true
[boundary]
supports = "rigid"
[solver]
steps = 2
min_dt = 0.1
max_iter = 25
"""


def disc_with_growth(path, bend, grow=1.05):
    """A free disc with point data G0 (in-plane growth) and G1 (bending)."""
    m = shapes.disc(5)
    n = m.n_nodes
    G0 = np.tile(np.diag([grow, grow, 1.0]).ravel(), (n, 1))
    G1 = np.tile(np.diag([bend, 0.0, 0.0]).ravel(), (n, 1))
    meshio.write(path, meshio.Mesh(m.vertices, [("triangle", m.triangles)],
                                   point_data={"G0": G0, "G1": G1}))


def make_inputs(folder, n_good=2):
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(n_good):
        disc_with_growth(folder / f"good{k}.vtu", bend=0.4 + 0.2 * k)
    return folder


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    p = tmp_path_factory.mktemp("scene") / "batch.toml"
    p.write_text(SCENE)
    return p


@pytest.fixture(scope="module")
def serial(tmp_path_factory, scene):
    """A clean serial run of two good inputs."""
    base = tmp_path_factory.mktemp("serial")
    inputs = make_inputs(base / "in")
    code = main(["convert", str(inputs), "-o", str(base / "out"), "--scene", str(scene), "--no-progress"])
    return inputs, base / "out", code


def outputs(out):
    return {p.name: p.read_bytes() for p in sorted(out.glob("good*.vtu"))}


def test_serial_batch_writes_outputs_and_report(serial):
    inputs, out, code = serial
    assert code == 0
    report = json.loads((out / "batch.json").read_text())
    assert report["counts"] == {"ok": 2}
    for k in range(2):
        s = json.loads((out / f"good{k}.json").read_text())
        assert s["status"] == "ok" and s["growth"].startswith("tensors G0 (array 'G0')")
        assert s["stability"]["stable"] and s["history"]["n_iterations"] > 0
        m = meshio.read(out / f"good{k}.vtu")
        assert {"displacement", "director", "G0", "G1"} <= set(m.point_data)
        assert {"principal_stretch", "cauchy_stress", "energy_density"} <= set(m.cell_data)
        # the bending growth G1 = diag(b, 0, 0) curls the disc about the y axis
        assert np.ptp(m.points[:, 2]) > 0.02
    assert not list(out.glob(".*"))            # no temporary files left


def test_rerun_skips_complete_outputs_and_force_redoes_them(serial, scene, capsys):
    inputs, out, _ = serial
    before = outputs(out)
    assert main(["convert", str(inputs), "-o", str(out), "--scene", str(scene), "--no-progress"]) == 0
    report = json.loads((out / "batch.json").read_text())
    assert report["counts"] == {"skipped": 2}
    # a damaged output is not complete: that input alone is redone
    (out / "good1.vtu").write_bytes(b"truncated")
    assert main(["convert", str(inputs), "-o", str(out), "--scene", str(scene), "--no-progress"]) == 0
    report = json.loads((out / "batch.json").read_text())
    assert report["counts"] == {"skipped": 1, "ok": 1}
    assert outputs(out) == before
    assert main(["convert", str(inputs / "good0.vtu"), "-o", str(out), "--scene", str(scene),
                 "--no-progress", "--force"]) == 0
    assert json.loads((out / "batch.json").read_text())["counts"] == {"ok": 1}


def write_bad_inputs(folder):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "garbage.vtu").write_bytes(b"\x00\x01 this is not a mesh " * 20)
    (folder / "empty.stl").write_bytes(b"")
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])
    meshio.write(folder / "nonmanifold.vtu", meshio.Mesh(X, [("triangle", np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))]))
    Xn = X[:3].copy()
    Xn[2, 1] = np.nan
    meshio.write(folder / "nan.vtu", meshio.Mesh(Xn, [("triangle", np.array([[0, 1, 2]]))]))
    # growth the solver cannot follow: h |G1| = 1.2 at t = 1 (h = 0.02)
    disc_with_growth(folder / "diverges.vtu", bend=60.0)
    # growth whose stress-free state folds through the thickness (h |G1| = 3)
    disc_with_growth(folder / "folds.vtu", bend=150.0)


def test_bad_inputs_are_reported_and_the_batch_goes_on(tmp_path, scene):
    inputs = make_inputs(tmp_path / "in", n_good=1)
    write_bad_inputs(inputs)
    out = tmp_path / "out"
    assert main(["convert", str(inputs), "-o", str(out), "--scene", str(scene), "--no-progress"]) == 1
    rows = {r["stem"]: r for r in json.loads((out / "batch.json").read_text())["inputs"]}
    assert rows["good0"]["status"] == "ok"
    reasons = {k: rows[k]["reason"] for k in rows if k != "good0"}
    assert all(rows[k]["status"] == "failed" for k in reasons)
    assert "garbage.vtu: cannot read it" in reasons["garbage"]
    assert "empty file" in reasons["empty"]
    assert "non-manifold edges" in reasons["nonmanifold"] and "(0, 1)" in reasons["nonmanifold"]
    assert "non-finite coordinates at vertices 2" in reasons["nan"]
    assert reasons["diverges"].startswith("solver failed")
    assert "G1: the grown state folds through the thickness at nodes [0, 1, 2" in reasons["folds"]
    # nothing computed is lost: the last converged state of the failed solve is written
    s = json.loads((out / "diverges.json").read_text())
    if s.get("partial"):
        assert (out / s["partial"]["files"]["mesh"]).exists()


def test_usage_errors_exit_2(tmp_path, scene, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.replace("[solver]", "[solver]\nstepz = 3"))
    assert main(["convert", str(tmp_path), "-o", str(tmp_path / "o"), "--scene", str(bad)]) == 2
    assert "[solver]: unknown key 'stepz'" in capsys.readouterr().err
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    disc_with_growth(tmp_path / "a" / "x.vtu", 0.5)
    disc_with_growth(tmp_path / "b" / "x.vtu", 0.5)
    assert main(["convert", str(tmp_path / "a" / "x.vtu"), str(tmp_path / "b" / "x.vtu"),
                 "-o", str(tmp_path / "o"), "--scene", str(scene)]) == 2
    assert "same stem" in capsys.readouterr().err
    assert main(["convert", str(tmp_path / "a" / "x.vtu"), "-o", str(tmp_path / "a" / "x.vtu"),
                 "--scene", str(scene)]) == 2
    assert "is an existing file" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["convert", "--bogus"])
    assert exc.value.code == 2


def test_workers_2_equal_serial_bit_for_bit(serial, scene, tmp_path):
    inputs, out_serial, _ = serial
    out = tmp_path / "out"
    assert main(["convert", str(inputs), "-o", str(out), "--scene", str(scene), "--workers", "2",
                 "--no-progress"]) == 0
    assert outputs(out) == outputs(out_serial)
    for k in range(2):
        a = json.loads((out / f"good{k}.json").read_text())
        b = json.loads((out_serial / f"good{k}.json").read_text())
        assert a["threads"]["numba"] == 1 and a["energy"] == b["energy"]
        assert a["outputs"] == b["outputs"]


def test_killed_batch_resumes_to_complete_identical_outputs(serial, scene, tmp_path):
    """SIGKILL the batch process once its first input is done; no output is
    half written, and the re-run completes the rest with the same results."""
    inputs, out_serial, _ = serial
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "shellritz.cli", "convert", str(inputs), "-o", str(out),
           "--scene", str(scene), "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 300
        while not (out / "good0.json").exists():
            assert proc.poll() is None and time.time() < deadline
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    done = {p.stem for p in out.glob("good*.json")}
    assert done == {"good0"}                         # killed mid-batch
    for stem in done:                                # what is there is complete
        assert (out / f"{stem}.vtu").read_bytes() == (out_serial / f"{stem}.vtu").read_bytes()
    assert main(["convert", str(inputs), "-o", str(out), "--scene", str(scene), "--no-progress"]) == 0
    counts = json.loads((out / "batch.json").read_text())["counts"]
    assert counts == {"skipped": 1, "ok": 1}
    assert outputs(out) == outputs(out_serial)
    assert not list(out.glob(".*"))


def test_dask_cluster_equals_serial_and_survives_a_killed_worker(serial, scene, tmp_path):
    """Through --scheduler on a Dask LocalCluster: the outputs equal the serial
    run byte for byte; and when the worker is SIGKILLed while it solves, the
    nanny starts a new one, the scheduler reruns the lost task, and the batch
    completes with the same outputs."""
    import threading

    from dask.distributed import Client, LocalCluster
    inputs, out_serial, _ = serial
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        args = ["--scene", str(scene), "--scheduler", cluster.scheduler_address, "--no-progress"]
        assert main(["convert", str(inputs), "-o", str(tmp_path / "clean")] + args) == 0
        assert outputs(tmp_path / "clean") == outputs(out_serial)
        out = tmp_path / "killed"
        pid = next(iter(client.run(os.getpid).values()))
        codes = []
        run = threading.Thread(target=lambda: codes.append(main(["convert", str(inputs), "-o", str(out)] + args)))
        run.start()
        deadline = time.time() + 300
        while not (out / "good0.json").exists():
            assert run.is_alive() and time.time() < deadline
            time.sleep(0.05)
        os.kill(pid, signal.SIGKILL)               # while it solves the next input
        run.join(600)
    assert codes == [0]
    assert json.loads((out / "batch.json").read_text())["counts"] == {"ok": 2}
    assert outputs(out) == outputs(out_serial)
