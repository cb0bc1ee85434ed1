"""Scene files: validation messages, every law, the solver table against
Shell.solve, field values, node selectors, and the shipped scenes."""

import inspect
from importlib.resources import files
from pathlib import Path

import meshio
import numpy as np
import pytest

from shellritz import Shell, materials, shapes
from shellritz.meshdata import Surface, read_surface
from shellritz.scenefile import SceneError, _laws, load_scene, loads_scene, nodal_field

BASE = """
[shell]
thickness = 0.02
[material]
law = "neo-hookean"
C = 1.0
nu = 0.4
"""


def scene(extra=""):
    return loads_scene(BASE + extra)


def surface(n=4):
    m = shapes.disc(n)
    return Surface(m, {"G0": np.tile(np.eye(3).ravel(), (m.n_nodes, 1)), "fix": (m.vertices[:, 0] > 0.9) * 1.0,
                       "short": np.zeros((m.n_nodes, 4))}, {"c9": np.tile(np.eye(3).ravel(), (m.n_triangles, 1))})


@pytest.mark.parametrize("text, message", [
    ("[shel]\nthickness = 1", "unknown key 'shel'"),
    ("[solver]\nstepz = 3", "[solver]: unknown key 'stepz'; allowed keys: "),
    ("[solver]\nsteps = 2.5", "[solver] steps: expected an integer, got 2.5"),
    ("[output]\nformat = 'docx'", "[output] format"),
    ("[boundary]\nsupports = 'floppy'", "[boundary] supports: expected one of none, rigid, got 'floppy'"),
    ("[[boundary.clamp]]\nnodes = {loop = 0}\n[boundary]\nsupports = 'rigid'", "is for free bodies"),
    ("[[boundary.clamp]]\nposition = [0, 0, 0]", "missing key 'nodes'"),
    ("[[boundary.pin]]\nnodes = {loop = 0, near = [0, 0, 0]}", "exactly one of"),
    ("[[boundary.pin]]\nnodes = {loop = 0}\nstiffness = 3", "[[boundary.pin]] #1: unknown key 'stiffness'"),
    ("[growth]\nG0 = 1.1\nstretches = [1, 1, 1]", "give one form of growth"),
    ("[growth]\nabar = {array = 'a'}", "'abar' and 'bbar' go together"),
    ("[output]\nname = '../elsewhere/leaf'", "[output] name: a file name without folders"),
    ("[solver]\nmax_escapes = -1", "[solver]: max_escapes must be at least 0, got -1"),
    ("[solver]\nsteps = 0", "[solver]: steps must be at least 1, got 0"),
    ("[solver]\nmin_dt = 0.0", "[solver]: min_dt must be in (0, 1), got 0.0"),
    ("[solver]\nrtol = -1e-9", "[solver]: rtol must be in (0, inf), got -1e-09"),
    ("[solver]\nlinear = 'mumps'", "[solver]: unknown linear solver 'mumps'"),
])
def test_invalid_scene_files_name_the_key(text, message):
    with pytest.raises(SceneError) as exc:
        scene(text)
    assert message in str(exc.value)


@pytest.mark.parametrize("table, message", [
    ("[shell]\nthickness = -0.1", "[shell] thickness: must be > 0, got -0.1"),
    ("[shell]\nthickness = 0.1\nlevel = 'plate'", "[shell] level: unknown level 'plate'"),
    ("[shell]\nthickness = 0.1\nmembrane = 'cst'", "[shell] membrane: unknown metric 'cst'; choose one of dkt, regge"),
    ("[shell]\nthickness = 0.1\nmembrane = 'regge'\nquadrature = 3",
     "[shell] membrane = 'regge' needs quadrature = 6 or 7, got 3"),
    ("[shell]\nthickness = 0.1\n[material]\nlaw = 'rubber'", "unknown law 'rubber'"),
    ("[shell]\nthickness = 0.1\n[material]\nlaw = 'neo-hookean'\nC = 1.0\nnu = 0.7",
     "Poisson ratio nu=0.7 must satisfy -1 < nu < 0.5"),
    ("[shell]\nthickness = 0.1\n[material]\nlaw = 'neo-hookean'\nmu = 1.0", "takes the parameters of one of"),
])
def test_non_physical_values_are_rejected(table, message):
    with pytest.raises(SceneError) as exc:
        loads_scene(table)
    assert message in str(exc.value)


