"""Every fault mode of the Modbus simulator: the run completes (or stops with one clear error),
the adapter's counters match what the device injected, no overwritten or corrupted sample is
used, and the FRF from the good periods is right (bit-identical to a clean run when nothing
was lost; inside its 95% regions when periods were rejected)."""
import json
import signal
import threading

import pytest

import mblib as c

P, K = 256, 8


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), periods=K)


@pytest.fixture(scope="module")
def clean(design, tmp_path_factory):
    out = {}
    for rtu in (False, True):
        tmp = tmp_path_factory.mktemp("clean")
        with c.Sim(tmp, "--seed", 4, rtu=rtu) as sim:
            out[rtu] = c.measure(tmp, sim, design).doc
    return out


def run_fault(design, tmp, *sim_args, rtu=False, extra=()):
    with c.Sim(tmp, "--seed", 4, *sim_args, rtu=rtu) as sim:
        r = c.measure(tmp, sim, design, *extra)
    return r.doc, sim.report(), sim.truth(), r.stderr


def test_delayed_replies_time_out_and_are_retried(design, tmp_path, clean):
    doc, rep, _, err = run_fault(design, tmp_path, "--delay-every", "150:500")
    a = doc["acquisition"]
    assert rep["injected"]["delayed"] >= 1
    # a late reply (500 ms > the 200 ms response timeout) costs the timeouts until the device is back
    # (the simulator is single-threaded: it answers nothing while it delays); each is answered by a reconnect.
    # How many attempts fall into the 500 ms depends on scheduling, so only the lower bound is asserted
    # (it was `<= 3 * d`, a wall-clock assumption); the run recovering bounds the rest.
    d = rep["injected"]["delayed"]
    assert d <= a["timeouts"] and a["reconnects"] == a["timeouts"] + a["io_errors"]
    assert a["samples_lost"] == 0 and a["stale_replies"] == 0
    assert c.frf_equal(doc, clean[False]) and "retried" in err


def test_dropped_connection_reconnects(design, tmp_path, clean):
    doc, rep, _, _ = run_fault(design, tmp_path, "--drop-at", "0:1000")
    a = doc["acquisition"]
    assert rep["injected"]["dropped"] == 1
    assert a["io_errors"] >= 1 and a["reconnects"] >= 1 and a["samples_lost"] == 0
    assert c.frf_equal(doc, clean[False])


def test_dropped_rtu_line_goes_silent_and_recovers(design, tmp_path, clean):
    doc, rep, _, _ = run_fault(design, tmp_path, "--drop-at", "1:700", rtu=True)
    a = doc["acquisition"]
    assert rep["injected"]["dropped"] == 1 and rep["unanswered"] >= 1
    # every request the device left unanswered is a timeout msid counted; a loaded machine may add one whose
    # answer came after msid's timeout (answered for the device, late for msid): more, never fewer
    assert a["timeouts"] >= rep["unanswered"] and a["samples_lost"] == 0
    assert c.frf_equal(doc, clean[True])


def test_busy_exceptions_are_retried(design, tmp_path, clean):
    doc, rep, _, _ = run_fault(design, tmp_path, "--exception-every", "97")
    a = doc["acquisition"]
    # how many requests a run takes depends on how the host's polls meet the device's clock (it failed
    # once with 7 < 10 under load): at least one injected, and every one counted
    assert rep["injected"]["exceptions"] >= 1 and a["exceptions"] == rep["injected"]["exceptions"]
    assert a["retries"] <= a["exceptions"] and a["samples_lost"] == 0
    assert c.frf_equal(doc, clean[False])


def test_other_exceptions_stop_with_a_clear_error(design, tmp_path):
    with c.Sim(tmp_path, "--exception-every", "40:4") as sim:
        r = c.measure(tmp_path, sim, design, ok=False)
    c.fails(tmp_path, r, 1, "exception 4 (server device failure)", "input registers")


def test_corrupted_rtu_frames(design, tmp_path, clean):
    doc, rep, _, _ = run_fault(design, tmp_path, "--corrupt-every", "23", rtu=True)
    a = doc["acquisition"]
    assert rep["injected"]["corrupted"] >= 5 and a["crc_errors"] == rep["injected"]["corrupted"]
    assert a["samples_lost"] == 0 and a["stale_replies"] == 0
    assert c.frf_equal(doc, clean[True])


