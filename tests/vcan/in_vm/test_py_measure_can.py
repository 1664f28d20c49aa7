"""msid.measure(can://vcan0, map=...) in process from Python, against msid-devsim's DBC node: the FRF with the
description's names and units, the node left at the safe value in its own state, the 95% regions near the node's
plant, and Ctrl-C mid-run keeping the complete periods and leaving the node at the safe value. Skipped only when
the build has no Python module (MSID_PYTHON_DIR unset). docs/python.md."""
import os
import signal
import sys

import pytest

import canlib
from mapcan import BINS, LINES, P, RATE, CanMapSim, description, maplib, plant  # noqa: F401

if not os.environ.get("MSID_PYTHON_DIR"):
    pytest.skip("this build has no Python module (MSID_PYTHON_DIR)", allow_module_level=True)
sys.path.insert(0, os.environ["MSID_PYTHON_DIR"])
import msid  # noqa: E402


def measure(sim, desc, **kw):
    """msid.measure over the node; a run a loaded VM left with too few usable periods is made again (3 at most)."""
    for attempt in range(3):
        try:
            return msid.measure(sim.uri, msid.design(period=P, lines=LINES, seed=kw.pop("seed", 3)), map=desc,
                                rate=RATE, periods=8, skip_periods=2, **kw)
        except ValueError as e:
            if "usable period(s)" not in str(e) or attempt == 2:
                raise


def test_measure_a_can_node_in_process(tmp_path, plant):
    desc = description(tmp_path, safe=0.125)
    seen = []
    with CanMapSim(tmp_path, desc, "--plant", plant[0], "--seed", 3, "--noise-y", "0.02", "--noise-u", "0.002") as sim:
        f = measure(sim, desc, progress=seen.append)
    rep = sim.report()
    assert abs(rep["setpoints"]["Torque command"] - 0.125) <= 0.5e-4, rep
    acq = f.meta["acquisition"]
    assert acq["transport"] == "can" and acq["protocol"] == "msid-device/1"
    assert acq["timing"]["samples_placed_by"] == "device counter"
    assert f.meta["input_names"] == ["Torque"] and f.meta["output_names"] == ["Speed"]
    assert f.meta["input_units"] == ["N m"] and f.meta["output_units"] == ["rad/s"]
    assert seen and all("periods" in s for s in seen)
    # 16 lines of one run: at least 12 inside their 95% region (P(Bin(16, 0.95) < 12) < 1e-3)
    G0 = maplib.dt_frf(*plant[1], BINS, P)
    inside = sum(canlib.f_sf(abs(f.G[k][0, 0] - G0[k][0, 0]) ** 2 / f.cov[k][0, 0].real, 2, 2 * int(f.dof[k])) > 0.05
                 for k in range(len(BINS)))
    assert inside >= 12, f"{inside}/16 lines inside their 95% region"


def test_ctrl_c_keeps_the_complete_periods_and_the_safe_value(tmp_path, plant):
    # a real SIGINT once four periods are in (a stop after a given period, not after a sleep): the FRF of the
    # complete periods, marked incomplete, and the node at the safe value in its own state
    desc = description(tmp_path, safe=-0.25)

    def progress(s):
        if s["periods"] >= 4:
            os.kill(os.getpid(), signal.SIGINT)

    with CanMapSim(tmp_path, desc, "--plant", plant[0]) as sim:
        with pytest.raises(msid.MeasurementInterrupted) as stop:
            msid.measure(sim.uri, msid.design(period=P, lines=LINES, seed=5), map=desc, rate=RATE, periods=12,
                         skip_periods=1, progress=progress)
    rep = sim.report()
    assert abs(rep["setpoints"]["Torque command"] + 0.25) <= 0.5e-4, rep
    assert rep["commands_not_safe"] == 0, rep
    f = stop.value.frf
    assert f.meta["complete"] is False
    assert 2 <= f.meta["experiments"][0]["periods_used"] < 11, f.meta["experiments"]
