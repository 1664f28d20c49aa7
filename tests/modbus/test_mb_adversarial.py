"""The adversarial Modbus device: msid-devsim replies with garbage transaction ids, drips
its bytes one at a time, cuts replies short, sends replies longer than asked, or reports an absurd
sample count in its header. Each run either recovers -- the FRF is bit-identical to the honest
device's and the host counted every injected fault exactly -- or fails in bounded time with one clear
error and nothing written. Never an FRF from corrupted data. (A device answering every request twice:
test_mb_faults.py; the MBAP reader frame by frame: test_mbap.c.) Generous link timeouts keep the counts exact on a loaded machine: no test depends
on how fast anything runs."""
import pytest

import mblib as c

P, K = 256, 8
# a late reply is not a fault of these tests: only the injected ones may cost a timeout
SLOW_OK = ("--response-timeout", 3000, "--byte-timeout", 1000)


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), periods=K)


@pytest.fixture(scope="module")
def honest(design, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("honest")
    with c.Sim(tmp, "--seed", 4) as sim:
        doc = c.measure(tmp, sim, design, *SLOW_OK).doc
    return doc, sim.report()


def hostile(design, tmp, *sim_args, ok=True):
    with c.Sim(tmp, "--seed", 4, *sim_args) as sim:
        r = c.measure(tmp, sim, design, *SLOW_OK, ok=ok, timeout=180)
    return r, sim.report()


def test_foreign_transaction_ids_are_skipped_and_time_out(design, tmp_path, honest):
    """Every 37th reply carries a transaction id the host never sent, in place of the real reply. The
    host's MBAP reader (daq/src/msid_mbap.c) skips and counts it and waits on for the matching reply,
    which never comes: one response timeout each, a reconnect, the request again (also a ring read);
    the FRF is the honest one."""
    r, rep = hostile(design, tmp_path, "--garbage-tid-every", 37)
    a, n = r.doc["acquisition"], rep["adversarial"]["garbage_tid"]
    assert n >= 5
    assert a["skipped_replies"] == n and a["timeouts"] == n and a["reconnects"] == n
    assert a["bad_replies"] == a["malformed_frames"] == 0 and a["samples_lost"] == 0
    assert c.frf_equal(r.doc, honest[0])


def test_oversized_replies_are_rejected_and_reissued(design, tmp_path, honest):
    """Every 37th read reply is 16 bytes longer than asked, byte count and MBAP length included. Within
    the 254-byte MBAP length it is read whole and rejected as a bad reply (the stream stays framed); a
    full 125-register read then has a length of 269: a malformed frame, counted, the connection
    renewed. Either way the request is issued again and the FRF is the honest one."""
    r, rep = hostile(design, tmp_path, "--oversize-every", 37)
    a, n = r.doc["acquisition"], rep["adversarial"]["oversized"]
    assert n >= 5
    assert a["bad_replies"] + a["malformed_frames"] == n and a["malformed_frames"] >= 1
    assert a["timeouts"] == a["skipped_replies"] == 0 and a["reconnects"] == a["malformed_frames"]
    assert a["samples_lost"] == 0
    assert c.frf_equal(r.doc, honest[0])


def test_only_garbage_transaction_ids_is_one_clear_error(design, tmp_path):
    """A device whose every reply has a foreign transaction id: one clear error after the retries, naming
    the skipped replies."""
    r, rep = hostile(design, tmp_path, "--garbage-tid-every", 1, ok=False)
    c.fails(tmp_path, r, 1, "no msid-modbus device answered", "no valid reply", "attempts",
            "with another transaction or unit id")
    assert rep["adversarial"]["garbage_tid"] >= 2


def test_slow_drip_bytes_below_the_byte_timeout(design, tmp_path, honest):
    """Every 40th read reply arrives one byte at a time, 2 ms apart (below the byte timeout): libmodbus
    assembles it; nothing is counted as a fault and the FRF is the honest one."""
    r, rep = hostile(design, tmp_path, "--drip-every", "40:2")
    a = r.doc["acquisition"]
    assert rep["adversarial"]["dripped"] >= 3
    assert a["timeouts"] == a["bad_replies"] == a["retries"] == 0 and a["samples_lost"] == 0
    assert c.frf_equal(r.doc, honest[0])


def test_truncated_replies_time_out_and_are_retried(design, tmp_path, honest):
    """Every 53rd read reply stops halfway: the byte timeout ends the wait, the host reconnects and asks
    again; one timeout per truncated reply, nothing lost."""
    r, rep = hostile(design, tmp_path, "--truncate-every", 53)
    a, n = r.doc["acquisition"], rep["adversarial"]["truncated"]
    assert n >= 3
    assert a["timeouts"] == n and a["reconnects"] == a["timeouts"] + a["io_errors"] and a["samples_lost"] == 0
    assert c.frf_equal(r.doc, honest[0])


def test_absurd_header_count_is_one_clear_error(design, tmp_path):
    """From sample 1000 of experiment 1 the header's TOTAL reads 0xFFFFFFF0: one protocol error, nothing
    written, in bounded time (the count never sizes work)."""
    r, rep = hostile(design, tmp_path, "--absurd-header-at", "0:1000", ok=False)
    c.fails(tmp_path, r, 1, "experiment 1", "4294967280")
    # seen at START (the unpaced device may be past sample 1000 by then) or while polling
    assert "announces 4294967280 samples" in r.stderr or "changed its samples per segment" in r.stderr
    assert rep["adversarial"]["absurd_header"] == 1


def test_negative_control_an_honest_device_counts_nothing(honest):
    """The counts above are the faults': the honest device injected none and the host counted none."""
    a = honest[0]["acquisition"]
    assert a["bad_replies"] == a["timeouts"] == a["retries"] == a["skipped_replies"] == a["malformed_frames"] == 0
    assert sum(honest[1]["adversarial"].values()) == 0
