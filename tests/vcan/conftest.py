import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))
import msid_emulator  # noqa: E402
msid_emulator.wrap_binaries()   # cross builds: MSID_EMULATOR runs the binaries (tests/common/msid_emulator.py)
