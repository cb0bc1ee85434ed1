"""The example scripts run and write what they promise."""

import importlib.util
from pathlib import Path

import numpy as np
import meshio

EXAMPLES = Path(__file__).parent.parent / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_invagination_example(tmp_path, capsys):
    load("invagination").main(tmp_path)
    for f in ("invagination.png", "invagination.vtu", "invagination_dkt.vtu"):
        assert (tmp_path / f).stat().st_size > 1000, f
    meridian = meshio.read(tmp_path / "invagination.vtu")
    radius = np.hypot(meridian.points[:, 0], meridian.points[:, 1])
    assert radius.max() < 0.95 and radius[40:90].min() < 0.7       # the furrow
    assert "max distance between the meridians" in capsys.readouterr().out
