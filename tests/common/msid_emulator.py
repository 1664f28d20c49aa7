"""Cross builds: the pytest harnesses run the target's executables through an emulator.

MSID_EMULATOR is the command prefix that runs one of the target's executables on this machine, e.g.
"qemu-aarch64 -L /usr/aarch64-linux-gnu -E LD_LIBRARY_PATH=/usr/aarch64-linux-gnu/lib" (a cross build's ctest sets it from CMAKE_CROSSCOMPILING_EMULATOR;
docs/target.md "Linux bench controller"). Each binary named by MSID_BIN, MSID_DEVSIM or MSID_CANDUMP_COPY
is then replaced, in this process's environment, by a two-line shell script that execs it through the
emulator: every caller runs it unchanged, the tests as well as msid itself when it starts the msid-devsim
named by MSID_DEVSIM (the machine has no binfmt_misc, so a foreign executable cannot be exec'd directly).
Without MSID_EMULATOR nothing changes.
"""
import atexit
import os
import shlex
import shutil
import tempfile

BINARIES = ("MSID_BIN", "MSID_DEVSIM", "MSID_CANDUMP_COPY")


def _is_script(path):
    with open(path, "rb") as f:
        return f.read(2) == b"#!"


def wrap_binaries(keys=BINARIES, emulator="MSID_EMULATOR", env=None):
    """Point the binaries that the variables `keys` of `env` (default os.environ) name at scripts that run
    them through the prefix in the variable `emulator`; returns the prefix (a list, empty when unset).
    tests/modbus/test_mb_cross_arch.py wraps another build's binaries with MSID_OTHER_EMULATOR."""
    env = os.environ if env is None else env
    emu = shlex.split(env.get(emulator, ""))
    if not emu:
        return []
    if shutil.which(emu[0]) is None:
        raise RuntimeError(f"{emulator}={env[emulator]!r}: {emu[0]} is not on PATH "
                           "(scripts/deps.sh cross-arm64 or cross-armhf installs qemu-user)")
    d = None
    for key in keys:
        b = env.get(key)
        if not b or not os.path.isfile(b) or _is_script(b):   # unset, a test's stand-in, or wrapped already
            continue
        if d is None:
            d = tempfile.mkdtemp(prefix="msid-emulated-")
            atexit.register(shutil.rmtree, d, True)
        w = os.path.join(d, os.path.basename(b))
        with open(w, "w", encoding="utf-8") as f:
            f.write("#!/bin/sh\nexec " + " ".join(shlex.quote(a) for a in emu + [os.path.abspath(b)]) + ' "$@"\n')
        os.chmod(w, 0o755)
        env[key] = w
    return emu
