"""Bad configurations: each gets one clear message, a non-zero exit status and no output file."""
import os

import pytest

import mblib as c


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), lines="1:2:41", periods=3)


class NoSim:
    link = ["--tcp", "127.0.0.1:9"]      # discard port: nothing listens


def test_nothing_listening(design, tmp_path):
    r = c.measure(tmp_path, NoSim(), design, ok=False)
    c.fails(tmp_path, r, 1, "cannot connect to 127.0.0.1:9")


def test_no_serial_port(design, tmp_path):
    class Bad:
        link = ["--rtu", str(tmp_path / "ttyNONE")]
    r = c.measure(tmp_path, Bad(), design, ok=False)
    c.fails(tmp_path, r, 1, "cannot open the serial port", "ttyNONE")


def test_rtu_rate_the_line_cannot_carry(design, tmp_path):
    with c.Sim(tmp_path, rtu=True) as sim:
        r = c.measure(tmp_path, sim, design, "--rate", 2000, ok=False)
        c.fails(tmp_path, r, 1, "the link cannot carry 4 channels at 2000 Hz", "10000 registers/s",
                "115200 baud, from the framing")
        ok = c.measure(tmp_path, sim, design, "--rate", 500)      # 2500 registers/s fits
    assert ok.doc["fs_hz"] == 500 and ok.doc["acquisition"]["samples_lost"] == 0


def test_tcp_rate_beyond_the_measured_link(design, tmp_path):
    with c.Sim(tmp_path) as sim:
        r = c.measure(tmp_path, sim, design, "--rate", 3000000000, "--encoding", "float32", ok=False)
    c.fails(tmp_path, r, 1, "the link cannot carry 4 channels", "measured with 125-register reads")


def test_device_refuses_a_design_for_other_inputs(tmp_path):
    d = c.excite(tmp_path, inputs=1, experiments=1, lines="1:2:9")
    with c.Sim(tmp_path) as sim:
        r = c.measure(tmp_path, sim, d, ok=False)
    c.fails(tmp_path, r, 1, "the device has 2 input(s) but the design has 1")


@pytest.mark.parametrize("args,msg", [
    (["--encoding", "int8"], "--encoding must be int16, int32 or float32"),
    (["--word-order", "ABDC"], "--word-order must be ABCD, CDAB, BADC or DCBA"),
    (["--max-regs", "126"], "--max-regs must be 1..125"),
    (["--rate", "1.5"], "--rate must be a whole number"),
    (["--periods", "1"], "--periods must be"),
    (["--rtu", "/dev/null"], "give one of --tcp HOST:PORT and --rtu DEVICE"),
    (["--response-timeout", "0"], "--response-timeout and --byte-timeout must be"),
])
def test_bad_options(design, tmp_path, args, msg):
    r = c.measure(tmp_path, NoSim(), design, *args, ok=False)
    c.fails(tmp_path, r, 2, msg)


def test_sample_larger_than_a_read(design, tmp_path):
    with c.Sim(tmp_path) as sim:
        r = c.measure(tmp_path, sim, design, "--encoding", "float32", "--max-regs", 8, ok=False)
    c.fails(tmp_path, r, 1, "takes 9 registers, more than --max-regs 8")


@pytest.mark.skipif(bool(os.environ.get("MSID_EMULATOR")),
                    reason="msid bench re-executes /proc/self/exe, which needs binfmt_misc under qemu-user")
def test_bench_smoke():
    r = c.run("bench", "modbus", "--quick", timeout=300)
    assert r.returncode == 0, r.stderr
    assert "Modbus TCP" in r.stdout and "Modbus RTU" in r.stdout and "theoretical" in r.stdout
