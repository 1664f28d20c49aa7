"""msid measure --map and msid device check against map_peer.py, an msid-device/1 device written with pymodbus
that reads the description and the plant file on its own (docs/devices.md, "Simulated devices"):
- the description and command of docs/examples/modbus-drive.toml end to end: the FRF from "Torque" to
  "Speed" with their names and units, and the device's own state at the safe value after msid has exited;
- every register type and word order decoded by msid as the peer encoded them, and an address the peer does
  not serve named by msid;
- Monte Carlo over fixed seeds, Modbus TCP (function 23) and Modbus RTU on a socat pty pair at 115200 baud
  (FC 23, the peer taking each frame's line time): with the input read back and a counter channel of a device
  cycling at the tick rate, the 95% regions cover the plant's own G(z) = C (zI - A)^-1 B + D at
  z = exp(j 2 pi bin / P) within binomial bounds, through clock offsets, a counter that wraps and answers held
  back past msid's timeout; a rate the RTU line cannot carry is refused with what it carries, and nothing but
  the safe values was written.
The peer (and socat, the serial cable) run under chrt -f 20 where the machine permits it. Nothing here depends
on how fast the machine is: late answers are missing samples that msid counts, and the checks read those counts
(periods used, acquisition counters); a run left with fewer than two usable periods, which msid refuses naming
the samples missing, is run again (three times at most). The one time checked is a floor: an RTU exchange cannot
take less than the line time the peer takes for its two frames."""
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import maplib
import mblib
from maplib import dt_frf, make_realtime, realtime_prefix, truth_doc, write_plant
from mblib import run
from canlib import binom_interval, row_pvalues  # noqa: E402 (mblib puts it on the path)

HERE = Path(__file__).resolve().parent
PEER = HERE / "map_peer.py"
EXAMPLE = mblib.SRC / "docs" / "examples" / "modbus-drive.toml"


# ---- plants, their truth, descriptions ---------------------------------------------------------------------

def modal_block(r, theta):
    return r * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])


def cycle_plant():
    """A drive's torque to speed at the device's cycle rate: a lightly damped mode at 0.07 cycles per cycle
    (|z| = 0.98), a better damped one at 0.21 (|z| = 0.9), a small feedthrough."""
    A = np.zeros((4, 4))
    A[:2, :2], A[2:, 2:] = modal_block(0.98, 2 * np.pi * 0.07), modal_block(0.9, 2 * np.pi * 0.21)
    return A, np.array([[0.08], [0.04], [0.15], [0.05]]), np.array([[0.6, 0.2, 0.3, 0.25]]), np.array([[0.05]])


def fast_cycle_plant(cycle_hz):
    """The drive of the example on a device cycling at cycle_hz: a mode at 25 Hz (damping 0.08) and a real pole
    at 3 Hz, from torque (N m) to speed (rad/s), a DC gain of 1 and a resonance peak of a few rad/s per N m."""
    h = 1.0 / cycle_hz
    w, z, w1 = 2 * np.pi * 25.0, 0.08, 2 * np.pi * 3.0
    A = np.zeros((3, 3))
    A[:2, :2] = modal_block(np.exp(-z * w * h), w * np.sqrt(1 - z * z) * h)
    A[2, 2] = np.exp(-w1 * h)
    B, C = np.array([[1.0], [0.0], [1.0]]), np.array([[0.0, 1.0, 0.2]])
    C = C / abs(dt_frf(A, B, C, np.zeros((1, 1)), [0], 1)[0, 0, 0])
    return A, B, C, np.zeros((1, 1))


def mc_description(path, rate):
    """Torque command written, the applied torque read back, the speed and the cycle counter read, all in one
    span of holding registers (function 23); a device that cycles at the tick rate."""
    Path(path).write_text(f"""format = "msid-device/1"
transport = "modbus"
unit = 3
cycle_hz = {rate}

[[drive]]
name = "Torque command"
unit = "N m"
register = "holding:20"
type = "float32"
word_order = "DCBA"
min = -2.0
max = 2.0
max_step = 1.8
safe = 0.0

[[measure]]
name = "Torque"
unit = "N m"
role = "input"
register = "holding:0"
type = "float32"
word_order = "CDAB"

[[measure]]
name = "Speed"
unit = "rad/s"
role = "output"
register = "holding:2"
type = "int32"
word_order = "BADC"
scale = 1e-5

[[measure]]
name = "Cycle"
role = "counter"
register = "holding:4"
type = "uint16"
""")
    return str(path)


