"""Scene files (TOML): a whole DKT shell problem in one file, checked before
any solve.

A scene file has the tables ``[mesh]``, ``[shell]``, ``[material]``,
``[growth]``, ``[boundary]``, ``[loads]``, ``[solver]`` and ``[output]``
(README, "Scene files", documents each key; ``meshes/*.toml`` are examples).
:func:`load_scene` reads and checks everything that does not need the mesh
(keys, value types, the material law, the solver options against
``Shell.solve``); :meth:`Scene.build` checks the rest against a mesh and its
data arrays (array names, shapes, values) and returns the :class:`Shell`.
Every error is a :class:`SceneError` naming the table, the key and, where it
applies, the array, the expected shape and the value found.

Field values (growth, tractions, directions) are numbers, expressions of the
reference coordinates ``x, y, z`` and normal ``nx, ny, nz`` (strings,
evaluated by numexpr), lists of those (vectors, 3x3 tensors as 9 entries
row-major or nested), or ``{array = "NAME"}``: a point or cell data array of
the mesh (cell values are averaged to the nodes, weighted by area).
"""

import inspect
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import materials
from .growth import cells_to_nodes, from_fundamental_forms, from_stretches
from .meshdata import Surface, read_surface, file_format
from .model import LEVELS
from .shell import Shell

try:
    import tomllib
except ImportError:                 # Python 3.10
    import tomli as tomllib

__all__ = ["Scene", "SceneError", "load_scene", "loads_scene", "parse_scene"]


class SceneError(ValueError):
    """The scene file (or a mesh it is applied to) is not usable; the message
    names the table, key, array, expected shape and value."""


TABLES = {
    "mesh": {"file", "normal"},
    "shell": {"thickness", "level", "quadrature", "membrane"},
    "material": None,            # "law" + the parameters of that law (checked by signature)
    "growth": {"G0", "G1", "stretches", "stretch_gradients", "direction", "abar", "bbar",
               "from_mesh_data"},
    "boundary": {"supports", "clamp", "pin", "rotate", "simply_support", "diaphragm", "symmetry"},
    "loads": {"pressure", "face_tractions", "point_force", "edge_load"},
    "solver": None,              # the keyword arguments of Shell.solve
    "output": {"name", "format", "picture", "faces", "solid"},
}
TOP_LEVEL = {"description"}
SELECTORS = {"loop", "plane", "near", "mask", "where"}
CONDITIONS = ("clamp", "pin", "rotate", "simply_support", "diaphragm", "symmetry")
SUPPORTS = ("none", "rigid")
EXPRESSION_HELP = "variables x, y, z (reference position), nx, ny, nz (reference normal), pi"


def _keys(table, allowed, where):
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise SceneError(f"{where}: unknown key {unknown[0]!r}; allowed keys: "
                         f"{', '.join(sorted(allowed))}")


