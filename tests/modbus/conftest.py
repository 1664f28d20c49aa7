import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))
import msid_emulator  # noqa: E402
msid_emulator.wrap_binaries()   # cross builds: MSID_EMULATOR runs the binaries (tests/common/msid_emulator.py)
msid_emulator.wrap_binaries(("MSID_OTHER_BIN", "MSID_OTHER_DEVSIM"), "MSID_OTHER_EMULATOR")   # test_mb_cross_arch