# ---- the peer --------------------------------------------------------------------------------------------

class Peer(mblib.Sim):
    """map_peer.py on Modbus TCP at 127.0.0.1:0 (a free port) or RTU on a socat pty pair; .uri is the device URI
    msid takes, .state() the peer's state file once it has exited (SIGTERM, mblib.Sim's exit)."""

    def __init__(self, tmp, desc, plant, *args, rtu=False, baud=115200, name="peer", host="127.0.0.1"):
        self.tmp = Path(tmp)
        self.desc, self.plant, self.rtu, self.baud, self.host = str(desc), str(plant), rtu, baud, host
        self.state_path = self.tmp / f"{name}-state.json"
        self.args = [str(a) for a in args]

    def __enter__(self):
        if self.rtu:
            self.pty = mblib.PtyPair().__enter__()
            make_realtime(self.pty.p.pid)
            where = ["--modbus-rtu", self.pty.device, "--baud", str(self.baud)]
        else:
            where = ["--modbus-tcp", f"{self.host}:0"]
        line = self.start(realtime_prefix() + [sys.executable, str(PEER), "--map", self.desc, "--plant", self.plant,
                                               *where, "--state", str(self.state_path), "--idle-exit", "120",
                                               *self.args])
        if self.rtu:
            self.uri = f"modbus-rtu://{self.pty.host}?baud={self.baud}"
        else:
            port = re.search(r"modbus-tcp .*:(\d+) \(unit", line).group(1)
            self.uri = f"modbus-tcp://[{self.host}]:{port}" if ":" in self.host else f"modbus-tcp://{self.host}:{port}"
        return self

    def state(self):
        return json.loads(self.state_path.read_text())


def measure(tmp, peer, desc, *, period, lines, periods, rate, seed, out="out", ok=True):
    o = Path(tmp) / out
    r = run("measure", "--device", peer.uri, "--map", desc, "--period", period, "--lines", lines, "--periods",
            periods, "--skip-periods", 1, "--rate", rate, "--seed", seed, "--no-plots", "-o", o, timeout=300)
    if ok:
        assert r.returncode == 0, f"msid measure --map failed ({r.returncode}):\n{r.stderr}"
        r.doc = json.loads((o / "frf.json").read_text())
    return r


# msid's refusals of a run that lost samples: too few periods left whole, or a line whose read-back input an
# exchange that read nothing or came late left apart in one period (counted in the message's tail)
REFUSED_FOR_LOSSES = (r"only \d usable period\(s\).*with samples missing"
                      r"|do not excite line .*of the run's \d+ measured samples [1-9]\d* were lost")


def measured(tmp, peer_args, peer_opts, desc, *, rate, floor=None, **kw):
    """msid measure against a fresh Peer(dir, *peer_args(desc, hz), **peer_opts), or Peer(dir, *peer_args) for a
    tuple: (its result, the peer's state).
    A run that a busy machine left with fewer than 2 usable periods, or with a line whose read-back input one
    period's losses left apart (msid refuses both, counting the samples lost), is made again against a new peer
    at half the rate, down to `floor` (half the rate unless told): the peer keeps cycling at the tick rate, so
    its FRF per cycle is the same. Any other failure fails."""
    if callable(peer_args):
        rates = maplib.halving_rates(rate, rate / 2 if floor is None else floor)
    else:   # a peer whose cycle rate is its own: three tries at the one rate
        rates, fixed = [rate] * 3, peer_args
        peer_args = lambda d, hz: fixed
    def attempt(k, hz, last):
        d = Path(tmp) / f"attempt{k}"
        d.mkdir()
        dk = maplib.rated(desc, hz, where=d) if len(set(rates)) > 1 else desc
        with Peer(d, *peer_args(dk, hz), **peer_opts) as peer:
            r = measure(d, peer, dk, ok=False, rate=hz, **kw)
        r.state = peer.state()
        if r.returncode == 0:
            r.doc = json.loads((d / "out" / "frf.json").read_text())
        else:
            assert r.returncode == 1 and re.search(REFUSED_FOR_LOSSES, r.stderr), r.stderr
        return r
    r = maplib.until_usable(rates, attempt, ("usable period(s)", "do not excite line"))
    if r.returncode == 0:
        return r, r.state
    raise AssertionError(f"runs at {rates} Hz were all refused for the samples they lost:\n{r.stderr}")


def late_every(k, ticks):
    """--late-every for map_peer.py as a function of the tick rate: every k-th answer held back `ticks` ticks."""
    return lambda hz: ("--late-every", f"{k}:{ticks * 1e3 / hz:g}")


