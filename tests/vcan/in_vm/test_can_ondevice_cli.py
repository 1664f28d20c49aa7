"""`msid can measure --on-device` (msid-can/1 extension estimate/1, docs/can-protocol.md):
the C host over the CAN session. msid-devsim runs lib/'s msid_meas + msid_frf on the samples it
produces and sends the result block as EST frames; the host writes msid-frf/1 from it.

- Same samples, bit for bit: the device estimates AND streams (--stream-check); the host's FRF from
  the stream (the ordinary decoder and FRF job, streaming DFT path) and the device's FRF are compared
  here field by field (not only by the CLI), for int16 and float32 codes. Negative control: a device
  that drops sample frames makes the host's estimate differ, and the check refuses it.
- The issue's demo: 4 channels at 50 kHz over classic CAN at 1 Mbit/s (100 000 frames/s, 13.5 times
  the bus): `msid can measure` refuses it with the bus-capacity message, `--on-device` measures it
  without a single sample frame, and its 95% regions cover the simulator's truth (the count inside
  the exact Bin(N, 0.95) interval); the same check against a truth scaled by 2% fails.
- A device error: the estimator's memory too small reaches the host as one message naming the
  msid_status and both byte counts, exit 1, no file.
Options refused before the bus is opened are tested outside the VM (tests/vcan/test_can_host.py).
"""
import json

import pytest

import canlib as c

P, K = 128, 5   # the stream checks' design: small, since every sample also crosses the emulated bus
LINE_KEYS = ("G", "cov", "dof", "cov_known_input", "dof_known_input", "noise_cov", "snr", "cond", "input_snr")


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), period=P, lines="1:2:40", periods=K)


def ondevice(tmp, design, *extra, out="frf.json", ok=True):
    return c.measure(tmp, design, "--on-device", *extra, out=out, ok=ok)


def same_estimates(a, b):
    """Every estimated quantity of every line, and the noise covariance, identical (floats compared exactly)."""
    if len(a["lines"]) != len(b["lines"]) or a["noise_cov"] != b["noise_cov"]:
        return False
    for la, lb in zip(a["lines"], b["lines"]):
        if any(la[k] != lb[k] for k in LINE_KEYS):
            return False
    for ea, eb in zip(a["experiments"], b["experiments"]):
        if any(ea[k] != eb[k] for k in ("samples", "periods_total", "periods_skipped", "periods_used", "periods_gap")):
            return False
    return True


@pytest.mark.parametrize("codes", [[], ["--encoding", "float32"]], ids=["int16", "float32"])
def test_stream_check_bit_identical(design, tmp_path, codes):
    """int16 codes: the device decodes them with the host decoder's step (0.001f stands for 0.001)."""
    import jsonschema
    schema = json.loads((c.SRC / "docs" / "schemas" / "msid-frf-1.schema.json").read_text())
    with c.Sim(tmp_path, "--seed", 21):
        # paced (4 kHz): the stream check asserts no sample lost, and an unpaced device overflows the
        # socket queue of a host that a loaded TCG VM starves (test_e2e saw it)
        r = ondevice(tmp_path, design, *codes, "--rate", 4000, "--stream-check", tmp_path / "host.json")
    dev, host = r.doc, json.loads((tmp_path / "host.json").read_text())
    jsonschema.Draft202012Validator(schema).validate(dev)
    a = dev["acquisition"]
    assert a["on_device"] and a["estimate_mode"] == "estimate+stream" and a["extension"] == "estimate/1"
    assert a["frame_format"] == ("classic/float32" if codes else "classic/int16")
    assert "bit-identical" in a["stream_check"] and a["transport"] == "socketcan"
    assert host["dft_path"] == "stream" and host["acquisition"]["samples_lost"] == 0 and a["frames_missing"] == 0
    assert same_estimates(dev, host)
    assert a["samples"] == host["acquisition"]["samples"] == 2 * K * P
    assert a["device_periods"] == sum(e["periods_used"] for e in host["experiments"]) == 2 * (K - 1)
    # the file agrees with the EST frames' count: two frames per double, plus the answers' STATE frames
    assert a["est_frames"] >= 2 * a["result_doubles"]


def test_stream_check_detects_lost_samples(design, tmp_path):
    """Negative control of the bit-for-bit check: the device drops every 1000th sample frame (one in
    each experiment of 5 x 256 frames), so the host rejects the period it touches while the device
    estimates on all of them."""
    with c.Sim(tmp_path, "--seed", 21, "--drop-every", 1000):
        r = ondevice(tmp_path, design, "--stream-check", tmp_path / "host.json", ok=False)
    c.fails(tmp_path, r, 1, "differs from the host's estimate", "were lost on the way to the host")
    host = json.loads((tmp_path / "host.json").read_text())   # the host's FRF is kept for inspection
    assert host["acquisition"]["samples_lost"] > 0


def test_rate_beyond_the_bus(tmp_path):
    """The issue's demo: 4 channels at 50 kHz need 100 000 classic frames/s; a 1 Mbit/s bus carries
    about 7 400 (135 bits each, worst-case stuffing)."""
    design = c.excite(tmp_path, period=256, lines="1:60", periods=6)
    with c.Sim(tmp_path, "--seed", 8) as sim:
        refused = c.measure(tmp_path, design, "--rate", 50000, "--bitrate", 1000000, ok=False)
        c.fails(tmp_path, refused, 1, "the bus cannot carry 4 channels at 50000 Hz")
        dev = ondevice(tmp_path, design, "--rate", 50000, "--bitrate", 1000000).doc
        truth = sim.truth()
    report = sim.report()
    assert dev["fs_hz"] == 50000 and dev["acquisition"]["estimate_mode"] == "estimate"
    assert dev["acquisition"]["samples"] == 2 * 6 * 256
    assert report["sample_frames"] == 0 and report["samples"] == 2 * 6 * 256   # not one sample frame on the bus
    assert "sample_frames" not in dev["acquisition"]   # no decoder: nothing but status and EST frames
    inside, n = c.check_coverage(dev, truth)
    print(f"50 kHz x 4 channels over classic CAN at 1 Mbit/s, on device: {inside}/{n} rows inside their 95% region")
    with pytest.raises(AssertionError):
        c.check_coverage(dev, truth, scale=1.02)   # negative control: a truth 2% off fails


def test_device_error_reaches_the_host(design, tmp_path):
    with c.Sim(tmp_path, "--seed", 1, "--est-mem", 4096):
        r = ondevice(tmp_path, design, ok=False)
        c.fails(tmp_path, r, 1, "cannot estimate on board", "msid_status 2", "needs", "it has 4096")
    assert int(r.stderr.split("needs ")[1].split()[0]) > 4096
