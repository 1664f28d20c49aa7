"""The package's shape (docs/python.md): one module per concept without import cycles, each importable
alone; __all__ holding the public API only; type hints on every public function and method with a
py.typed marker in the source, the staged and the installed package; a repr that says what each public
class holds. Needs NumPy only (no compiled module)."""
import ast
import importlib
import inspect
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import msid
from msid import types as mtypes

PKG = Path(msid.__file__).resolve().parent
SRC = Path(__file__).resolve().parents[2] / "tools" / "python" / "msid"
MODULES = sorted(p.stem for p in SRC.glob("*.py") if p.stem != "__init__")
# every module of the package: each public function and method carries type hints
TYPED = MODULES


def _package_imports(path):
    """The package modules `path` imports, anywhere in the file (a function-level import is a
    dependency too), as module names within the package."""
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                out.add(node.module.split(".")[0])
            else:
                out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("msid."):
            out.add(node.module.split(".")[1])
    return out - {"_msid"}


def test_no_import_cycle():
    """The package's import graph (module- and function-level imports alike) has no cycle; in
    particular compute, files and types do not import each other both ways."""
    graph = {m: _package_imports(SRC / f"{m}.py") & set(MODULES) for m in MODULES}
    state = {}

    def visit(m, path):
        if state.get(m) == "done":
            return
        assert state.get(m) != "open", f"import cycle: {' -> '.join(path + [m])}"
        state[m] = "open"
        for d in sorted(graph[m]):
            visit(d, path + [m])
        state[m] = "done"
    for m in MODULES:
        visit(m, [])
    # the layering the docs describe
    assert "compute" not in graph["files"] and "compute" not in graph["types"]
    assert "files" not in graph["types"]
    assert graph["_compiled"] == set() and graph["regions"] == set()


def test_cycle_check_catches_a_cycle(tmp_path):
    """Negative control: the graph walk above names a cycle made of a function-level import."""
    (tmp_path / "a.py").write_text("from . import b\n")
    (tmp_path / "b.py").write_text("def f():\n    from .a import x\n")
    assert _package_imports(tmp_path / "a.py") == {"b"} and _package_imports(tmp_path / "b.py") == {"a"}


@pytest.mark.parametrize("name", MODULES + ["__init__"])
def test_each_module_imports_alone(name):
    """Each module imported first and alone in a fresh interpreter: the package's __init__ (which
    imports every module) is replaced by an empty package, so the module must import what it needs
    itself, and no module of a higher layer may come with it (types and files never load compute);
    the compiled module is loaded on the first call that needs it, not on import."""
    target = "msid" if name == "__init__" else f"msid.{name}"
    stub = "" if name == "__init__" else (
        "import types as t; p = t.ModuleType('msid'); p.__path__ = [%r]; sys.modules['msid'] = p\n" % str(PKG))
    code = (f"import sys, importlib\n{stub}importlib.import_module({target!r})\n"
            "print(' '.join(sorted(m for m in sys.modules if m.startswith('msid.'))))")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(PKG.parent)] + sys.path), MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    loaded = set(r.stdout.split())
    if name in ("types", "files", "regions", "_args", "_compiled"):
        assert "msid.compute" not in loaded, loaded
    if name in ("types", "regions", "_args", "_compiled"):
        assert "msid.files" not in loaded, loaded
    if name in ("regions", "_compiled"):
        assert loaded == {f"msid.{name}"}, loaded
    assert "msid._msid" not in loaded, loaded


def test_all_is_the_public_api():
    """__all__ names what docs/python.md documents, every name resolves, and the document plumbing
    (frf_from_doc, frf_to_doc, model_to_doc) is not in it, though its module still has it."""
    for n in msid.__all__:
        assert getattr(msid, n) is not None, n
        assert not n.startswith("_"), n
    for n in ("frf_from_doc", "frf_to_doc", "model_to_doc", "FRF_FORMAT", "MODEL_FORMAT"):
        assert n not in msid.__all__
    from msid.files import frf_from_doc, frf_to_doc, model_to_doc  # noqa: F401  (internal use)
    for n in ("frf", "lpm", "etfe", "fit", "validate", "modes", "FRF", "Model", "Validation", "Modes", "read_frf",
              "write_frf", "read_model", "write_model", "import_frf", "export", "design", "Design", "Measurement",
              "measure"):
        assert n in msid.__all__, n
    assert len(set(msid.__all__)) == len(msid.__all__)
    # each module's __all__ holds only names it has and that are public
    for m in ("types", "files", "compute"):
        mod = importlib.import_module(f"msid.{m}")
        for n in mod.__all__:
            assert hasattr(mod, n) and not n.startswith("_"), (m, n)
    # the data types are defined in msid.types, whatever module re-exports them
    for n in ("FRF", "Model", "Validation", "Modes", "FormatError"):
        assert getattr(msid, n).__module__ == "msid.types", n