# ---- what every run must show ----------------------------------------------------------------------------

def check_counts(doc, periods):
    """The periods add up, every rejected period has a counted cause, and the samples were placed by the
    device's counter with the input read back."""
    acq, t = doc["acquisition"], doc["acquisition"]["timing"]
    assert acq["input"] == "read back" and t["samples_placed_by"] == "device counter", acq
    (e,) = doc["experiments"]
    assert e["periods_total"] == periods and e["periods_skipped"] == 1
    assert e["periods_used"] + e["periods_gap"] + e["periods_nonfinite"] + len(e["transient_dropped"]) == periods - 1
    assert doc["periods_used"] == e["periods_used"] >= 2
    assert e["periods_nonfinite"] == 0
    # placed by the counter, a sample is lost when its cycle was not read or ran on another cycle's value (a
    # failed exchange or a missed tick shows as such cycles); every measured sample is used or counted lost
    assert acq["samples_lost"] == t["cycles_not_read"], t
    assert acq["samples"] + acq["samples_lost"] == periods * doc["period_samples"], acq
    if e["periods_gap"]:   # a period with samples missing: msid counted why
        assert acq["samples_lost"] > 0, t
    # the device answers every request it gets (on RTU an answer later than msid's timeout may be read as a bad
    # reply to the next request: counted, and its sample missing)
    assert acq["exceptions"] == 0 and acq["safe_values_written"] is True


def check_peer(state, acq, safe):
    """The device's own account: it holds the safe values, msid never wrote outside [min, max] nor a step beyond
    max_step, never touched an address the device does not serve, used only its functions, and every request
    msid sent on a connection it kept reached the device."""
    assert state["setpoints"] == safe, state
    c = state["counters"]
    assert c["writes_outside_range"] == 0 and c["steps_over_max_step"] == 0 and c["setpoints_not_finite"] == 0, c
    assert c["refused_address"] == 0 and c["refused_function"] == 0 and c["refused_unit"] == 0, c
    if acq["recoveries"] == 0:
        assert c["requests"] == acq["requests"], (c, acq["requests"])


def check_pooled_coverage(pvalues, alpha=1e-3):
    """Rows inside their 95% regions, over all runs (independent noise): inside the two-sided Bin(N, 0.95)
    interval at level alpha."""
    p = np.concatenate(pvalues)
    inside = int(np.sum(p > 0.05))
    lo, hi = binom_interval(len(p), 0.95, alpha)
    assert lo <= inside <= hi, f"{inside}/{len(p)} rows inside their 95% regions; Bin({len(p)}, 0.95): [{lo}, {hi}]"
    return inside, len(p)


def check_late_answers(acq, state, line_s):
    """Answers the peer held back past msid's timeout: each a timeout, and the answer that came after it skipped
    as stale (not taken for a later request's: then every exchange after it would take the one before's answer,
    and look faster than the line can carry its two frames)."""
    late = state["counters"]["answers_late"]
    if late:
        assert acq["timeouts"] >= late and acq["skipped_replies"] >= 1, (late, acq)
    if line_s:
        assert acq["timing"]["round_trip_s"]["median"] >= line_s, (acq["timing"]["round_trip_s"], line_s)


def monte_carlo(tmp_path, runs, *, rate, rtu, period=64, lines="1:2:31", periods=10, line_s=0.0, floor=None):
    """One msid measure per run against a fresh peer; each run's counts checked; the pooled coverage. A run's
    peer arguments are a tuple or a function of the tick rate (measured() may halve it). line_s: the line time of
    one exchange (RTU), the least an honest round trip takes."""
    desc = mc_description(tmp_path / "mc.toml", rate)
    A, B, C, D = cycle_plant()
    plant = write_plant(tmp_path / "mc.plant", A, B, C, D)
    pv = []
    for k, extra in enumerate(runs):
        run_dir = tmp_path / f"run{k}"
        run_dir.mkdir()
        args = lambda d, hz: (d, plant, "--seed", 100 + k, *(extra(hz) if callable(extra) else extra))
        r, state = measured(run_dir, args, {"rtu": rtu}, desc, period=period, lines=lines, periods=periods,
                            rate=rate, floor=floor, seed=k + 1)
        doc = r.doc
        check_counts(doc, periods)
        assert doc["acquisition"]["timing"]["exchange"].startswith("FC 23"), doc["acquisition"]["timing"]["exchange"]
        check_peer(state, doc["acquisition"], {"Torque command": 0.0})
        check_late_answers(doc["acquisition"], state, line_s)
        bins = [ln["bin"] for ln in doc["lines"]]
        pv.append(row_pvalues(doc, truth_doc(dt_frf(A, B, C, D, bins, period), bins)))
    return check_pooled_coverage(pv)


