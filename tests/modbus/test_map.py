"""Described devices over Modbus (msid measure --map, msid device check) against msid-devsim --map: the
issue's description as written, Monte Carlo coverage of the device's true FRF with the input read back and with
the commanded input only, with an injected device clock offset of 100 ppm, the safe value in the device's own
registers after every way out, and bad descriptions and devices refused with one message and nothing written
but the safe value. No check depends on the machine being idle: samples a loaded machine loses are missing
samples, and the checks judge by what the files record.

The truths: a device that cycles at the tick rate with a counter channel gets the sample of each cycle and is
read per cycle, so the FRF is the device's DT plant G(z) (maplib.dt_frf), read back or commanded; a device
that cycles M times per tick is seen through the hold of each written value (maplib.held_frf)."""
import json
import re
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest

import maplib
from mblib import MSID, canlib, run

DOCS = Path(__file__).resolve().parents[2] / "docs" / "examples"
P, LINES, BINS = 64, "1:2:31", list(range(1, 32, 2))


@pytest.fixture(scope="module")
def plant(tmp_path_factory):
    A, B, C, D = maplib.siso_plant()
    path = maplib.write_plant(tmp_path_factory.mktemp("plant") / "plant.txt", A, B, C, D)
    return str(path), (A, B, C, D)


# ---- the description as written ----------------------------------------------------------------------

def test_the_issue_example_as_written(tmp_path):
    desc = str(DOCS / "modbus-drive.toml")
    with maplib.MapSim(tmp_path, desc, "--cycle-hz", "200") as sim:
        # the example has no counter: a tick the loaded machine missed costs its period (counted and refused,
        # never placed wrong), so a run that lost most of its periods is made again
        maplib.measure(tmp_path, sim, desc, period=256, lines="1:2:99", periods=6, skip=1, rate=200, seed=1,
                       attempts=3)
        safe = maplib.float32_of(sim.holding(100, 2))
    doc = json.loads((tmp_path / "out" / "frf.json").read_text())
    assert (tmp_path / "out" / "design.json").exists()
    assert doc["input_names"] == ["Torque"] and doc["input_units"] == ["N m"]
    assert doc["output_names"] == ["Speed"] and doc["output_units"] == ["rad/s"]
    assert doc["fs_hz"] == 200 and len(doc["lines"]) == 50
    a = doc["acquisition"]
    assert a["protocol"] == "msid-device/1" and a["input"] == "read back"
    maplib.validate_frf(doc)
    t = a["timing"]
    for k in ("rate_hz", "rate_achieved_hz", "lateness_s", "round_trip_s", "ticks_missed", "exchange", "scheduling"):
        assert k in t, k
    for k in ("median", "p99", "max"):
        assert t["lateness_s"][k] >= 0 and t["round_trip_s"][k] > 0
    assert safe == 0.0 and a["safe_values_written"]
    assert sim.report()["setpoints"]["Torque command"] == 0.0


def test_device_check_reads_every_channel_and_writes_only_safe(tmp_path):
    desc = maplib.description(tmp_path / "dev.toml", safe=0.25)
    with maplib.MapSim(tmp_path, desc) as sim:
        r = run("device", "check", "--map", desc, "--device", sim.uri)
        assert r.returncode == 0, r.stderr
        for name in ("Torque command", "Torque", "Speed", "Cycle"):
            assert name in r.stdout
        assert "(the safe value)" in r.stdout and "ok: every channel answered" in r.stdout
        assert abs(maplib.float32_of(sim.holding(100, 2)) - 0.25) < 1e-7
    rep = sim.report()
    assert rep["writes"] >= 1 and rep["writes_not_safe"] == 0


# ---- Monte Carlo coverage ----------------------------------------------------------------------------

