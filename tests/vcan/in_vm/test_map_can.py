"""Described CAN devices (msid measure --device can://vcan0 --map, msid device check) against msid-devsim --map
--iface vcan0: a node that takes the command message the host sends and sends its status message once per cycle
of its own clock, laid out by a DBC (Intel and Motorola, signed, a float32 signal, a counter). The FRF names and
units come from the description, the safe value is asserted in the node's own state (its report), bad
descriptions are refused with one message and nothing sent. No check depends on the VM being fast: samples a
loaded VM loses are missing samples, counted, and a run refused for too few usable periods is made again (at
most 3 times).

The truth: a node that cycles at the tick rate with a counter signal gets the sample of each cycle and is read
per cycle, so the FRF is the node's DT plant G(z) (maplib.dt_frf)."""
import random

import numpy as np
import pytest

import canlib
from canlib import run
from mapcan import DRIVE, LINES, P, PEER_RATE, RATE, BINS, CanMapSim, PeerSim, description, maplib, measure, plant  # noqa: F401


def test_measure_over_can_names_units_timing_and_the_safe_value(tmp_path, plant):
    desc = description(tmp_path, safe=0.125)
    with CanMapSim(tmp_path, desc, "--plant", plant[0], "--noise-y", "0.01", "--noise-u", "0.001") as sim:
        r = measure(tmp_path, sim, desc)
    doc = r.doc
    assert doc["input_names"] == ["Torque"] and doc["input_units"] == ["N m"]
    assert doc["output_names"] == ["Speed"] and doc["output_units"] == ["rad/s"]
    assert doc["fs_hz"] == RATE and len(doc["lines"]) == len(BINS)
    a = doc["acquisition"]
    assert a["transport"] == "can" and a["protocol"] == "msid-device/1" and a["input"] == "read back"
    for k in ("frames_sent", "status_frames", "stale_ticks", "bus_errors", "kernel_drops", "send_retries_enobufs"):
        assert k in a, k
    assert a["frames_sent"] > 0 and a["status_frames"] > 0 and a["bus_errors"] == 0
    t = a["timing"]
    for k in ("rate_hz", "lateness_s", "round_trip_s", "ticks_missed", "exchange"):
        assert k in t, k
    assert "DriveCmd 0x101" in t["exchange"] and "DriveStatus 0x181" in t["exchange"]
    assert a["safe_values_written"]
    rep = sim.report()
    # the node's own applied setpoint: the safe value, to the signal's resolution
    assert abs(rep["setpoints"]["Torque command"] - 0.125) <= 0.5e-4, rep
    assert rep["commands"] > 0
    # one run: the estimate is near the node's plant (the Monte Carlo coverage is its own test)
    truth = maplib.truth_doc(maplib.dt_frf(*plant[1], BINS, P), BINS)
    pv = maplib.element_pvalues(doc, truth)
    assert np.sum(pv > 1e-4) >= len(pv) - 1, pv


def test_device_check_reads_every_status_signal_and_sends_only_safe(tmp_path):
    desc = description(tmp_path, safe=-0.25)
    with CanMapSim(tmp_path, desc) as sim:
        r = run("device", "check", "--map", desc, "--device", sim.uri)
        assert r.returncode == 0, r.stdout + r.stderr
        for name in ("Torque", "Speed", "Cycle"):
            assert name in r.stdout
        assert "DriveStatus.Speed (0x181)" in r.stdout
    rep = sim.report()
    assert rep["commands"] >= 1 and rep["commands_not_safe"] == 0
    assert abs(rep["setpoints"]["Torque command"] + 0.25) <= 0.5e-4