def _public_callables(mod):
    """(qualified name, function) of the public functions of `mod` and the public methods and
    properties of its public classes (defined there), __init__ included."""
    for n, obj in vars(mod).items():
        if n.startswith("_") or getattr(obj, "__module__", None) != mod.__name__:
            continue
        if inspect.isfunction(obj):
            yield n, obj
        elif inspect.isclass(obj) and not issubclass(obj, BaseException):
            for a, v in vars(obj).items():
                if a.startswith("_") and a != "__init__":
                    continue
                if isinstance(v, property):
                    v = v.fget
                elif isinstance(v, (classmethod, staticmethod)):
                    v = v.__func__
                if inspect.isfunction(v):
                    yield f"{n}.{a}", v


def _missing_hints(fn):
    sig = inspect.signature(fn)
    miss = [p.name for k, p in enumerate(sig.parameters.values())
            if p.annotation is inspect.Parameter.empty and not (k == 0 and p.name in ("self", "cls"))]
    if sig.return_annotation is inspect.Signature.empty:
        miss.append("return")
    return miss


@pytest.mark.parametrize("name", TYPED)
def test_type_hints(name):
    """Every public function and method (properties' getters too) has annotated parameters and return."""
    mod = importlib.import_module(f"msid.{name}")
    bad = {q: m for q, fn in _public_callables(mod) if (m := _missing_hints(fn))}
    assert not bad, f"msid.{name}: without type hints: {bad}"
    # and every hint names something: a type checker resolves the same strings
    import typing
    for q, fn in _public_callables(mod):
        typing.get_type_hints(fn)


def test_type_hint_check_catches_a_gap():
    """Negative control: a function without a return hint, a method with an unannotated parameter."""
    def f(x: int):
        return x

    class C:
        def g(self, y) -> None:
            pass
    assert _missing_hints(f) == ["return"] and _missing_hints(C.g) == ["y"]


def test_py_typed_marker():
    """py.typed (PEP 561) beside the modules: in the source, in the staged package (build/python, when
    the compiled module's build staged it) and in what `pip install` and `cmake --install` copy."""
    assert (SRC / "py.typed").is_file()
    staged = os.environ.get("MSID_PYTHON_STAGE") or os.environ.get("MSID_PYTHON_DIR")
    if staged:
        assert (Path(staged) / "msid" / "py.typed").is_file()
    root = SRC.parents[2]
    stage_rule = (root / "tools" / "python" / "CMakeLists.txt").read_text()
    assert "py.typed" in stage_rule
    # cmake --install copies the package directory whole, pip (scikit-build-core) the package "msid"
    assert "install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/python/msid" in (root / "cmake" / "msidInstall.cmake").read_text()
    assert 'wheel.packages = ["msid"]' in (root / "tools" / "python" / "pyproject.toml").read_text()


def _frf(ny=2, nu=2, L=200, P=400, h=0.001, method=None):
    bins = np.arange(1, L + 1)
    meta = {"period_samples": P, "sample_time": h, "fs_hz": 1 / h}
    if method:
        meta["method"] = method
    return mtypes.FRF(np.ones((L, ny, nu)), bins / P, bins=bins, freq_hz=bins / P / h, meta=meta)


