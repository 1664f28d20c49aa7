"""Helpers of the robustness tests (tests/python/test_py_*.py): a child interpreter that runs
one script against the staged package with a bound on its time (a hang detector, not a speed claim),
and msid-devsim over Modbus TCP on 127.0.0.1 (tests/modbus/mblib.py)."""
import os
import subprocess
import sys
import textwrap
from pathlib import Path

HERE = Path(__file__).resolve().parent
PKG = os.environ.get("MSID_PYTHON_DIR") or str(HERE.parents[1] / "tools" / "python")
# a child that has not ended in this long hangs (a run of the scripts here takes seconds)
BOUND_S = float(os.environ.get("MSID_CHILD_BOUND_S", "240"))

DESIGN = dict(period=256, lines="1:3:120", amplitudes=0.2, seed=7, inputs=2, experiments=2)


def run_child(script, *args, bound=BOUND_S, preexec=None):
    """Run `script` (dedented) in a fresh interpreter with the package on its path; returns the
    CompletedProcess. TimeoutExpired is the failure of a test that hangs."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([PKG, str(HERE)]), PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run([sys.executable, "-c", textwrap.dedent(script), *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=bound, preexec_fn=preexec)


def sim_module():
    """tests/modbus/mblib.py (the simulator's harness), or skip when ctest did not name the binaries."""
    import pytest
    if not (os.environ.get("MSID_BIN") and os.environ.get("MSID_DEVSIM")):
        pytest.skip("MSID_BIN and MSID_DEVSIM not set (ctest sets them)")
    sys.path.insert(0, str(HERE.parent / "modbus"))
    import mblib
    return mblib


def small_case(period=64, lines="1:3:20"):
    """A one-input design of 6 periods and its record [u1, y1] (y = 0.7 u + noise, seed 1): the small
    case of the robustness tests."""
    import numpy as np
    import msid
    d = msid.design(period=period, lines=lines, amplitudes=0.5, seed=3, periods=6)
    u = d.samples(0, 6)
    y = 0.7 * u[:, 0] + 0.01 * np.random.default_rng(1).standard_normal(len(u))
    return d, np.column_stack([u[:, 0], y])


def quiet(call, *args, **kwargs):
    """call(*args, **kwargs) with msid's notes (NoteWarning, ConvergenceWarning) silenced."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return call(*args, **kwargs)


def small_frf(period=64, lines="1:3:20"):
    """small_case() and its FRF: (design, record, FRF)."""
    import msid
    d, rec = small_case(period, lines)
    return d, rec, quiet(msid.frf, rec, design=d)