def run_many(tmp_path, plant, desc, seeds, *sim_args, truth=None, cycles_per_tick=1, **kw):
    """One measurement per seed (a new device and new noise each); the element p-values of all, and the docs.
    Two periods are skipped: the plant's slow pole (0.985) keeps 0.985^64 = 0.38 of the fade-in's transient a
    period later, which a run left with two usable periods cannot tell from the response. A run that msid
    refuses for too few usable periods is made again with a new device at half the rate, down to 50 Hz (the
    device keeps its cycles per tick, so the truth per cycle is the same)."""
    kw.setdefault("skip", 2)
    rates = maplib.halving_rates(kw.pop("rate", 200), 50)
    pv, docs = [], []
    for s in seeds:
        def attempt(k, hz, last, s=s):
            d = maplib.rated(desc, hz, cycles_per_tick)
            with maplib.MapSim(tmp_path, d, "--plant", plant[0], "--cycle-hz", cycles_per_tick * hz, "--seed", s,
                               "--noise-y", "0.02", "--noise-u", "0.002", *sim_args) as sim:
                return maplib.measure(tmp_path, sim, d, seed=s, out=f"run{s}", rate=hz, attempts=1, ok=last, **kw)
        r = maplib.until_usable(rates, attempt, ("usable period(s)", "do not excite line"))
        assert r.returncode == 0, f"msid measure --map failed ({r.returncode}):\n{r.stderr}"
        docs.append(r.doc)
        pv.append(maplib.element_pvalues(r.doc, truth))
    return np.concatenate(pv), docs


def test_coverage_input_read_back(tmp_path, plant):
    desc = maplib.description(tmp_path / "dev.toml", readback=True, counter=True)
    truth = maplib.truth_doc(maplib.dt_frf(*plant[1], BINS, P), BINS)
    pv, docs = run_many(tmp_path, plant, desc, range(1, 11), truth=truth)
    maplib.covered(pv)
    for d in docs:
        assert d["acquisition"]["input"] == "read back"
        assert d["acquisition"]["timing"]["samples_placed_by"] == "device counter"


def test_coverage_commanded_input_by_the_devices_counter(tmp_path, plant):
    # each device cycle gets its sample and is read as itself: the commanded value is the cycle's
    desc = maplib.description(tmp_path / "dev.toml", readback=False, counter=True)
    truth = maplib.truth_doc(maplib.dt_frf(*plant[1], BINS, P), BINS)
    pv, docs = run_many(tmp_path, plant, desc, range(21, 31), truth=truth)
    maplib.covered(pv)
    for d in docs:
        assert d["acquisition"]["input"] == "commanded"
        assert d["acquisition"]["timing"]["samples_placed_by"] == "device counter"


def test_coverage_commanded_input_and_its_bias_bound(tmp_path, plant):
    # no counter, a device that cycles 4 times per tick: the host's timing enters, each line reports its bound
    desc = maplib.description(tmp_path / "dev.toml", readback=False, counter=False, cycle_hz=800)
    G0 = maplib.held_frf(*plant[1], BINS, P, 4)
    truth = maplib.truth_doc(G0, BINS)
    _, docs = run_many(tmp_path, plant, desc, range(31, 39), truth=truth, cycles_per_tick=4)
    # the regions, widened by the bias bound each line reports, cover: the error less |G| bound against the
    # F law (as many inside as an unbiased estimate would have at least), and the error is within the bound plus
    # the noise's own spread (3 sd: a normal error beyond it has a probability of 0.1 % per element)
    pv, within, n = [], 0, 0
    for d in docs:
        for ln, g0 in zip(d["lines"], G0):
            v = canlib.cplx(ln["cov"])[0, 0].real
            e = max(0.0, abs(canlib.cplx(ln["G"])[0, 0] - g0[0, 0]) - abs(g0[0, 0]) * ln["timing_bias"]["bound"])
            pv.append(canlib.f_sf(e * e / v, 2, 2 * ln["dof"]))
    inside = int(np.sum(np.array(pv) > 0.05))
    lo, _ = canlib.binom_interval(len(pv), 0.95, 1e-3)
    assert inside >= lo, f"{inside}/{len(pv)} inside their 95% region widened by the bias bound (at least {lo})"
    for d in docs:
        assert d["acquisition"]["input"] == "commanded"
        for ln, g0 in zip(d["lines"], G0):
            tb = ln["timing_bias"]
            assert 0 < tb["gain"] <= 1 and tb["bound"] >= 0
            sd = np.sqrt(canlib.cplx(ln["cov"])[0, 0].real)
            err = abs(canlib.cplx(ln["G"])[0, 0] - g0[0, 0])
            within += err <= abs(g0[0, 0]) * tb["bound"] + 3 * sd
            n += 1
    assert within >= 0.99 * n, f"{within}/{n} lines within their bias bound + 3 sd" 