def test_frf_repr():
    """repr(FRF): the shape, the number of lines, the frequency range in its unit and the estimator."""
    assert repr(_frf()) == "<FRF 2x2, 200 lines 2.5–500 Hz, periodic>"
    assert repr(_frf(1, 3, 10, method="lpm")) == "<FRF 1x3, 10 lines 2.5–25 Hz, lpm>"
    g = mtypes.FRF(np.ones((3, 1, 1)), [0.1, 0.2, 0.3])
    assert repr(g) == "<FRF 1x1, 3 lines 0.1–0.3 cycles/sample, periodic>"
    ct = mtypes.FRF(np.ones((2, 1, 1)), [0, 0], omega=[2 * np.pi, 4 * np.pi],
                    meta={"domain": "ct", "imported": {"format": "touchstone"}, "period_samples": 0})
    assert repr(ct) == "<FRF 1x1, 2 lines 1–2 Hz, ct, imported (touchstone)>"
    one = mtypes.FRF(np.ones((1, 1, 1)), [0.25])
    assert repr(one) == "<FRF 1x1, 1 line at 0.25 cycles/sample, periodic>"


def _model(structure=None, n=4, ny=2, nu=1, method="ml", domain="dt"):
    doc = {"format": "msid-model/1", "order": n, "n_inputs": nu, "n_outputs": ny, "method": method, "domain": domain,
           "A": np.eye(n).tolist(), "B": np.ones((n, nu)).tolist(), "C": np.ones((ny, n)).tolist(),
           "D": np.zeros((ny, nu)).tolist(), "sample_time": 0.001}
    if structure:
        doc[structure] = {}
    return mtypes.Model(doc)


def test_model_repr():
    """repr(Model): the method, the order, the structure (state space unless the file says), ny x nu and the domain."""
    assert repr(_model()) == "<Model ml, order 4, state space, 2x1, dt>"
    assert repr(_model("pole_residue", 2, 1, 1, "ml", "ct")) == "<Model ml, order 2, pole-residue, 1x1, ct>"
    assert repr(_model("lmfd", 3, 1, 2, "lmfd")) == "<Model lmfd, order 3, LMFD, 1x2, dt>"
    assert " object at 0x" not in repr(_model())


def test_every_public_class_has_a_repr():
    """No public class of the package keeps object's repr (<... object at 0x...>): each defines its own."""
    for n in msid.__all__:
        obj = getattr(msid, n)
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            assert "__repr__" in vars(obj), f"msid.{n} has no repr of its own"
    v = mtypes.Validation({"report": {"cost": 1.0, "dof": 10, "p_value": 0.5, "expected": 5.0}, "text": [],
                           "consistent": True})
    assert repr(v).startswith("<msid.Validation cost 1")
    m = mtypes.Modes({"report": {"model": "m.json", "modes": [{}]}, "text": ""})
    assert repr(m) == "<msid.Modes 1 mode(s) of m.json>"


def test_what_needs_the_compiled_module(tmp_path, monkeypatch):
    """The package docstring's claim, checked without the compiled module: msid-frf/1 and msid-model/1
    files are read and written with NumPy only; another tool's FRF (.s2p, .uff, .unv, .csv, .mat) and the
    estimators raise the ImportError that says how to build msid._msid, and the docstring names those
    formats as needing it."""
    from msid import _compiled
    monkeypatch.setattr(_compiled, "_MODULE", None)
    monkeypatch.setitem(sys.modules, "msid._msid", None)   # import msid._msid now fails
    f = _frf()
    msid.write_frf(tmp_path / "f.json", f)
    g = msid.read_frf(tmp_path / "f.json")
    assert np.array_equal(g.G, f.G)
    m = _model()
    msid.write_model(tmp_path / "m.json", m)
    assert np.array_equal(msid.read_model(tmp_path / "m.json").A, m.A)
    for name in ("dut.s2p", "modal.uff", "modal.unv", "frf.csv", "idfrd.mat"):
        (tmp_path / name).write_text("x\n")
        with pytest.raises(ImportError, match="compiled extension msid._msid"):
            msid.read_frf(tmp_path / name)
    with pytest.raises(ImportError, match="compiled extension msid._msid"):
        msid.lpm(np.zeros((8, 2)), n_inputs=1)
    doc = " ".join(msid.__doc__.split())
    for ext in (".sNp", ".uff", ".csv", ".mat"):
        assert ext in doc
    assert "need NumPy only" in doc and "compiled module" in doc
