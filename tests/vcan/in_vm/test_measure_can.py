"""`msid measure --device can://vcan0` and `msid can measure` over the one measure code
(docs/measure.md): the FRF covers the simulator's truth, progress is one line per event without
a terminal, and SIGINT keeps every complete period. Real SocketCAN, the real simulator; no timing
assertions: the signal is sent after a period is seen in the progress output."""
import json

import pytest

import canlib as c


def test_measure_uri_covers_truth_with_progress(tmp_path):
    """can://vcan0 with design options (the device's inputs): frf.json and design.json, complete, the
    exact Bin(N, 0.95) coverage of the true plant, a plant 3% off rejected, and one progress line per
    period of both experiments. The device is paced (--rate 2000): unpaced, a host process that a loaded
    VM does not schedule in time overflows its socket queue, and the lost samples (counted and reported,
    as they must be) leave too few periods: a test of the machine's load, not of msid."""
    out = tmp_path / "out"
    with c.Sim(tmp_path, "--seed", 4):
        r = c.run("measure", "--device", "can://vcan0", "--period", 256, "--lines", "1:3:120", "--amplitudes", 0.1,
                  "--seed", 7, "--periods", 6, "--skip-periods", 1, "--rate", 2000, "--no-plots", "-o", out)
    assert r.returncode == 0, r.stderr
    truth = json.loads((tmp_path / "truth.json").read_text())
    doc = json.loads((out / "frf.json").read_text())
    assert doc["complete"] is True and doc["experiments_completed"] == 2 == doc["experiments_planned"]
    assert doc["acquisition"]["transport"] == "socketcan" and doc["acquisition"]["interface"] == "vcan0"
    assert [e["periods_total"] for e in doc["experiments"]] == [6, 6]
    inside, n = c.check_coverage(doc, truth)
    assert n == 40 * doc["n_outputs"]
    with pytest.raises(AssertionError):   # negative control
        c.check_coverage(doc, truth, scale=1.03)
    assert (out / "design.json").exists()
    for e in (1, 2):
        for k in range(1, 7):
            assert f"msid measure: experiment {e}/2: {k}/6 periods acquired" in r.stderr, r.stderr
        assert f"msid measure: experiment {e}/2 done" in r.stderr
    assert "wrote " in r.stdout and "over vcan0" in r.stdout


@pytest.mark.parametrize("form", ["measure", "can"])
def test_sigint_keeps_complete_periods(tmp_path, form):
    """SIGINT after 5 periods of experiment 2 seen in the progress: exit 130, the FRF of the complete
    periods marked "complete": false with the counts, valid and covering the truth; the same for
    `msid measure --device can://` and `msid can measure` (one session). The device is paced (1 kHz,
    32 ms periods, 40 per experiment), so the run is still going when the signal lands."""
    opts = ["--periods", "40", "--skip-periods", "1", "--rate", "1000"]
    with c.Sim(tmp_path, "--seed", 6):
        if form == "measure":
            frf = tmp_path / "out" / "frf.json"
            cmd = [c.MSID, "measure", "--device", "can://vcan0", "--period", "32", "--lines", "1:2:15",
                   "--amplitudes", "0.2", "--experiments", "2", *opts, "--no-plots", "-o", str(tmp_path / "out")]
        else:
            design = c.excite(tmp_path, period=32, lines="1:2:15", amp=0.2, periods=40, seed=1)
            frf = tmp_path / "frf.json"
            cmd = [c.MSID, "can", "measure", "--iface", "vcan0", "--design", str(design), "--rcvbuf", str(4 << 20),
                   *opts, "-o", str(frf)]
        p, seen, rest = c.interrupt_after(cmd, "experiment 2/2: 5/40 periods acquired")
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert p.returncode == 130, "".join(seen[-3:]) + rest
    assert "interrupted" in rest
    prefix = "msid measure" if form == "measure" else "msid can"
    assert all(f"{prefix}: experiment 1/2: {k}/40 periods acquired" in "".join(seen) for k in range(1, 41))
    doc = json.loads(frf.read_text())
    assert doc["complete"] is False and doc["experiments_completed"] == 1 and doc["experiments_planned"] == 2
    assert "signal 2" in doc["incomplete_reason"]
    e1, e2 = doc["experiments"]
    assert e1["periods_total"] == 40 and e1["periods_used"] == 39
    assert 5 <= e2["periods_total"] < 40
    assert e2["periods_total"] == e2["samples"] // 32   # every complete period kept, the partial one left out
    assert e2["periods_used"] == e2["periods_total"] - 1
    # 15 lines x 2 outputs: the count inside is Bin(30, 0.95); 80% is below its 1e-3 quantile
    c.check_coverage(doc, truth, min_fraction=0.8)