def test_coverage_with_the_device_clock_100_ppm_fast(tmp_path, plant):
    # the host follows the device's counter (clock = "device"): its cycles get their samples whatever the offset
    desc = maplib.description(tmp_path / "dev.toml", readback=True, counter=True, clock="device")
    truth = maplib.truth_doc(maplib.dt_frf(*plant[1], BINS, P), BINS)
    pv, docs = run_many(tmp_path, plant, desc, range(41, 49), "--clock-ppm", "100", truth=truth, periods=10)
    maplib.covered(pv)
    for d in docs:
        t = d["acquisition"]["timing"]
        assert t["clock"] == "device" and t["retimes"] >= 1
        # the offset is reported with what a count per tick can resolve over the run
        assert t["device_clock_offset_ppm"] is not None
        assert abs(t["device_clock_offset_ppm"] - 100) <= 3 * t["device_clock_offset_resolution_ppm"]


def test_coverage_over_modbus_rtu(tmp_path, plant):
    # RTU at 115200 baud on a socat pty pair, the simulator taking each frame's wire time (a write and a read a
    # tick, about 20 ms with the silences the line needs): 25 ticks a second
    desc = maplib.description(tmp_path / "dev.toml", readback=True, counter=True)
    # periods of 32 ticks (1.3 s): a sample the loaded line lost costs less of the run
    P2, bins2 = 32, list(range(1, 16, 2))
    truth = maplib.truth_doc(maplib.dt_frf(*plant[1], bins2, P2), bins2)
    pv = []
    for s in (71, 72, 73):
        with maplib.MapSim(tmp_path, desc, "--plant", plant[0], "--cycle-hz", 25, "--seed", s, "--noise-y", "0.02",
                           rtu=True) as sim:
            r = maplib.measure(tmp_path, sim, desc, seed=s, out=f"rtu{s}", rate=25, period=P2, lines="1:2:15",
                               periods=10, attempts=3)
        a = r.doc["acquisition"]
        assert a["transport"] == "modbus-rtu" and a["timing"]["samples_placed_by"] == "device counter"
        # the exchange takes at least its frames' time on the line: 2 x (8 + 13) and (13 + 13) bytes of 10 bits
        assert a["timing"]["round_trip_s"]["median"] >= 0.004
        pv.append(maplib.element_pvalues(r.doc, truth))
    maplib.covered(np.concatenate(pv))


def test_a_counter_that_runs_at_twice_the_tick_rate_is_named(tmp_path):
    # the device cycles at 400 Hz, its counter with it, and the description states no cycle_hz: its samples
    # cannot be placed by its cycles at 200 ticks a second
    desc = maplib.description(tmp_path / "dev.toml", readback=True, counter=True)
    with maplib.MapSim(tmp_path, desc, "--cycle-hz", 400) as sim:
        r = maplib.measure(tmp_path, sim, desc, rate=200, ok=False)
        one_error(r, "does not cycle at the tick rate", "state its cycle_hz")
        m = re.search(r"advanced by ([0-9.]+) per tick", r.stderr)
        assert m and 1.8 <= float(m.group(1)) <= 2.2, r.stderr
    # refused within its first 3 windows of 32 reads (a few more ticks when the host was late), and left at the
    # safe value
    rep = sim.report()
    assert rep["writes_not_safe"] <= 3 * 32 + 8 and set(rep["setpoints"].values()) == {0.0}, rep


def test_ticks_the_host_sleeps_through_are_not_a_fast_device(tmp_path):
    # msid itself stopped for 30 ms in every 40 ms (SIGSTOP, SIGCONT), as a loaded host sleeps through its
    # ticks: the counter steps by several cycles a read while the device still cycles once a tick. The run may
    # be refused for the periods the missed ticks cost (counted) or measured, never refused as a device that
    # cycles at another rate (judged per read, the missed ticks were taken for a device cycling too fast)
    desc = maplib.description(tmp_path / "dev.toml", readback=True, counter=True)
    with maplib.MapSim(tmp_path, desc) as sim:
        o = tmp_path / "out"
        p = subprocess.Popen([maplib.mblib.MSID, "measure", "--device", sim.uri, "--map", desc, "--period", "64", "--lines",
                              "1:2:31", "--periods", "4", "--rate", "200", "--no-realtime", "--no-plots", "-o", str(o)],
                             stderr=subprocess.PIPE, text=True)
        import threading, time
        stop = threading.Event()
        def pulse():
            while not stop.is_set() and p.poll() is None:
                time.sleep(0.010)
                try:
                    p.send_signal(signal.SIGSTOP); time.sleep(0.030); p.send_signal(signal.SIGCONT)
                except ProcessLookupError:
                    return
        t = threading.Thread(target=pulse, daemon=True)
        t.start()
        try:
            _, err = p.communicate(timeout=300)
        finally:
            stop.set(); t.join()
            if p.poll() is None:
                p.send_signal(signal.SIGCONT)
    assert "does not cycle at the tick rate" not in err, err
    assert p.returncode == 0 or "usable period(s)" in err, err


