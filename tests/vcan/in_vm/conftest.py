"""In-VM CAN tests: run by tests/vcan/run_tests.py inside the qemu guest (real SocketCAN, vcan0
with MTU 72 and vcan1 with MTU 16). They refuse to run where there is no vcan0."""
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope="session", autouse=True)
def _environment():
    for k in ("MSID_BIN", "MSID_DEVSIM"):
        if not os.environ.get(k) or not os.access(os.environ[k], os.X_OK):
            pytest.fail(f"{k} must name an executable (ctest sets it)")
    if not Path("/sys/class/net/vcan0").exists():
        pytest.fail("no vcan0: these tests run inside the VM (tests/vcan/run_tests.py)")
