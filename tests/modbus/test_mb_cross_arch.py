"""Modbus TCP across architectures (docs/target.md "Linux bench controller"): this build's msid and
msid-devsim against another architecture's, over 127.0.0.1. A cross build (scripts/cross_test.sh)
registers it with the x86-64 build as the other one, so the aarch64 (or armhf) binaries run under
qemu-user: the x86-64 `msid modbus measure` against the emulated msid-devsim, and the emulated msid
against the x86-64 msid-devsim. Each mixed run's FRF must equal both same-architecture runs' bit for bit
(the device's samples and noise come from msid_rng and the plant in C without fused multiply-add; the
host's streaming line DFT adds them in sample order; the FFT path, FFTW's codelets differing by CPU,
is held to 1e-12 in tests/integration/test_cross_arch.py instead). MSID_OTHER_BIN and MSID_OTHER_DEVSIM name the other build's binaries,
MSID_OTHER_EMULATOR its emulator prefix if it needs one (tests/common/msid_emulator.py)."""
import os

import pytest

import mblib as c

OWN = (c.MSID, c.DEVSIM)
OTHER = (os.environ.get("MSID_OTHER_BIN", ""), os.environ.get("MSID_OTHER_DEVSIM", ""))
assert all(OTHER), "MSID_OTHER_BIN and MSID_OTHER_DEVSIM must name the other architecture's binaries"
RUNS = {"own": (OWN[0], OWN[1]), "other": (OTHER[0], OTHER[1]),
        "own msid, other device": (OWN[0], OTHER[1]), "other msid, own device": (OTHER[0], OWN[1])}


@pytest.fixture(scope="module")
def docs(tmp_path_factory):
    design = c.excite(tmp_path_factory.mktemp("design"), lines="1:60", periods=4)
    out = {}
    mp = pytest.MonkeyPatch()
    try:
        for name, (msid, devsim) in RUNS.items():
            mp.setattr(c.canlib, "MSID", msid)
            mp.setattr(c, "DEVSIM", devsim)
            tmp = tmp_path_factory.mktemp(name.replace(" ", "").replace(",", "-"))
            with c.Sim(tmp, "--seed", 29) as sim:
                out[name] = c.measure(tmp, sim, design, "--dft", "stream").doc
    finally:
        mp.undo()
    return out


@pytest.mark.parametrize("name", ["own msid, other device", "other msid, own device"])
def test_mixed_equals_same_architecture(docs, name):
    assert c.frf_equal(docs[name], docs["own"]), f"{name}: the FRF differs from this architecture's own run"
    assert c.frf_equal(docs[name], docs["other"]), f"{name}: the FRF differs from the other architecture's run"


def test_negative_control(docs):
    """One ulp more in one FRF value: frf_equal tells the documents apart."""
    import copy
    import math
    d = copy.deepcopy(docs["own"])
    assert c.frf_equal(d, docs["own"])
    G = d["lines"][1]["G"]["re"]
    G[0][0] = math.nextafter(G[0][0], math.inf)
    assert not c.frf_equal(d, docs["own"]), "a one-ulp change went unseen"