def test_a_rate_the_rtu_line_cannot_carry(tmp_path):
    desc = maplib.description(tmp_path / "dev.toml")
    with maplib.MapSim(tmp_path, desc, rtu=True) as sim:
        r = maplib.measure(tmp_path, sim, desc, rate=400, ok=False)
        one_error(r, "cannot carry 400 ticks per second", "it carries at most about")
    assert sim.report()["writes_not_safe"] == 0


# ---- the safe value on every way out ------------------------------------------------------------------

SAFE = 0.5   # distinct from zero: a device that never saw the safe value does not hold it by accident


def safe_desc(tmp_path):
    return maplib.description(tmp_path / "dev.toml", safe=SAFE, lo=-1.5, hi=2.5,
                              extra_drive="operating_point = 0.5\namplitude = 1.0")


def assert_holds_safe(sim):
    assert abs(maplib.float32_of(sim.holding(100, 2)) - SAFE) < 1e-7


def test_safe_value_at_the_end(tmp_path):
    desc = safe_desc(tmp_path)
    with maplib.MapSim(tmp_path, desc) as sim:
        r = maplib.measure(tmp_path, sim, desc, periods=5)
        assert r.doc["acquisition"]["safe_values_written"]
        assert_holds_safe(sim)


@pytest.mark.parametrize("after", [1, 3, 6])
def test_safe_value_after_ctrl_c(tmp_path, after):
    # SIGINT after `after` progress events: the complete periods are kept (or none, when fewer than 2), and
    # the device holds the safe value
    desc = safe_desc(tmp_path)
    with maplib.MapSim(tmp_path, desc) as sim:
        cmd = [MSID, "measure", "--device", sim.uri, "--map", desc, "--period", str(P), "--lines", LINES,
               "--periods", "8", "--rate", "200", "--no-plots", "-o", str(tmp_path / "out")]
        rc, err = maplib.interrupt_after_periods(cmd, after)
        assert rc == 130, err
        assert_holds_safe(sim)


def test_safe_value_when_the_connection_drops(tmp_path):
    desc = safe_desc(tmp_path)
    with maplib.MapSim(tmp_path, desc, "--drop-after", "300") as sim:
        r = maplib.measure(tmp_path, sim, desc, periods=4, ok=False)
        assert_holds_safe(sim)
    # the run survives the drop (reconnected, the ticks of the drop missing) or fails with one message
    if r.returncode == 0:
        doc = json.loads((tmp_path / "out" / "frf.json").read_text())
        assert doc["acquisition"]["recoveries"] >= 1
    else:
        assert "error:" in r.stderr


def test_safe_value_after_register_exceptions(tmp_path):
    # every 40th request refused with exception 4 (server device failure): missing samples, counted
    desc = safe_desc(tmp_path)
    with maplib.MapSim(tmp_path, desc, "--exception-every", "40:4") as sim:
        r = maplib.measure(tmp_path, sim, desc, periods=6, ok=False)
        assert_holds_safe(sim)
    if r.returncode == 0:
        a = json.loads((tmp_path / "out" / "frf.json").read_text())["acquisition"]
        assert a["exceptions"] >= 1 and a["timing"]["exchanges_failed"] + a["timing"]["exchanges_failed_outside_measured_periods"] >= 1


def test_a_device_that_dies_ends_the_run_with_one_message(tmp_path):
    desc = safe_desc(tmp_path)
    with maplib.MapSim(tmp_path, desc, "--die-after", "400") as sim:
        sim.expect_exit = 9
        r = maplib.measure(tmp_path, sim, desc, "--timeout", "2", periods=8, ok=False)
        assert r.returncode == 1
        assert "did not answer" in r.stderr or "cannot connect" in r.stderr or "reconnecting" in r.stderr, r.stderr
        assert not (tmp_path / "out" / "frf.json").exists()
        sim.p.wait(30)
    rep = sim.report()
    assert rep["requests"] > 400


