"""On-device estimation (msid-modbus/1 extension estimate/1, docs/modbus-registers.md):
msid-devsim runs lib/'s msid_meas + msid_frf on the samples it produces and the host reads each
line's G, covariances and dof as float64 registers. Real libmodbus at both ends on 127.0.0.1 (and a
socat pty pair for RTU).

- Same samples, bit for bit: the device estimates AND streams (--stream-check); the host's FRF from
  the stream and the device's FRF are compared here field by field (not only by the CLI), for int16
  and float32 codes. A different device seed must differ (negative control).
- Estimation only (no ring): a fresh device equals a fresh streaming device with the same seed, bit
  for bit, and its 95% regions cover the simulator's truth (a 2% wrong truth fails the same check).
- A plant rate the link cannot carry (4 channels at 50 kHz over RTU at 115200 baud): the streaming
  host refuses, on-device estimation measures it and the coverage check passes.
- Bad device configurations: estimator memory too small, a device without the extension; one
  message naming the msid_status, exit 1, no output file. A plain host afterwards gets a plain device.
"""
import json

import pytest

import mblib as c

P, K = 256, 8
LINE_KEYS = ("G", "cov", "dof", "cov_known_input", "dof_known_input", "noise_cov", "snr", "cond", "input_snr")


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), lines="1:30")


def ondevice(tmp, sim, design, *extra, out="dev.json", ok=True):
    return c.measure(tmp, sim, design, "--on-device", *extra, out=out, ok=ok)


def same_estimates(a, b):
    """Every estimated quantity of every line, and the noise covariance, identical (floats compared exactly)."""
    if len(a["lines"]) != len(b["lines"]) or a["noise_cov"] != b["noise_cov"]:
        return False
    for la, lb in zip(a["lines"], b["lines"]):
        for k in LINE_KEYS:
            if la[k] != lb[k]:
                return False
    for ea, eb in zip(a["experiments"], b["experiments"]):
        for k in ("samples", "periods_total", "periods_skipped", "periods_used", "periods_gap", "transient_flagged"):
            if ea[k] != eb[k]:
                return False
    return True


@pytest.mark.parametrize("codes", [[], ["--encoding", "float32", "--word-order", "CDAB"]], ids=["int16", "float32"])
def test_stream_check_bit_identical(design, tmp_path, codes):
    import jsonschema
    schema = json.loads((c.SRC / "docs" / "schemas" / "msid-frf-1.schema.json").read_text())
    with c.Sim(tmp_path, "--seed", 21) as sim:
        r = ondevice(tmp_path, sim, design, *codes, "--stream-check", tmp_path / "host.json")
    dev, host = r.doc, json.loads((tmp_path / "host.json").read_text())
    jsonschema.Draft202012Validator(schema).validate(dev)
    assert dev["acquisition"]["on_device"] and dev["acquisition"]["estimate_mode"] == "estimate+stream"
    assert "bit-identical" in dev["acquisition"]["stream_check"]
    assert host["dft_path"] == "stream" and host["acquisition"]["samples_lost"] == 0
    assert same_estimates(dev, host)
    assert dev["acquisition"]["samples"] == host["acquisition"]["samples"] == 2 * K * P
    assert dev["acquisition"]["device_periods"] == sum(e["periods_used"] for e in host["experiments"]) == 2 * (K - 1)


def test_stream_check_with_a_device_restart(design, tmp_path):
    """A watchdog restart in experiment 2: device and host both open a new segment (its skip period
    applies again) and still agree bit for bit."""
    with c.Sim(tmp_path, "--seed", 21, "--restart-at", "1:700") as sim:
        r = ondevice(tmp_path, sim, design, "--stream-check", tmp_path / "host.json")
    host = json.loads((tmp_path / "host.json").read_text())
    assert host["acquisition"]["device_restarts"] == 1 and same_estimates(r.doc, host)
    e = r.doc["experiments"][1]
    assert (e["samples"], e["periods_skipped"], e["periods_used"]) == (700 + K * P, 2, 8)