def periods_hit(ranges):
    """{experiment: sorted periods} touched by the device's overwritten ranges [e, a, b)."""
    out = {0: set(), 1: set()}
    for e, a, b in ranges:
        out[e] |= {s // P for s in range(a, b)}
    return {e: sorted(v) for e, v in out.items()}


@pytest.mark.parametrize("rtu", [False, True], ids=["tcp", "rtu"])
def test_stall_overruns_the_ring(design, tmp_path, rtu):
    """The device stops answering for 300 ms and writes 900 samples into a 512-sample ring: what it
    overwrote unread is declared missing, those periods are rejected, the rest is used."""
    doc, rep, truth, err = run_fault(design, tmp_path, "--ring", 512, "--stall-at", "0:900:900", rtu=rtu)
    a = doc["acquisition"]
    lost = rep["overrun_samples"]
    assert rep["injected"]["stalls"] == 1 and lost >= 900 - 512
    assert a["overrun_samples"] == a["samples_lost"] == a["device_overruns"] == lost
    assert a["overrun_events"] == len(rep["overrun_ranges"]) and a["timeouts"] >= 1
    hit = periods_hit(rep["overrun_ranges"])
    for e, exp in enumerate(doc["experiments"]):
        assert exp["periods_gap"] == len(hit[e]), (e, exp, hit)
        assert exp["periods_used"] == K - 1 - len(hit[e])
    assert doc["periods_rejected"] == sum(len(v) for v in hit.values()) >= 2
    c.check_coverage(doc, truth, min_fraction=0.0 if rtu else 0.9)
    assert "overwritten" in err


def test_device_restart_mid_run(design, tmp_path):
    at = 1000
    doc, rep, truth, _ = run_fault(design, tmp_path, "--restart-at", f"1:{at}")
    a = doc["acquisition"]
    assert rep["injected"]["restarts"] == 1 and a["device_restarts"] == 1 and a["samples_lost"] == 0
    e0, e1 = doc["experiments"]
    assert e0["periods_used"] == K - 1 and e0["leftover_samples"] == 0
    assert e1["periods_total"] == at // P + K and e1["periods_skipped"] == 2
    assert e1["periods_used"] == at // P - 1 + K - 1 and e1["leftover_samples"] == at % P
    c.check_coverage(doc, truth)


def test_device_that_hangs_never_blocks_the_host(design, tmp_path):
    """SIGSTOP the device mid-run: the host gives up after its retries with one clear error. Bounded by
    its attempts (the message says 4), not asserted by the clock: measure's subprocess timeout is only
    a hang detector."""
    with c.Sim(tmp_path) as sim:
        threading.Timer(0.8, lambda: sim.p.send_signal(signal.SIGSTOP)).start()
        r = c.measure(tmp_path, sim, design, "--rate", 2000, "--response-timeout", 100, "--retries", 3, ok=False,
                      timeout=120)
    c.fails(tmp_path, r, 1, "no valid reply", "after 4 attempts")


def test_device_that_dies_mid_run_is_named_as_gone(design, tmp_path):
    """The device exits instead of answering its 300th request: every reconnect is refused, and the one
    message says the connection is lost (it said "bad request" once the failed reconnect had left no socket)."""
    with c.Sim(tmp_path, "--die-after", "300") as sim:
        sim.expect_exit = 9
        r = c.measure(tmp_path, sim, design, "--response-timeout", 100, "--retries", 3, ok=False, timeout=120)
    c.fails(tmp_path, r, 1, "no valid reply", "after 4 attempts")
    assert "bad request" not in r.stderr
    assert "not connected" in r.stderr or "Connection refused" in r.stderr or "Connection reset" in r.stderr, r.stderr


# ---- adversarial device: the header's counts are checked against the design ----

def test_device_that_never_reports_done_ends_after_k_p(design, tmp_path, clean):
    """A device that keeps writing past K P samples and never reports DONE: with --transient off the
    host used to poll forever. Each experiment now ends after the design's K P samples (the header's
    TOTAL), with a note, and the FRF is the clean run's."""
    doc, rep, _, err = run_fault(design, tmp_path, "--never-done", extra=("--transient", "off"))
    a = doc["acquisition"]
    assert a["samples_lost"] == 0 and a["samples"] == 2 * K * P
    assert "without the device reporting DONE" in err
    (tmp_path / "honest").mkdir()
    with c.Sim(tmp_path / "honest", "--seed", 4) as sim:   # the same device, honest, same options
        clean_off = c.measure(tmp_path / "honest", sim, design, "--transient", "off").doc
    assert c.frf_equal(doc, clean_off)


def test_write_index_stepping_back_is_one_clear_error(design, tmp_path):
    """A write index that steps back used to end the experiment early (exit 0 with part of the
    samples, no note): it is a protocol error now, reported once, nothing written."""
    with c.Sim(tmp_path, "--seed", 4, "--index-back-at", "0:1000") as sim:
        r = c.measure(tmp_path, sim, design, ok=False, timeout=120)
    c.fails(tmp_path, r, 1, "experiment 1")
    # seen either as the step back itself or, when the host had not read past the new index yet, as a
    # DONE before the design's K P samples
    assert "write index stepped back" in r.stderr or f"reported DONE after {K * P - 16} of the design's" in r.stderr


def test_device_that_answers_twice(design, tmp_path, clean):
    """Every reply sent twice. The host's own MBAP reader (daq/src/msid_mbap.c) reads the stale
    duplicate of request k while it waits for reply k+1, sees transaction id k, skips and counts it:
    deterministic recovery (libmodbus alone took the duplicate for the next reply and recovered only
    when the timing let it). The FRF is the honest device's, bit for bit, with no fault
    counted, and the host skipped exactly the device's duplicates but the last (sent after the host's
    last request, never read)."""
    with c.Sim(tmp_path, "--seed", 4, "--answer-twice") as sim:
        r = c.measure(tmp_path, sim, design, "--timeout", 3, timeout=120)
    rep, a = sim.report(), r.doc["acquisition"]
    dup = rep["adversarial"]["duplicated"]
    assert dup == rep["requests"] and dup >= 100   # every request answered twice
    assert a["skipped_replies"] == dup - 1
    assert a["bad_replies"] == a["timeouts"] == a["retries"] == a["reconnects"] == a["malformed_frames"] == 0
    assert a["samples_lost"] == 0 and a["requests"] == rep["requests"]
    assert c.frf_equal(r.doc, clean[False])


def test_negative_control_an_honest_device_skips_nothing(design, tmp_path, clean):
    """The count above is the duplicates': a device answering once leaves nothing to skip."""
    with c.Sim(tmp_path, "--seed", 4) as sim:
        r = c.measure(tmp_path, sim, design, "--timeout", 3, timeout=120)
    assert r.doc["acquisition"]["skipped_replies"] == 0 and sim.report()["adversarial"]["duplicated"] == 0
    assert c.frf_equal(r.doc, clean[False])
