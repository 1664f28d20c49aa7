"""pytest configuration of the integration tests.

Run through ctest (label `integration`), or by hand:
  PYTHONDONTWRITEBYTECODE=1 MSID_BIN=<build>/tools/msid \
    python3 -m pytest -q -p no:cacheprovider tests/integration
A cross build's msid runs through MSID_EMULATOR (the prefix of cmake/linux-cross.cmake, e.g.
"qemu-aarch64 -L /usr/aarch64-linux-gnu -E LD_LIBRARY_PATH=/usr/aarch64-linux-gnu/lib").
"""
import sys
from pathlib import Path

import pytest

_here = Path(__file__).resolve().parent
for p in (_here, _here.parent.parent / "tools" / "python"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))
import msid_emulator  # noqa: E402
msid_emulator.wrap_binaries()   # cross builds: MSID_EMULATOR runs the binaries (tests/common/msid_emulator.py)

import helpers  # noqa: E402


@pytest.fixture(scope="session", autouse=True)
def _msid_available():
    helpers.msid_bin()   # fails clearly when MSID_BIN is not set