def test_estimate_only_equals_stream_and_covers_truth(design, tmp_path):
    docs = {}
    for name, seed, extra in (("dev", 5, ["--on-device"]), ("host", 5, ["--dft", "stream"]), ("other", 6, ["--dft", "stream"])):
        (tmp_path / name).mkdir()
        with c.Sim(tmp_path / name, "--seed", seed) as sim:
            docs[name] = c.measure(tmp_path, sim, design, *extra, out=name + ".json").doc
            if name == "dev":
                truth = sim.truth()
    dev = docs["dev"]
    assert dev["acquisition"]["estimate_mode"] == "estimate"
    assert same_estimates(dev, docs["host"])
    assert not same_estimates(dev, docs["other"])   # negative control: another noise realisation
    inside, n = c.check_coverage(dev, truth)
    print(f"on-device: {inside}/{n} rows inside their 95% region")
    with pytest.raises(AssertionError):
        c.check_coverage(dev, truth, scale=1.02)


def test_rate_beyond_the_link(tmp_path):
    """4 channels at 50 kHz: 250 000 registers/s, about 50 times what RTU at 115200 baud carries."""
    design = c.excite(tmp_path, lines="1:60", periods=6)
    with c.Sim(tmp_path, "--seed", 8, rtu=True) as sim:
        refused = c.measure(tmp_path, sim, design, "--rate", 50000, ok=False)
        assert refused.returncode == 1 and "the link cannot carry" in refused.stderr, refused.stderr
        dev = ondevice(tmp_path, sim, design, "--rate", 50000).doc
        truth = sim.truth()
    assert dev["fs_hz"] == 50000 and dev["acquisition"]["transport"] == "modbus-rtu"
    assert dev["acquisition"]["samples"] == 2 * 6 * P
    inside, n = c.check_coverage(dev, truth)
    print(f"50 kHz x 4 channels over RTU 115200 baud, on device: {inside}/{n} rows inside their 95% region")


def test_estimator_memory_too_small(design, tmp_path):
    with c.Sim(tmp_path, "--seed", 1, "--est-mem", 4096) as sim:
        r = ondevice(tmp_path, sim, design, out="frf.json", ok=False)
        c.fails(tmp_path, r, 1, "cannot estimate on board", "msid_status 2", "needs", "it has 4096")
        # the device stays a plain msid-modbus/1 device for a host without --on-device
        plain = c.measure(tmp_path, sim, design, "--periods", 3, out="plain.json")
    assert plain.doc["acquisition"]["samples"] == 2 * 3 * P
    need = int(r.stderr.split("needs ")[1].split()[0])
    assert need > 4096


def test_non_finite_result_is_refused(design, tmp_path):
    """An adversarial device publishes a NaN in line 1's G: one message, no file."""
    with c.Sim(tmp_path, "--seed", 1, "--bad-result") as sim:
        r = ondevice(tmp_path, sim, design, out="frf.json", ok=False)
    c.fails(tmp_path, r, 1, "non-finite value")


def test_bad_options(design, tmp_path):
    with c.Sim(tmp_path, "--seed", 1) as sim:
        r = ondevice(tmp_path, sim, design, "--detect-lines", "40", out="frf.json", ok=False)
        c.fails(tmp_path, r, 2, "--detect-lines is not available with --on-device")
        r = ondevice(tmp_path, sim, design, "--stream-check", tmp_path / "frf.json", out="frf.json", ok=False)
        c.fails(tmp_path, r, 2, "different files")


def test_device_without_the_extension(design, tmp_path):
    """The pymodbus peer (peer_server.py) serves plain msid-modbus/1: input register 40 is 0."""
    from test_mb_peer import Peer
    peer = Peer(tmp_path, 1)
    try:
        r = c.run("modbus", "measure", "--tcp", f"127.0.0.1:{peer.port}", "--design", design, "--on-device",
                  "-o", tmp_path / "frf.json")
    finally:
        peer.close()
    c.fails(tmp_path, r, 1, "does not estimate on board")