def _number(value, where, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SceneError(f"{where}: expected a finite number, got {value!r}")
    if positive and not value > 0:
        raise SceneError(f"{where}: must be > 0, got {value!r}")
    return float(value)


def _norm(name):
    return name.lower().replace("-", "").replace("_", "").replace(" ", "")


def _laws():
    """Law classes of shellritz.materials that take numbers (not InvariantLaw,
    which takes a compiled cfunc: ``law = "invariant"`` builds one from an
    expression instead)."""
    out = {}
    for name in materials.__all__:
        obj = getattr(materials, name)
        if (isinstance(obj, type) and issubclass(obj, materials.Law)
                and obj not in (materials.Law, materials.InvariantLaw)):
            out[_norm(name)] = obj          # the class name, e.g. NeoHookean
            out[_norm(obj.name)] = obj      # and the law's own, e.g. neo-Hookean
    return out


def _constructors(cls):
    """(callable, parameter names, required names) for __init__ and the
    from_* classmethods of a law class."""
    out = []
    for name in ["__init__"] + sorted(n for n in vars(cls) if n.startswith("from_")):
        fn = getattr(cls, name)
        sig = inspect.signature(fn)
        params = [p for p in sig.parameters.values() if p.name not in ("self", "cls")]
        names = [p.name for p in params]
        required = {p.name for p in params if p.default is inspect.Parameter.empty}
        out.append((cls if name == "__init__" else fn, names, required, name))
    return out


def _material(table):
    where = "[material]"
    if "law" not in table:
        raise SceneError(f"{where}: missing key 'law'; choose one of "
                         f"{', '.join(sorted({c.__name__ for c in _laws().values()}))}, invariant")
    law = table["law"]
    params = {k: v for k, v in table.items() if k != "law"}
    if not isinstance(law, str):
        raise SceneError(f"{where} law: expected a string, got {law!r}")
    if _norm(law) == "invariant":
        _keys(params, {"psi", "parameters"}, where)
        if not isinstance(params.get("psi"), str):
            raise SceneError(f"{where} psi: expected an expression of I1, I2, J (a string)")
        consts = params.get("parameters", {})
        if not isinstance(consts, dict):
            raise SceneError(f"{where} parameters: expected a table of numbers")
        for k, v in consts.items():
            _number(v, f"{where} parameters.{k}")
        try:
            import sympy as sp
        except ImportError:
            raise SceneError(f"{where}: law 'invariant' needs SymPy (pip install sympy)") from None
        I1, I2, J = sp.symbols("I1 I2 J", positive=True)
        syms = {k: sp.Symbol(k) for k in consts}
        try:
            expr = sp.sympify(params["psi"], locals={"I1": I1, "I2": I2, "J": J, **syms})
            return materials.invariant_law_from_sympy(expr, I1, I2, J, params=list(syms.values()),
                                                      values=[float(v) for v in consts.values()])
        except (sp.SympifyError, ValueError, TypeError) as exc:
            raise SceneError(f"{where} psi = {params['psi']!r}: {exc}") from None
    laws = _laws()
    cls = laws.get(_norm(law))
    if cls is None:
        raise SceneError(f"{where} law: unknown law {law!r}; choose one of "
                         f"{', '.join(sorted({c.__name__ for c in laws.values()}))}, invariant")
    for k, v in params.items():
        _number(v, f"{where} {k}")
    options = []
    for make, names, required, label in _constructors(cls):
        options.append(f"{label.replace('__init__', cls.__name__)}({', '.join(names)})")
        if set(params) <= set(names) and required <= set(params):
            try:
                return make(**params)
            except (ValueError, TypeError) as exc:
                raise SceneError(f"{where}: {exc}") from None
    raise SceneError(f"{where}: law {law!r} takes the parameters of one of "
                     f"{'; '.join(options)}; got {', '.join(sorted(params)) or 'none'}")


def _solver_keys():
    """Options of Shell.solve a scene may set, with their defaults: the
    continuation's (steps, min_dt) and the solver's (solve.SolverOptions),
    minus the verbosity (the command line's) and the callables."""
    from dataclasses import fields
    from .solve import SolverOptions
    sig = inspect.signature(Shell.solve)
    keys = {name: p.default for name, p in sig.parameters.items()
            if name not in ("self", "verbose", "monitor") and p.default is not p.empty}
    keys.update({f.name: f.default for f in fields(SolverOptions) if f.name not in ("verbose", "stop")})
    keys["nested"] = False      # nested iteration on coarse meshes made from the input (Scene.solve)
    return keys


def _solver(table):
    allowed = _solver_keys()
    _keys(table, allowed, "[solver]")
    for k, v in table.items():
        default = allowed[k]
        where = f"[solver] {k}"
        if isinstance(default, bool):
            if not isinstance(v, bool):
                raise SceneError(f"{where}: expected true or false, got {v!r}")
        elif isinstance(default, (int, float)) and default is not None:
            _number(v, where)
            if isinstance(default, int) and not isinstance(v, int):
                raise SceneError(f"{where}: expected an integer, got {v!r}")
        elif isinstance(default, str) and not isinstance(v, str):
            raise SceneError(f"{where}: expected a string, got {v!r}")
    # the values, as solve checks them (before any mesh is read or solved)
    from dataclasses import fields
    from .solve import SolverOptions, solver_options
    names = {f.name for f in fields(SolverOptions)} | {"steps", "min_dt"}
    try:
        solver_options(verbose=False, **{k: v for k, v in table.items() if k in names})
    except (ValueError, TypeError) as exc:
        raise SceneError(f"[solver]: {exc}") from None
    return dict(table)


def _check_output(table):
    _keys(table, TABLES["output"], "[output]")
    for k in ("picture", "faces", "solid"):
        if k in table and not isinstance(table[k], bool):
            raise SceneError(f"[output] {k}: expected true or false, got {table[k]!r}")
    for k in ("name", "format"):
        if k in table and not isinstance(table[k], str):
            raise SceneError(f"[output] {k}: expected a string, got {table[k]!r}")
    name = table.get("name")
    if name is not None and (not name or name in (".", "..") or any(c in name for c in "/\\")):
        raise SceneError(f"[output] name: a file name without folders, got {name!r} "
                         "(the output folder is the command line's)")
    if "format" in table:
        try:
            file_format("x." + table["format"].lstrip("."))
        except ValueError as exc:
            raise SceneError(f"[output] format: {exc}") from None


def parse_scene(data, base_dir=".", source="scene"):
    """Check a scene given as a dict (the parsed TOML) and return a Scene."""
    if not isinstance(data, dict):
        raise SceneError(f"{source}: a scene is a table of tables")
    _keys(data, set(TABLES) | TOP_LEVEL, source)
    for name, value in data.items():
        if name in TABLES and not isinstance(value, dict):
            raise SceneError(f"[{name}]: expected a table, got {value!r}")
    for name, allowed in TABLES.items():
        if allowed is not None:
            _keys(data.get(name, {}), allowed, f"[{name}]")
    shell = data.get("shell", {})
    if "thickness" not in shell:
        raise SceneError("[shell]: missing key 'thickness' (a length, or {relative = f}: "
                         "f times the largest extent of the mesh)")
    th = shell["thickness"]
    if isinstance(th, dict):
        _keys(th, {"relative"}, "[shell] thickness")
        _number(th.get("relative"), "[shell] thickness.relative", positive=True)
    else:
        _number(th, "[shell] thickness", positive=True)
    level = shell.get("level", "consistent")
    if level not in LEVELS:
        raise SceneError(f"[shell] level: unknown level {level!r}; choose one of {', '.join(LEVELS)}")
    if "quadrature" in shell:
        from .discretize.dkt import RULES
        if shell["quadrature"] not in RULES:
            raise SceneError(f"[shell] quadrature: no {shell['quadrature']!r}-point rule; "
                             f"choose one of {sorted(RULES)}")
    membrane = shell.get("membrane", "dkt")
    if membrane not in Shell.MEMBRANES:
        raise SceneError(f"[shell] membrane: unknown metric {membrane!r}; choose one of "
                         f"{', '.join(Shell.MEMBRANES)}")
    if membrane == "regge" and shell.get("quadrature", 6) not in Shell.REGGE_RULES:
        raise SceneError(f"[shell] membrane = 'regge' needs quadrature = "
                         f"{' or '.join(map(str, Shell.REGGE_RULES))}, "
                         f"got {shell['quadrature']!r}")
    law = _material(data.get("material", {}))
    solver = _solver(data.get("solver", {}))
    _check_output(data.get("output", {}))
    growth = data.get("growth", {})
    if growth.get("from_mesh_data") not in (None, True, False):
        raise SceneError(f"[growth] from_mesh_data: expected true or false, "
                         f"got {growth['from_mesh_data']!r}")
    forms = [k for k in ("G0/G1", "stretches", "abar/bbar", "from_mesh_data")
             if any(g in growth for g in k.split("/"))
             and (k != "from_mesh_data" or growth[k])]
    if len(forms) > 1:
        raise SceneError(f"[growth]: give one form of growth, got {' and '.join(forms)}")
    if ("stretch_gradients" in growth or "direction" in growth) and "stretches" not in growth:
        raise SceneError("[growth] stretch_gradients/direction: only with 'stretches'")
    if ("abar" in growth) != ("bbar" in growth):
        raise SceneError("[growth]: 'abar' and 'bbar' go together (target first and second "
                         "fundamental forms)")
    boundary = data.get("boundary", {})
    supports = boundary.get("supports", "none")
    if supports not in SUPPORTS:
        raise SceneError(f"[boundary] supports: expected one of {', '.join(SUPPORTS)}, got {supports!r}")
    for kind in CONDITIONS:
        items = boundary.get(kind, [])
        if not isinstance(items, list) or not all(isinstance(c, dict) for c in items):
            raise SceneError(f"[boundary] {kind}: expected an array of tables ([[boundary.{kind}]])")
        allowed = set(inspect.signature(getattr(Shell, kind)).parameters) - {"self"}
        for i, cond in enumerate(items):
            _keys(cond, allowed, f"[[boundary.{kind}]] #{i + 1}")
            if "nodes" in cond:
                _check_selector(cond["nodes"], f"[[boundary.{kind}]] #{i + 1} nodes")
            elif kind != "symmetry":
                raise SceneError(f"[[boundary.{kind}]] #{i + 1}: missing key 'nodes' (a table with "
                                 f"one of {', '.join(sorted(SELECTORS))})")
    if supports == "rigid" and any(boundary.get(k) for k in CONDITIONS):
        raise SceneError("[boundary] supports = 'rigid' is for free bodies: it removes exactly the "
                         "rigid motions, and the other boundary conditions of this scene already "
                         "remove some of them; drop one or the other")
    loads = data.get("loads", {})
    if "pressure" in loads:
        _number(loads["pressure"], "[loads] pressure")
    if "face_tractions" in loads:
        ft = loads["face_tractions"]
        if not isinstance(ft, dict):
            raise SceneError("[loads] face_tractions: expected a table {q_plus = ..., q_minus = ...}")
        _keys(ft, {"q_plus", "q_minus"}, "[loads] face_tractions")
    for kind, value_key in (("point_force", "force"), ("edge_load", "traction")):
        items = loads.get(kind, [])
        if not isinstance(items, list) or not all(isinstance(c, dict) for c in items):
            raise SceneError(f"[loads] {kind}: expected an array of tables ([[loads.{kind}]])")
        for i, item in enumerate(items):
            where = f"[[loads.{kind}]] #{i + 1}"
            _keys(item, {"nodes", value_key}, where)
            for k in ("nodes", value_key):
                if k not in item:
                    raise SceneError(f"{where}: missing key {k!r}")
            _check_selector(item["nodes"], f"{where} nodes")
    mesh = data.get("mesh", {})
    if "file" in mesh and not isinstance(mesh["file"], str):
        raise SceneError(f"[mesh] file: expected a path (string), got {mesh['file']!r}")
    return Scene(data, Path(base_dir), law, solver, source)


def _check_selector(sel, where):
    if not isinstance(sel, dict) or len(sel) != 1 or not set(sel) <= SELECTORS:
        raise SceneError(f"{where}: expected a table with exactly one of "
                         f"{', '.join(sorted(SELECTORS))}, got {sel!r}")


def load_scene(path):
    """Read and check a scene file (everything that does not need the mesh)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc.strerror})") from None
    return loads_scene(text, path.parent, source=str(path))


def loads_scene(text, base_dir=".", source="scene"):
    """Read and check a scene given as TOML text."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: not valid TOML: {exc}") from None
    return parse_scene(data, base_dir, source=source)