def test_the_membrane_metric_reaches_the_shell():
    text = BASE.replace("[shell]\n", "[shell]\nmembrane = 'regge'\n", 1)
    assert "membrane = 'regge'" in text
    shell, _ = loads_scene(text).build(surface())
    assert shell.membrane == "regge"
    assert scene().build(surface())[0].membrane == "dkt"


def test_every_material_law_of_the_package_is_reachable():
    names = {n for n in materials.__all__ if isinstance(getattr(materials, n), type)
             and issubclass(getattr(materials, n), materials.Law)} - {"Law", "InvariantLaw"}
    assert {c.__name__ for c in _laws().values()} == names
    for law, params in [("NeoHookean", "C = 1.0\nD = 2.0"), ("cubic-stretch", "nu = 1.0"),
                        ("saint_venant_kirchhoff", "lam = 1.0\nmu = 1.0"),
                        ("StVenantKirchhoff", "E = 1.0\nnu = 0.3"), ("linear-isotropic", "E = 1.0\nnu = 0.3")]:
        s = loads_scene(f"[shell]\nthickness = 0.1\n[material]\nlaw = '{law}'\n{params}")
        assert isinstance(s.law, materials.Law)
    pytest.importorskip("sympy")
    s = loads_scene("[shell]\nthickness = 0.1\n[material]\nlaw = 'invariant'\n"
                    "psi = 'C/2*(I1 - 3 - 2*log(J)) + D/2*(J - 1)**2'\nparameters = {C = 1.0, D = 2.0}")
    W = s.law.evaluate(np.diag([1.1, 1.0, 1.0]))[0]
    ref = materials.NeoHookean(1.0, D=2.0).evaluate(np.diag([1.1, 1.0, 1.0]))[0]
    assert abs(W - ref) < 1e-14


def test_solver_table_follows_the_signature_of_shell_solve():
    params = set(inspect.signature(Shell.solve).parameters) - {"self", "verbose"}
    text = "\n".join(f"{k} = {v.default!r}".replace("True", "true").replace("False", "false")
                     for k, v in inspect.signature(Shell.solve).parameters.items()
                     if k in params and isinstance(v.default, (int, float, bool, str)))
    assert scene("[solver]\n" + text).solver.keys() <= params
    # continuation in the thickness: a list, checked by Shell.solve
    assert scene("[solver]\nthickness_path = [0.04, 0.02]").solver == {"thickness_path": [0.04, 0.02]}


@pytest.mark.parametrize("value, message", [
    ({"array": "nope"}, "no array 'nope' (point or cell data); its arrays: G0, c9, fix, short"),
    ({"array": "short"}, "point data 'short' has shape"),
    ([1, 2, 3], "expected 9 entries (3x3 row-major or nested), got 3"),
    (["1 + x", 0, 0, 0, "sqrt(-1 - y**2)", 0, 0, 0, 1], "is not finite at nodes"),
    (["1 + q", 0, 0, 0, 1, 0, 0, 0, 1], "cannot evaluate '1 + q'"),
])
def test_field_errors_name_array_shape_and_value(value, message):
    with pytest.raises(SceneError) as exc:
        nodal_field(value, "[growth] G0", surface(), (3, 3))
    assert message in str(exc.value) and "[growth] G0" in str(exc.value)


def test_field_values():
    surf = surface()
    X = surf.mesh.vertices
    G = nodal_field(["1 + x**2", 0, 0, 0, 1.5, 0, 0, 0, 1], "G0", surf, (3, 3))
    assert np.allclose(G[:, 0, 0], 1 + X[:, 0] ** 2) and np.all(G[:, 1, 1] == 1.5)
    assert np.allclose(nodal_field(1.1, "G0", surf, (3, 3)), 1.1 * np.eye(3))
    assert np.allclose(nodal_field({"array": "c9"}, "G0", surf, (3, 3)), np.eye(3))   # cells -> nodes


def test_growth_errors_before_the_solve():
    surf = surface()
    with pytest.raises(SceneError, match=r"\[growth\] .*det G0 <= 0 at nodes"):
        scene("[growth]\nG0 = [-1, 0, 0, 0, 1, 0, 0, 0, 1]").build(surf)
    with pytest.raises(SceneError, match=r"stretches: must be > 0"):
        scene("[growth]\nstretches = [1, '-x', 1]").build(surf)
    with pytest.raises(SceneError, match=r"direction: parallel to the surface normal"):
        scene("[growth]\nstretches = [1.1, 1, 1]\ndirection = [0, 0, 1]").build(surf)
    with pytest.raises(SceneError, match=r"abar: the mesh has no array 'A'"):
        scene("[growth]\nabar = {array = 'A'}\nbbar = {array = 'B'}").build(surf)