# ---- bad input: one message, nothing written but the safe value ---------------------------------------

def desc_text(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def one_error(r, *needles):
    lines = [l for l in r.stderr.splitlines() if "error:" in l]
    assert r.returncode != 0 and len(lines) == 1, r.stderr
    for n in needles:
        assert n in lines[0], lines[0]


def test_unknown_register_is_named(tmp_path):
    dev = maplib.description(tmp_path / "dev.toml")
    # msid's description reads a register the device does not map
    text = Path(dev).read_text().replace('register = "input:2"', 'register = "input:7"')
    wrong = desc_text(tmp_path, "wrong.toml", text)
    with maplib.MapSim(tmp_path, dev) as sim:
        r = maplib.measure(tmp_path, sim, wrong, ok=False)
        one_error(r, "illegal data address", "input registers")
        assert not (tmp_path / "out").exists() or not (tmp_path / "out" / "frf.json").exists()
        r = run("device", "check", "--map", wrong, "--device", sim.uri)
        assert r.returncode == 1 and "illegal data address" in r.stdout
    assert sim.report()["writes_not_safe"] == 0


def test_a_type_that_does_not_match(tmp_path):
    dev = maplib.description(tmp_path / "dev.toml")
    # msid believes Speed is a float32 over input:2..3: the device maps input:3 as the counter, int16 as Speed
    text = Path(dev).read_text().replace('register = "input:2"\ntype = "int16"', 'register = "input:2"\ntype = "float32"')
    text = text.replace('register = "input:3"', 'register = "input:5"')
    wrong = desc_text(tmp_path, "wrong.toml", text)
    with maplib.MapSim(tmp_path, dev) as sim:
        r = maplib.measure(tmp_path, sim, wrong, ok=False)
        one_error(r, "illegal data address")
    assert sim.report()["writes_not_safe"] == 0


def test_a_value_outside_min_max_is_refused_before_any_write(tmp_path):
    dev = maplib.description(tmp_path / "dev.toml", extra_drive="amplitude = 1.9\noperating_point = 0.5")
    with maplib.MapSim(tmp_path, dev) as sim:
        r = maplib.measure(tmp_path, sim, dev, ok=False)
        one_error(r, "'Torque command' would reach", "above max", "nothing was written")
    assert sim.report()["writes_not_safe"] == 0


def test_a_rate_the_link_cannot_carry_says_what_it_can(tmp_path):
    dev = maplib.description(tmp_path / "dev.toml")
    with maplib.MapSim(tmp_path, dev, "--delay-every", "1:4") as sim:   # every answer 4 ms late
        r = maplib.measure(tmp_path, sim, dev, rate=1000, ok=False)
        one_error(r, "cannot carry 1000 ticks per second", "it carries at most about")
    assert sim.report()["writes_not_safe"] == 0


def test_a_modbus_exception_is_named(tmp_path):
    dev = maplib.description(tmp_path / "dev.toml")
    with maplib.MapSim(tmp_path, dev, "--exception-every", "1:4") as sim:
        r = maplib.measure(tmp_path, sim, dev, ok=False)
        one_error(r, "exception 4", "server device failure")
    assert sim.report()["writes_not_safe"] == 0


@pytest.mark.parametrize("edit, needle", [
    (('max = 2.0', 'max_stp = 2.0'), "unknown key 'max_stp'"),
    (('register = "holding:100"', 'register = "40101"'), "holding:100"),
    (('safe = 0.0', 'safe = 9.0'), "the safe value 9 is above max 2"),
    (('format = "msid-device/1"', 'format = "msid-device/9"'), "msid reads msid-device/1"),
])
def test_bad_descriptions_fail_before_the_device_is_touched(tmp_path, edit, needle):
    dev = maplib.description(tmp_path / "dev.toml")
    bad = desc_text(tmp_path, "bad.toml", Path(dev).read_text().replace(*edit))
    with maplib.MapSim(tmp_path, dev) as sim:
        r = maplib.measure(tmp_path, sim, bad, ok=False)
        one_error(r, needle)
        assert r.returncode == 2
    assert sim.report()["requests"] == 0