# ---------------------------------------------------------------------------
# fields on a mesh
# ---------------------------------------------------------------------------

def expression(text, where, X, N=None):
    """Values of an expression string at the points X (n, 3)."""
    import numexpr
    names = {"x": np.ascontiguousarray(X[:, 0]), "y": np.ascontiguousarray(X[:, 1]),
             "z": np.ascontiguousarray(X[:, 2]), "pi": np.pi}
    if N is not None:
        names.update(nx=np.ascontiguousarray(N[:, 0]), ny=np.ascontiguousarray(N[:, 1]),
                     nz=np.ascontiguousarray(N[:, 2]))
    try:
        v = numexpr.evaluate(text, local_dict=names, global_dict={})
    except Exception as exc:
        raise SceneError(f"{where}: cannot evaluate {text!r} ({type(exc).__name__}: {exc}); "
                         f"{EXPRESSION_HELP}") from None
    v = np.broadcast_to(np.asarray(v), (len(X),))
    if v.dtype != bool:
        v = v.astype(np.float64)
        bad = np.where(~np.isfinite(v))[0]
        if len(bad):
            raise SceneError(f"{where}: {text!r} is not finite at nodes {bad[:8].tolist()} "
                             f"(node {bad[0]} at {X[bad[0]].tolist()})")
    return v.copy()


