"""Bad configurations: each gets one clear message, a non-zero exit status and no output files."""
import shutil
import tempfile
from pathlib import Path

import pytest

import canlib as c


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), lines="1:2:41")


def fails(tmp, r, code, *needles):
    c.fails(tmp, r, code, *needles, absent=("run.log",))


def test_unknown_interface(design, tmp_path):
    r = c.measure(tmp_path, design, "--log", tmp_path / "run.log", iface="vcan9", ok=False)
    fails(tmp_path, r, 1, "no CAN interface 'vcan9'")


def test_fd_on_a_classic_interface(design, tmp_path):
    r = c.measure(tmp_path, design, "--fd", iface="vcan1", ok=False)
    fails(tmp_path, r, 1, "does not carry CAN FD", "mtu 72")


def test_rate_the_bus_cannot_carry(design, tmp_path):
    with c.Sim(tmp_path) as sim:
        r = c.measure(tmp_path, design, "--rate", 10000, "--bitrate", 500000, "--log", tmp_path / "run.log", ok=False)
        fails(tmp_path, r, 1, "the bus cannot carry 4 channels at 10000 Hz", "20000 frames/s")
        # 2 kHz: 4000 frames/s * 135 bits = 0.54 Mbit/s fits 1 Mbit/s
        ok = c.measure(tmp_path, design, "--rate", 2000, "--bitrate", 1000000, "--periods", 3)
    assert ok.doc["fs_hz"] == 2000 and ok.doc["acquisition"]["rate_hz"] == 2000
    # The device paces itself: checked by what it reports, never by wall-clock time (the
    # stream time was 1.57 s against 0.77 s nominal on a loaded machine). It ran at the uploaded 2 kHz,
    # every sample went through its pacer (it waited for the sample's deadline, or found it already
    # passed on a loaded machine) and none was sent before its deadline. The unpaced control (--rate 0)
    # shows the counts are not vacuous: there no sample goes through the pacer.
    rep = sim.report()
    assert rep["rate_hz"] == 2000 and rep["samples"] == 2 * 3 * 256, rep
    assert rep["paced_waits"] + rep["late_samples"] >= rep["samples"] and rep["early_samples"] == 0, rep
    (tmp_path / "unpaced").mkdir()
    with c.Sim(tmp_path / "unpaced") as sim:
        c.measure(tmp_path / "unpaced", design, "--periods", 3)
    rep = sim.report()
    assert rep["rate_hz"] == 0 and rep["samples"] == 2 * 3 * 256, rep
    assert rep["paced_waits"] == rep["late_samples"] == rep["early_samples"] == 0, rep


def test_no_permission(design):
    """As an unprivileged user, a receive buffer above net.core.rmem_max needs CAP_NET_ADMIN."""
    d = Path(tempfile.mkdtemp())   # TMPDIR: world-writable tmpfs in the VM
    d.chmod(0o777)
    shutil.copy(design, d / "design.json")
    (d / "design.json").chmod(0o644)
    r = c.run("can", "measure", "--iface", "vcan0", "--design", d / "design.json", "--rcvbuf", 8 << 20,
              "-o", d / "frf.json", user=65534)
    fails(d, r, 1, "no permission", "CAP_NET_ADMIN")


def test_protocol_version_mismatch(design, tmp_path):
    with c.Sim(tmp_path, "--protocol-version", 2):
        r = c.measure(tmp_path, design, ok=False)
    fails(tmp_path, r, 1, "protocol version mismatch", "msid-can/2", "msid-can/1")


def test_no_device(design, tmp_path):
    r = c.measure(tmp_path, design, ok=False)
    fails(tmp_path, r, 1, "no msid-can device answered at base 0x200 on vcan0")


@pytest.mark.parametrize("args,msg", [
    (["--base", "0x201"], "--base must be a multiple of 0x80"),
    (["--encoding", "int8"], "--encoding must be int16 or float32"),
    (["--rate", "1.5"], "--rate must be a whole number"),
    (["--window", "0"], "--window must be"),
    (["--periods", "1"], "--periods must be"),
])
def test_bad_options(design, tmp_path, args, msg):
    r = c.measure(tmp_path, design, *args, ok=False)
    fails(tmp_path, r, 2, msg)


def test_device_refuses_a_design_for_other_inputs(tmp_path):
    d = c.excite(tmp_path, inputs=1, experiments=1, lines="1:2:9")
    with c.Sim(tmp_path):
        r = c.measure(tmp_path, d, ok=False)
    fails(tmp_path, r, 1, "the device has 2 input(s) but the design has 1")
