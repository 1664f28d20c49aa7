"""Fixtures of the Python package tests: one demo measurement (msid demo: 2x2 plant, 2 experiments,
coloured noise, noisy inputs) with an ml fit and an order scan, made once per test session."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT / "tests" / "integration"))
# the package from the source tree; the compiled module's tests name the staged package instead
# (MSID_PYTHON_DIR=build/python: the .py files beside msid/_msid*.so)
sys.path.insert(0, os.environ.get("MSID_PYTHON_DIR") or str(ROOT / "tools" / "python"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))
import msid_emulator  # noqa: E402
from no_process import refuse_processes  # noqa: E402,F401
from keyword_messages import keyword_messages  # noqa: E402,F401  (the fixture, for _keyword_messages)
msid_emulator.wrap_binaries()   # cross builds: MSID_EMULATOR runs the binaries (tests/common/msid_emulator.py)


@pytest.fixture(autouse=True)
def _keyword_messages(request):
    """The compiled module's tests (test_ext_*): each bad-input case's message names keywords, never
    flags (keyword_messages.py)."""
    if not request.module.__name__.split(".")[-1].startswith("test_ext_"):
        yield
        return
    yield request.getfixturevalue("keyword_messages")


def msid(*args, cwd=None, check=True):
    b = os.environ.get("MSID_BIN")
    if not b:
        pytest.skip("MSID_BIN not set (ctest sets it)")
    r = subprocess.run([b] + [str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=600)
    if check:
        assert r.returncode == 0, f"msid {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stderr}"
    return r


@pytest.fixture(scope="session")
def demo(tmp_path_factory):
    """Directory with frf.json, truth.json, model.json (ml order 4) and auto.json (ml --order auto)."""
    d = tmp_path_factory.mktemp("demo")
    msid("demo", "--out", d, "--quiet", "--seed", "7")
    msid("fit", "--method", "ml", "--order", "4", d / "frf.json", "-o", d / "model.json")
    msid("fit", "--method", "ml", "--order", "auto", d / "frf.json", "-o", d / "auto.json")
    return d


@pytest.fixture(scope="session")
def siso(demo, tmp_path_factory):
    """The y1/u1 path of the demo (FRF.subsystem, written by the package) with an ml fit of it (model.json):
    the small case of the rendering tests (a 1x1 figure draws four times faster than the 2x2)."""
    import msid as pkg
    d = tmp_path_factory.mktemp("siso")
    pkg.write_frf(d / "frf.json", pkg.read_frf(demo / "frf.json").subsystem([0], [0]))
    msid("fit", "--method", "ml", "--order", "4", d / "frf.json", "-o", d / "model.json")
    return d