def _flatten(value):
    if isinstance(value, list):
        return [y for x in value for y in _flatten(x)]
    return [value]


def nodal_field(value, where, surf, shape):
    """A field value (module docstring) as nodal values (n,) + shape.  A scalar
    for a 3x3 tensor means that multiple of the identity."""
    mesh = surf.mesh
    n, size = mesh.n_nodes, int(np.prod(shape))
    if isinstance(value, dict):
        _keys(value, {"array"}, where)
        name = value.get("array")
        try:
            arr, kind = surf.array(name)
        except KeyError as exc:
            raise SceneError(f"{where}: {exc.args[0]}") from None
        arr = np.asarray(arr, dtype=np.float64)
        rows = n if kind == "point" else mesh.n_triangles
        if arr.shape[0] != rows or arr.size != rows * size:
            raise SceneError(f"{where}: {kind} data {name!r} has shape {arr.shape}; expected "
                             f"({rows}, {size})" + (" (3x3 row-major)" if shape == (3, 3) else ""))
        arr = arr.reshape((rows,) + shape)
        bad = np.where(~np.all(np.isfinite(arr.reshape(rows, -1)), axis=1))[0]
        if len(bad):
            raise SceneError(f"{where}: {kind} data {name!r} is not finite at "
                             f"{'nodes' if kind == 'point' else 'triangles'} {bad[:8].tolist()}")
        return arr if kind == "point" else cells_to_nodes(mesh, arr)
    if not isinstance(value, list):
        s = _scalar(value, where, mesh)
        if shape == ():
            return s
        if shape == (3, 3):
            return s[:, None, None] * np.eye(3)
        raise SceneError(f"{where}: expected {size} entries (a list), got {value!r}")
    entries = _flatten(value)
    if len(entries) != size:
        raise SceneError(f"{where}: expected {size} entries"
                         + (" (3x3 row-major or nested)" if shape == (3, 3) else "")
                         + f", got {len(entries)}: {value!r}")
    cols = [_scalar(v, f"{where}[{i}]", mesh) for i, v in enumerate(entries)]
    return np.stack(cols, axis=1).reshape((n,) + shape)