def test_unknown_signal_is_refused_naming_it_and_nothing_is_sent(tmp_path):
    drive = DRIVE.replace('signal = "TorqueCmd"', 'signal = "TorqCmd"')
    desc = description(tmp_path, drive=drive)
    r = run("measure", "--device", "can://vcan0", "--map", desc, "--period", P, "--lines", LINES, "--periods", 3,
            "--rate", RATE, "--no-plots", "-o", tmp_path / "o")
    assert r.returncode != 0
    assert "message 'DriveCmd' of" in r.stderr and "has no signal 'TorqCmd' (its signals: TorqueCmd, Mode)" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_a_limit_the_signal_cannot_carry_is_refused(tmp_path):
    drive = DRIVE.replace("max = 2.0", "max = 4.0")   # the DBC's range of TorqueCmd is [-3, 3]
    desc = description(tmp_path, drive=drive)
    r = run("device", "check", "--map", desc, "--device", "can://vcan0")
    assert r.returncode != 0
    assert "drive channel 'Torque command': max 4 does not fit DriveCmd.TorqueCmd" in r.stderr
    assert "[-3, 3]" in r.stderr


def test_injected_dropped_status_cycles_are_missing_samples(tmp_path, plant):
    # one status cycle in 250 dropped: about three in a run, so that most periods stay usable; no counter, so that
    # a dropped cycle is a tick without a fresh frame
    desc = description(tmp_path, counter=False)
    with CanMapSim(tmp_path, desc, "--plant", plant[0], "--drop-every", "250") as sim:
        r = measure(tmp_path, sim, desc, periods=8)
    a = r.doc["acquisition"]
    rep = sim.report()
    assert rep["injected"]["dropped"] > 0
    # a dropped cycle is a tick without a fresh status frame: never a value held over
    assert a["stale_ticks"] >= 1, a


def test_peer_measured_with_the_input_read_back_and_left_at_the_safe_value(tmp_path, plant):
    desc = description(tmp_path, safe=0.25)
    with PeerSim(tmp_path, desc, "--plant", plant[0], "--noise-y", "0.01", "--noise-u", "0.001", "--seed", 3) as sim:
        r = measure(tmp_path, sim, desc, seed=3, rate=PEER_RATE)
    st = sim.state()
    assert st["commands"] > 0 and st["commands_not_safe"] == 0, st
    assert abs(st["setpoints"]["Torque command"] - 0.25) <= 0.5e-4, st
    doc = r.doc
    assert doc["input_names"] == ["Torque"] and doc["output_names"] == ["Speed"]
    truth = maplib.truth_doc(maplib.dt_frf(*plant[1], BINS, P), BINS)
    pv = maplib.element_pvalues(doc, truth)
    assert np.sum(pv > 1e-4) >= len(pv) - 1, pv


@pytest.mark.parametrize("after", random.Random(41).sample(range(1, 5), 2))
def test_sigint_mid_run_leaves_the_peer_at_the_safe_value(tmp_path, plant, after):
    # SIGINT after `after` progress events (drawn once with a fixed seed): exit 130, the peer holds the safe value
    desc = description(tmp_path, safe=-0.5)
    with PeerSim(tmp_path, desc, "--plant", plant[0]) as sim:
        cmd = [canlib.MSID, "measure", "--device", sim.uri, "--map", desc, "--period", str(P), "--lines", LINES,
               "--periods", "6", "--rate", str(PEER_RATE), "--no-plots", "-o", str(tmp_path / "o")]
        rc, err = maplib.interrupt_after_periods(cmd, after, timeout=300)
        assert rc == 130, err
    st = sim.state()
    assert st["commands_not_safe"] == 0 and abs(st["setpoints"]["Torque command"] + 0.5) <= 0.5e-4, (st, err)


def test_a_node_that_dies_is_named_and_the_run_ends(tmp_path, plant):
    desc = description(tmp_path)
    with CanMapSim(tmp_path, desc, "--plant", plant[0], "--die-after", 300) as sim:
        sim.expect_exit = 9
        r = measure(tmp_path, sim, desc, "--timeout", "2", ok=False)
        sim.p.wait(30)
    assert r.returncode == 1
    assert "no fresh status frame" in r.stderr or "did not answer" in r.stderr, r.stderr