def test_selectors():
    surf = surface()
    s = scene()
    m = surf.mesh
    assert set(s.select({"loop": "all"}, "w", surf)) == set(m.boundary_nodes())
    assert list(s.select({"near": [0.01, 0, 0]}, "w", surf)) == [0]
    assert set(s.select({"mask": "fix"}, "w", surf)) == set(np.where(m.vertices[:, 0] > 0.9)[0])
    assert set(s.select({"where": "x > 0.9"}, "w", surf)) == set(np.where(m.vertices[:, 0] > 0.9)[0])
    assert set(s.select({"plane": {"axis": "y", "value": 0.0}}, "w", surf)) == set(m.nodes_on_plane("y", 0.0))
    with pytest.raises(SceneError, match="selects no node"):
        s.select({"where": "x > 5"}, "[[boundary.pin]] #1 nodes", surf)
    with pytest.raises(SceneError, match="the mesh has 1 boundary loops"):
        s.select({"loop": 3}, "w", surf)


def test_stretches_growth_is_the_tensor_growth():
    surf = surface()
    a = scene("[growth]\nstretches = ['1 + 0.3*(x**2 + y**2)', '1 + 0.3*(x**2 + y**2)', 1]\n"
              "stretch_gradients = [0.5, -0.5, 0]\ndirection = [1, 0, 0]")
    G0, G1, _ = a.growth(surf)
    X = surf.mesh.vertices
    g = 1 + 0.3 * (X[:, 0] ** 2 + X[:, 1] ** 2)
    assert np.array_equal(G0[:, 0, 0], g) and np.array_equal(G0[:, 1, 1], g)
    assert np.allclose(G1, np.diag([0.5, -0.5, 0]))


def test_shipped_scenes_load_and_their_meshes_read():
    for f in files("shellritz.meshes").iterdir():
        if f.name.endswith(".toml"):
            s = load_scene(Path(str(f)))
            if s.mesh_file is not None:
                assert s.read().mesh.n_triangles > 100


def test_leaf_of_another_thickness_is_the_same_scene():
    """scenes.leaf(rings, thickness): the default scene (h = 0.02) on the
    same disc with only the thickness changed (bench/scaling.py
    --thickness); a non-physical thickness is refused."""
    from shellritz.scenes import leaf
    default, thin = leaf(6), leaf(6, thickness=0.005)
    assert (default.h, thin.h) == (0.02, 0.005)
    assert np.array_equal(default.mesh.vertices, thin.mesh.vertices)
    assert np.array_equal(default._G0, thin._G0) and np.array_equal(default._G1, thin._G1)
    assert np.array_equal(default._fixed_user, thin._fixed_user) and default._fixed_user.any()
    with pytest.raises(ValueError, match="thickness"):
        leaf(6, thickness=-0.01)


def test_convert_defaults_scale_a_free_disc_by_1_1(tmp_path):
    """The issue's example: a free disc given point data G0 = diag(1.1, 1.1, 1)
    comes out as the same disc scaled by 1.1 (rigid supports: no stress)."""
    from shellritz.batch import run_one
    m = shapes.disc(6)
    meshio.write(tmp_path / "disc.vtu", meshio.Mesh(m.vertices, [("triangle", m.triangles)], point_data={
        "G0": np.tile(np.diag([1.1, 1.1, 1.0]).ravel(), (m.n_nodes, 1))}))
    text = Path(str(files("shellritz.meshes") / "convert-defaults.toml")).read_text()
    s = run_one({"scene_text": text, "scene_dir": ".", "input": str(tmp_path / "disc.vtu"),
                 "out_dir": str(tmp_path), "stem": "out", "format": None})
    assert s["status"] == "ok", s["reason"]
    r = read_surface(tmp_path / "out.vtu")
    assert np.abs(r.mesh.vertices - 1.1 * m.vertices).max() < 1e-12       # observed 2e-16
    assert np.abs(r.cell_data["cauchy_stress"]).max() < 1e-12              # observed 3e-14
    assert np.allclose(r.cell_data["principal_stretch"], [1.1, 1.1, 1.0], atol=1e-12)
