"""ENOBUFS on send, on real SocketCAN. vcan0 normally has no qdisc (noqueue), so a send never
fails; here a token-bucket qdisc (tbf, module sch_tbf loaded by vm.py) admits 4000 classic
frames/s with room for about two, and drops the rest at enqueue, which the raw socket reports
as ENOBUFS. Both senders must wait and send the same frame again: the simulator (streaming
samples unpaced, the heavy sender) and the host (CFG/CTRL frames). Every qdisc drop must be a
counted retry, no sample may be missing, and the FRF must be bit for bit the one of an
uncongested run with the same seeds. A queue that never drains must make the senders give up."""
import contextlib
import json
import subprocess
import time

import pytest

import canlib as c

P, K, CHUNKS = 256, 4, 2          # classic int16, 4 channels: 2 frames per sample
IFACE = "vcan0"


def qdisc():
    out = subprocess.run(["tc", "-s", "-j", "qdisc", "show", "dev", IFACE], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out)[0]


@contextlib.contextmanager
def tbf(spec):
    """vcan0 behind `tc qdisc ... root tbf <spec>`; the qdisc is removed afterwards, whatever happens."""
    assert qdisc()["kind"] == "noqueue", "vcan0 should start without a qdisc"
    subprocess.run(["tc", "qdisc", "replace", "dev", IFACE, "root", "tbf"] + spec.split(), check=True)
    try:
        yield
    finally:
        subprocess.run(["tc", "qdisc", "del", "dev", IFACE, "root"], check=True)
        assert qdisc()["kind"] == "noqueue"


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), periods=K)


def test_enobufs_retried_nothing_lost(design, tmp_path):
    for d in ("clean", "congested"):
        (tmp_path / d).mkdir()
    clean, clean_rep, _ = c.sim_measure(design, tmp_path / "clean")
    t0 = time.monotonic()
    # 512 kbit/s = 64000 B/s = 4000 16-byte frames/s; bucket and queue of 31 and 32 bytes
    with tbf("rate 512kbit burst 32 limit 32"):
        r, rep, _ = c.sim_measure(design, tmp_path / "congested")     # the same seeds
        q = qdisc()
    doc, a = r.doc, r.doc["acquisition"]
    print(f"qdisc drops {q['drops']}, device send_retries {rep['send_retries']}, host send_retries "
          f"{a['send_retries']}, stream {a['stream_seconds']:.2f} s (clean "
          f"{clean.doc['acquisition']['stream_seconds']:.2f} s), {time.monotonic() - t0:.1f} s")
    # (a) the sends really failed with ENOBUFS and were retried: every frame the qdisc dropped is
    # one retry counted by its sender, and no sender gave up on a frame
    assert q["drops"] > 0
    assert rep["send_retries"] > 0 and a["send_retries"] > 0
    assert q["drops"] == rep["send_retries"] + a["send_retries"], "a dropped frame was not retried"
    assert rep["tx_busy"] == 0
    # (b) nothing was lost: every frame the device meant to send went out and arrived
    assert rep["frames_sent"] == clean_rep["frames_sent"]
    assert rep["sample_frames"] == a["sample_frames"] == 2 * K * P * CHUNKS
    assert a["samples"] == 2 * K * P
    assert a["samples_lost"] == a["frames_missing"] == a["gap_events"] == a["kernel_drops"] == 0
    assert a["frames"] == clean.doc["acquisition"]["frames"]
    assert doc["periods_rejected"] == 0
    for e in doc["experiments"]:
        assert e["periods_gap"] == 0 and e["periods_used"] == K - 1
    # the same samples: the same FRF, bit for bit
    assert c.lines_equal(doc, clean.doc)


def test_queue_that_never_drains_gives_up(design, tmp_path):
    # a bucket smaller than any frame (16 bytes): every send is dropped, the retries must end
    with tbf("rate 512kbit burst 8 limit 8"):
        with c.Sim(tmp_path) as sim:
            t0 = time.monotonic()
            r = c.measure(tmp_path, design, ok=False)
            dt = time.monotonic() - t0
        drops = qdisc()["drops"]
    rep = sim.report()
    assert r.returncode == 1 and "the CAN send queue stayed full (ENOBUFS) for 2000 ms" in r.stderr, r.stderr
    assert not (tmp_path / "frf.json").exists()
    assert dt < 30, f"the host took {dt:.1f} s to give up (its send timeout is 2 s)"
    # the device gave up on its INFO and STATE frames (1 s each) and is still alive
    assert rep["frames_sent"] == 0 and rep["tx_busy"] >= 2 and rep["send_retries"] > 0
    assert drops >= rep["send_retries"] + rep["tx_busy"]