# ---- the tests -------------------------------------------------------------------------------------------

# The line time of one FC 23 exchange of mc_description at 115200 baud: frames of 17 and 15 bytes (10 bits a
# byte), each with its 1.75 ms silence (as map_peer.py takes it).
RTU_LINE_S = 2 * 1.75e-3 + (17 + 15) * 10 / 115200

def test_the_documented_example_end_to_end(tmp_path):
    """docs/examples/modbus-drive.toml and its command. The description states no cycle_hz: the peer cycles at
    10 kHz, fast against the time between a tick's write and its read, so that the read-back torque is the one
    just written (a device cycling near the tick rate without a counter would mix two ticks' inputs unseen)."""
    cycle_hz = 10000
    plant = write_plant(tmp_path / "drive.plant", *fast_cycle_plant(cycle_hz))
    r, state = measured(tmp_path, (EXAMPLE, plant, "--cycle-hz", cycle_hz, "--seed", 7), {}, str(EXAMPLE),
                        period=256, lines="1:2:99", periods=6, rate=200, seed=1)
    doc = r.doc
    assert doc["input_names"] == ["Torque"] and doc["input_units"] == ["N m"]
    assert doc["output_names"] == ["Speed"] and doc["output_units"] == ["rad/s"]
    assert [ln["bin"] for ln in doc["lines"]] == list(range(1, 100, 2))
    acq = doc["acquisition"]
    assert acq["input"] == "read back" and acq["protocol"] == "msid-device/1"
    assert acq["timing"]["exchange"].startswith("1 FC 16 write(s) + 1 read(s)"), acq["timing"]["exchange"]
    assert doc["periods_used"] >= 2
    check_peer(state, acq, {"Torque command": 0.0})
    # the resonance where the plant has it: the largest |G| within two lines of the truth's at the tick rate
    G = np.abs([mblib.cplx(ln["G"])[0] for ln in doc["lines"]])
    bins = np.array([ln["bin"] for ln in doc["lines"]])
    f_peak = 25.0 * np.sqrt(1 - 2 * 0.08 ** 2)
    assert abs(bins[int(np.argmax(G))] - f_peak * 256 / 200) <= 4, (bins[int(np.argmax(G))], f_peak)


def codec_description(path, plant_path):
    """One output channel per register type and word order, each with a value that uses every byte (signed
    ones negative), behind a static plant y = D u with u = 1 (the safe value)."""
    raws = {"int16": (-12345, 0.01, 100.0), "uint16": (54321, 1.0, 0.0), "int32": (-123456789, 1e-3, 0.0),
            "uint32": (3456789012, 1.0, -5.0), "float32": (1234.5677490234375, 1.0, 0.0),
            "float64": (-9876.54321012345, 1.0, 0.0)}
    text = ('format = "msid-device/1"\ntransport = "modbus"\n\n[[drive]]\nname = "u"\nregister = "holding:900"\n'
            'type = "float32"\nsafe = 1.0\nmin = -2.0\nmax = 2.0\n')
    values, addr = {}, 0
    for typ, (raw, scale, offset) in raws.items():
        for wo in ("ABCD", "CDAB", "BADC", "DCBA"):
            name = f"{typ} {wo}"
            text += (f'\n[[measure]]\nname = "{name}"\nrole = "output"\nregister = "input:{addr}"\ntype = "{typ}"\n'
                     f'word_order = "{wo}"\nscale = {scale!r}\noffset = {offset!r}\n')
            values[name] = raw * scale + offset
            addr += {"int16": 1, "uint16": 1, "int32": 2, "uint32": 2, "float32": 2, "float64": 4}[typ] + 1
    Path(path).write_text(text)
    D = np.array([[v] for v in values.values()])
    write_plant(plant_path, np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((len(values), 0)), D)
    return values