def _scalar(value, where, mesh):
    if isinstance(value, str):
        return expression(value, where, mesh.vertices, mesh.normals)
    return np.full(mesh.n_nodes, _number(value, where))


# ---------------------------------------------------------------------------
# the scene
# ---------------------------------------------------------------------------

@dataclass
class Scene:
    data: dict
    base_dir: Path
    law: object
    solver: dict
    source: str = "scene"
    notes: list = field(default_factory=list)

    def table(self, name):
        return self.data.get(name, {})

    @property
    def membrane(self):
        """The membrane metric of the triangle engine ([shell] membrane)."""
        return self.table("shell").get("membrane", "dkt")

    @property
    def mesh_file(self):
        f = self.table("mesh").get("file")
        return None if f is None else (self.base_dir / f)

    @property
    def output(self):
        out = {"name": None, "format": "vtu", "picture": False, "faces": False, "solid": False}
        out.update(self.table("output"))
        out["format"] = out["format"].lstrip(".")
        return out

    def normal_function(self):
        """The [mesh] normal option as Mesh's ``normal`` argument."""
        spec = self.table("mesh").get("normal")
        if spec is None:
            return None
        entries = _flatten(spec) if isinstance(spec, list) else None
        if entries is None or len(entries) != 3:
            raise SceneError(f"[mesh] normal: expected 3 entries (numbers or expressions of "
                             f"x, y, z), got {spec!r}")

        def normal(X):
            return np.stack([np.full(len(X), _number(v, f"[mesh] normal[{i}]"))
                             if not isinstance(v, str) else expression(v, f"[mesh] normal[{i}]", X)
                             for i, v in enumerate(entries)], axis=1)
        return normal

    def read(self, path=None):
        """The scene's surface (or ``path``) with its data arrays."""
        path = self.mesh_file if path is None else Path(path)
        if path is None:
            raise SceneError(f"{self.source}: [mesh] file is not given")
        return read_surface(path, normal=self.normal_function())

    def thickness(self, mesh):
        th = self.table("shell")["thickness"]
        if isinstance(th, dict):
            return th["relative"] * float(np.ptp(mesh.vertices, axis=0).max())
        return float(th)

    def build(self, surf, growth=None, thickness=None, membrane=None):
        """The Shell of this scene on a surface (checks the arrays); returns
        (shell, description of the growth source).  growth: (G0, G1) nodal
        arrays, thickness: a number (coarse levels), membrane: a metric name,
        instead of the scene's."""
        sh = self.table("shell")
        h = self.thickness(surf.mesh) if thickness is None else thickness
        shell = Shell(surf.mesh, thickness=h, material=self.law,
                      level=sh.get("level", "consistent"), quadrature=sh.get("quadrature", 6),
                      membrane=self.membrane if membrane is None else membrane)
        G0, G1, source = self.growth(surf) if growth is None else (*growth, "carried from the input mesh")
        if G0 is not None:
            try:
                shell.set_growth(G0=G0, G1=G1)
            except ValueError as exc:
                raise SceneError(f"[growth] ({source}): {exc}") from None
        self._boundary(shell, surf)
        self._loads(shell, surf)
        return shell, source

    def solve(self, surf, shell, verbose=False):
        """Solve ``shell`` (this scene built on ``surf``) with the [solver]
        options; with ``nested = true`` by nested iteration
        (nested.solve_nested): the scene on meshes coarsened from the input,
        with its point data, its cell data (averaged to the nodes) and the
        input's nodal growth interpolated onto them, the thickness that of
        the input (a relative thickness is not re-measured on a coarse
        mesh).  Raises what Shell.solve raises."""
        options = dict(self.solver)
        if not options.pop("nested", False):
            return shell.solve(**options, verbose=verbose)
        from .nested import interpolate, solve_nested
        fine = surf.mesh
        data = dict(surf.point_data)
        for name, arr in surf.cell_data.items():
            arr = np.asarray(arr)
            if arr.dtype.kind in "biuf" and len(arr) == fine.n_triangles:
                data.setdefault(name, cells_to_nodes(fine, arr))
        G0, G1, _ = self.growth(surf)

        def build(mesh):
            if mesh is fine:
                return shell
            point = {name: interpolate(fine, arr, mesh.vertices) for name, arr in data.items()}
            growth = None if G0 is None else (interpolate(fine, G0, mesh.vertices),
                                               interpolate(fine, G1, mesh.vertices))
            return self.build(Surface(mesh, point), growth=growth, thickness=shell.h)[0]
        return solve_nested(build, fine, verbose=verbose, **options)

    def growth(self, surf):
        """(G0, G1, source) nodal arrays, or (None, None, "none")."""
        g = self.table("growth")
        mesh = surf.mesh
        if g.get("from_mesh_data"):
            have = set(surf.point_data) | set(surf.cell_data)
            if have & {"G0", "G1"}:
                g = {k: {"array": k} for k in ("G0", "G1") if k in have}
            elif have & {"abar", "bbar"}:
                g = {"abar": {"array": "abar"}, "bbar": {"array": "bbar"}}
            else:
                return None, None, "none (the mesh has no G0, G1, abar or bbar array)"
        if "abar" in g:
            forms = []
            for k in ("abar", "bbar"):
                spec = g[k]
                if not (isinstance(spec, dict) and set(spec) == {"array"}):
                    raise SceneError(f"[growth] {k}: expected {{array = \"NAME\"}} (cell data)")
                try:
                    arr, kind = surf.array(spec["array"])
                except KeyError as exc:
                    raise SceneError(f"[growth] {k}: {exc.args[0]}") from None
                if kind != "cell":
                    raise SceneError(f"[growth] {k}: {spec['array']!r} is point data; the target "
                                     "fundamental forms are cell data (one row per triangle)")
                forms.append(arr)
            try:
                G0c, G1c = from_fundamental_forms(mesh.vertices, mesh.triangles, mesh.normals, *forms)
            except ValueError as exc:
                raise SceneError(f"[growth] {exc}") from None
            return (cells_to_nodes(mesh, G0c), cells_to_nodes(mesh, G1c),
                    f"target fundamental forms (cell data {g['abar']['array']!r}, {g['bbar']['array']!r})")
        if "stretches" in g:
            s = nodal_field(g["stretches"], "[growth] stretches", surf, (3,))
            gz = (nodal_field(g["stretch_gradients"], "[growth] stretch_gradients", surf, (3,))
                  if "stretch_gradients" in g else None)
            d = nodal_field(g["direction"], "[growth] direction", surf, (3,)) if "direction" in g else None
            bad = np.where(~np.all(s > 0, axis=1))[0]
            if len(bad):
                raise SceneError(f"[growth] stretches: must be > 0, got {s[bad[0]].tolist()} at "
                                 f"node {bad[0]} (nodes {bad[:8].tolist()})")
            try:
                G0, G1 = from_stretches(mesh.normals, s, gz, d, frames=mesh.frames)
            except ValueError as exc:
                raise SceneError(f"[growth] {exc}") from None
            return G0, G1, "principal stretches"
        if "G0" in g or "G1" in g:
            G0 = nodal_field(g["G0"], "[growth] G0", surf, (3, 3)) if "G0" in g else np.eye(3)
            G1 = nodal_field(g["G1"], "[growth] G1", surf, (3, 3)) if "G1" in g else np.zeros((3, 3))
            src = ", ".join(f"{k} " + (f"(array {g[k]['array']!r})" if isinstance(g[k], dict) else "(given)")
                            for k in ("G0", "G1") if k in g)
            return G0, G1, f"tensors {src}"
        return None, None, "none"

    def select(self, sel, where, surf):
        """Node indices of a selector table."""
        mesh = surf.mesh
        (kind, arg), = sel.items()
        if kind == "loop":
            loops = mesh.boundary_loops()
            if not loops:
                raise SceneError(f"{where}: the mesh has no boundary (a closed surface)")
            if arg == "all":
                nodes = mesh.boundary_nodes()
            elif arg == "longest":
                nodes = max(loops, key=lambda lp: np.linalg.norm(
                    np.diff(mesh.vertices[np.r_[lp, lp[:1]]], axis=0), axis=1).sum())
            elif isinstance(arg, int) and not isinstance(arg, bool) and 0 <= arg < len(loops):
                nodes = loops[arg]
            else:
                raise SceneError(f"{where}: loop = {arg!r}; expected 'all', 'longest' or an index "
                                 f"0..{len(loops) - 1} (the mesh has {len(loops)} boundary loops)")
        elif kind == "plane":
            if not isinstance(arg, dict):
                raise SceneError(f"{where}: plane: expected {{axis = \"x\", value = 0.0}}")
            _keys(arg, {"axis", "value", "tol"}, f"{where} plane")
            if arg.get("axis") not in ("x", "y", "z"):
                raise SceneError(f"{where} plane: axis must be 'x', 'y' or 'z', got {arg.get('axis')!r}")
            tol = _number(arg["tol"], f"{where} plane.tol", positive=True) if "tol" in arg else None
            nodes = mesh.nodes_on_plane(arg["axis"], _number(arg.get("value", 0.0), f"{where} plane.value"),
                                        tol=tol)
        elif kind == "near":
            p = _flatten(arg) if isinstance(arg, list) else []
            if len(p) != 3:
                raise SceneError(f"{where}: near: expected a point [x, y, z], got {arg!r}")
            p = np.array([_number(v, f"{where} near") for v in p])
            nodes = np.array([int(np.argmin(np.linalg.norm(mesh.vertices - p, axis=1)))])
        elif kind == "mask":
            try:
                arr, where_kind = surf.array(arg)
            except KeyError as exc:
                raise SceneError(f"{where}: {exc.args[0]}") from None
            if where_kind != "point" or np.asarray(arr).shape not in ((mesh.n_nodes,), (mesh.n_nodes, 1)):
                raise SceneError(f"{where}: mask {arg!r} must be point data of shape "
                                 f"({mesh.n_nodes},), got {where_kind} data of shape {np.asarray(arr).shape}")
            nodes = np.where(np.asarray(arr).ravel() != 0)[0]
        else:   # where
            if not isinstance(arg, str):
                raise SceneError(f"{where}: where: expected an expression (string), got {arg!r}")
            mask = expression(arg, f"{where} where", mesh.vertices, mesh.normals)
            nodes = np.where(mask != 0)[0]
        if not len(nodes):
            raise SceneError(f"{where}: {kind} = {arg!r} selects no node")
        return nodes

    def _boundary(self, shell, surf):
        b = self.table("boundary")
        for kind in CONDITIONS:
            for i, cond in enumerate(b.get(kind, [])):
                where = f"[[boundary.{kind}]] #{i + 1}"
                kwargs = dict(cond)
                if "nodes" in kwargs:
                    kwargs["nodes"] = self.select(cond["nodes"], f"{where} nodes", surf)
                try:
                    getattr(shell, kind)(**kwargs)
                except (ValueError, TypeError) as exc:
                    raise SceneError(f"{where}: {exc}") from None
        if b.get("supports", "none") == "rigid":
            shell.remove_rigid_motions()

    def _loads(self, shell, surf):
        loads = self.table("loads")
        if "pressure" in loads:
            shell.pressure(loads["pressure"])
        if "face_tractions" in loads:
            q = {k: nodal_field(v, f"[loads] face_tractions.{k}", surf, (3,))
                 for k, v in loads["face_tractions"].items()}
            shell.face_tractions(**q)
        for kind, key in (("point_force", "force"), ("edge_load", "traction")):
            for i, item in enumerate(loads.get(kind, [])):
                where = f"[[loads.{kind}]] #{i + 1}"
                nodes = self.select(item["nodes"], f"{where} nodes", surf)
                vec = _flatten(item[key]) if isinstance(item[key], list) else []
                if len(vec) != 3:
                    raise SceneError(f"{where} {key}: expected a vector [x, y, z], got {item[key]!r}")
                if kind == "point_force":
                    value = [_number(v, f"{where} {key}[{j}]") for j, v in enumerate(vec)]
                else:
                    def value(Xm, vec=vec, where=where):
                        return np.stack([expression(v, f"{where} {key}[{j}]", Xm) if isinstance(v, str)
                                         else np.full(len(Xm), _number(v, f"{where} {key}[{j}]"))
                                         for j, v in enumerate(vec)], axis=1)
                try:
                    getattr(shell, kind)(nodes, value)
                except ValueError as exc:
                    raise SceneError(f"{where}: {exc}") from None