def test_every_type_and_word_order_decoded_as_the_peer_encoded_it(tmp_path):
    desc, plant = tmp_path / "codec.toml", tmp_path / "codec.plant"
    values = codec_description(desc, plant)
    with Peer(tmp_path, desc, plant, "--noise-y", 0, "--cycle-hz", 100) as peer:
        r = run("device", "check", "--map", desc, "--device", peer.uri)
        assert r.returncode == 0, r.stdout + r.stderr
        # a description naming a register the device does not serve: msid names the channel and the refusal
        bad = tmp_path / "bad.toml"
        bad.write_text(desc.read_text() + '\n[[measure]]\nname = "Not served"\nrole = "reference"\n'
                       'register = "input:5000"\ntype = "uint16"\n')
        rb = run("device", "check", "--map", bad, "--device", peer.uri)
    seen = {}
    for line in r.stdout.splitlines():
        m = re.match(r"\s+(\w+ [A-D]{4})\s+output\s+input:\d+\s+\w+\s+= (\S+)", line)
        if m:
            seen[m.group(1)] = float(m.group(2))
    assert seen.keys() == values.keys(), r.stdout
    for name, v in values.items():   # msid prints 9 significant digits
        assert abs(seen[name] - v) <= 1e-8 * abs(v), (name, seen[name], v)
    assert rb.returncode != 0, rb.stdout + rb.stderr
    out = rb.stdout + rb.stderr
    assert re.search(r"input registers 5000\.\.5000 \(function 4; 'Not served'\).*exception 2", out), out
    state = peer.state()
    assert state["setpoints"] == {"u": 1.0} and state["counters"]["writes_not_safe"] == 0, state
    assert state["counters"]["refused_address"] >= 1, state


def test_a_device_on_ipv6(tmp_path):
    """The peer listens on ::1 only: msid reaches it by its bracketed address (libmodbus's IPv4-only backend
    could not), reads every channel and leaves the safe value."""
    desc, plant = tmp_path / "codec.toml", tmp_path / "codec.plant"
    values = codec_description(desc, plant)
    with Peer(tmp_path, desc, plant, "--noise-y", 0, "--cycle-hz", 100, host="::1") as peer:
        assert peer.uri.startswith("modbus-tcp://[::1]:"), peer.uri
        r = run("device", "check", "--map", desc, "--device", peer.uri)
        assert r.returncode == 0, r.stdout + r.stderr
        assert len([l for l in r.stdout.splitlines() if re.match(r"\s+\w+ [A-D]{4}\s+output", l)]) == len(values)
    assert peer.state()["setpoints"] == {"u": 1.0}


def test_coverage_over_seeds_modbus_tcp(tmp_path):
    """Five runs: one with the device's clock 300 ppm fast, one 250 ppm slow, one whose 16-bit counter wraps
    during the measured periods (a device that had been running for a while), one whose every 250th answer
    comes 8 ms late (past the 4.5 ms timeout of a 200 Hz tick)."""
    runs = [(), ("--clock-ppm", 300), ("--clock-ppm", -250), ("--counter-start", 65536 - 400),
            late_every(250, 1.6)]
    inside, n = monte_carlo(tmp_path, runs, rate=200, rtu=False, floor=50)
    assert n == 5 * 16


def test_coverage_over_seeds_modbus_rtu(tmp_path):
    """Over RTU at 115200 baud one function 23 exchange of this description takes RTU_LINE_S (6.3 ms) of line
    time: 50 Hz leaves 20 ms a tick, room for a busy machine to answer late now and then (a late answer is a
    missing sample, counted). First, 400 Hz is refused with what the line carries, before anything but the safe
    values is written. One run has every 250th answer 25 ms late (past the 18 ms timeout): an RTU frame has no
    transaction id, and that answer must not be taken for the next request's."""
    desc = mc_description(tmp_path / "mc400.toml", 400)
    plant = write_plant(tmp_path / "mc.plant", *cycle_plant())
    with Peer(tmp_path, desc, plant, rtu=True, name="refused") as peer:
        r = measure(tmp_path, peer, desc, period=64, lines="1:2:31", periods=10, rate=400, seed=1, ok=False)
    mblib.fails(tmp_path, r, 2, "cannot carry 400 ticks per second", "FC 23")
    assert not (tmp_path / "out" / "frf.json").exists()
    carried = int(re.search(r"it carries at most about (\d+) Hz", r.stderr).group(1))
    assert 1 <= carried <= 0.8 / RTU_LINE_S, (carried, r.stderr)
    c = peer.state()["counters"]
    assert c["writes"] > 0 and c["writes_not_safe"] == 0, c
    runs = [(), ("--clock-ppm", 200), late_every(250, 1.25)]
    inside, n = monte_carlo(tmp_path, runs, rate=50, rtu=True, line_s=RTU_LINE_S, floor=25)
    assert n == 3 * 16
