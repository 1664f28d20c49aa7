"""msid measure over canopen:// with the torque-loop preset (preset = "csv-torque-loop") against msid-devsim
--canopen 5 at 25 Hz (as test_measure_canopen_csv.py, whose rate and design it shares): the drive in CSV holds
hold_velocity with its own PI velocity loop around the two-mass plant, msid writes the excitation each SYNC to the
torque offset 0x60B2 (the reference r, which the node adds to its loop's output) and reads back, from the TPDOs
of each SYNC, the offset the drive applied, the torque demand u and the actual values; it estimates the FRF from r
to every signal (reference.json) and the plant through the reference (frf.json, G = G_yr G_ur^-1).
- coverage: over three seeds, the 95% regions cover, within binomial bounds (alpha 1e-3), the exact values
  computed here from the node's documented discrete model (comap.loop_parts, not msid): u = S r with the loop's
  sensitivity S = 1 / (1 + C Gp), the velocity of the TPDO set z Gp S, and the plant z Gp;
- a negative control: the velocity row against Gp S (without the SYNC between the reference and the velocity of
  a TPDO set) covers fewer lines than the lower binomial bound;
- every way out leaves the torque offset and the velocity target at 0 on the node (read by the canopen package)
  and the node out of "operation enabled", with no SYNC after the end.
The rated torque 0x6076 is 10 mN m (as in the csv-loop test: a count of the torques is then far below the loop's
noise). A run left with too few usable periods by a loaded VM is made again (comap.measure)."""
import json

import numpy as np

import canlib
from comap import Drive, loop_parts, maplib, measure, remote_node, row_pvalues, state_name, syncs_within

RATE, P, LINES, BINS = 25, 32, "1:2:15", list(range(1, 16, 2))
NOISE = ("--noise-y", "0.1")   # rad/s on the velocity the drive measures (reported and fed back)
RATED_MNM = 10
HOLD = 2.0                     # rad/s the velocity loop holds

DESC = f"""format = "msid-device/1"
transport = "canopen"
name = "simulated CiA 402 drive, torque loop"
preset = "csv-torque-loop"
velocity_scale = 0.001
velocity_unit = "rad/s"
position_scale = 1e-6
position_unit = "rad"
hold_velocity = {HOLD}

[[drive]]
safe = 0.0
min = -0.02
max = 0.02
max_step = 0.05
amplitude = 0.005
"""


def test_torque_loop_plant_and_sensitivity_through_the_reference(tmp_path):
    desc = tmp_path / "tq.toml"
    desc.write_text(DESC)
    z, gp, C = loop_parts(RATE, BINS, P)
    S = 1.0 / (1.0 + C * gp)
    col = lambda g: np.asarray(g).reshape(-1, 1, 1)   # noqa: E731  (row_pvalues takes [L, 1, 1])
    pv = {"plant": [], "S": [], "zGpS": [], "GpS": []}
    for s in range(1, 4):
        with Drive(tmp_path, "--seed", s, *NOISE) as sim:
            assert sim.write(0x6076, RATED_MNM) == RATED_MNM
            r = measure(tmp_path, sim, desc, seed=s, out=f"run{s}", period=P, lines=LINES, rate=RATE, periods=8)
            assert syncs_within(0.5) == 0
            with remote_node() as n:
                st, offset, target = n.sdo[0x6041].raw, n.sdo[0x60B2].raw, n.sdo[0x60FF].raw
            assert state_name(st) in ("switch on disabled", "quick stop active"), hex(st)
            assert offset == 0 and target == 0, (offset, target)   # the safe values, written on the way out
        doc = r.doc
        ref = json.loads((tmp_path / f"run{s}" / "reference.json").read_text())
        a = doc["acquisition"]
        assert a["mode"].startswith("cyclic synchronous velocity"), a
        assert a["safe_values_written"] is True, a
        assert doc["input_names"] == ["Torque demand"], doc["input_names"]
        assert doc["output_names"] == ["Torque actual", "Velocity actual", "Position actual"]
        assert ref["input_names"] == ["Torque reference"]
        assert ref["output_names"] == ["Torque demand", "Torque actual", "Velocity actual", "Position actual"]
        assert doc["reference"]["input"] == "Torque demand" and doc["reference"]["signal"] == "Torque reference"
        assert f"preset csv-torque-loop, the velocity loop holding {HOLD:g} rad/s" in r.stderr, r.stderr
        assert [l["bin"] for l in doc["lines"]] == BINS and [l["bin"] for l in ref["lines"]] == BINS
        pv["plant"].append(row_pvalues(doc, col(z * gp), "Velocity actual"))
        pv["S"].append(row_pvalues(ref, col(S), "Torque demand"))
        pv["zGpS"].append(row_pvalues(ref, col(z * gp * S), "Velocity actual"))
        pv["GpS"].append(row_pvalues(ref, col(gp * S), "Velocity actual"))
    found = {k: np.concatenate(v) for k, v in pv.items()}
    print({k: f"{int(np.sum(v > 0.05))}/{len(v)}" for k, v in found.items()})
    for k in ("plant", "S", "zGpS"):
        maplib.covered(found[k])
    lo, _ = canlib.binom_interval(len(found["GpS"]), 0.95, 1e-3)
    assert int(np.sum(found["GpS"] > 0.05)) < lo, "Gp S is covered as well: the test cannot fail"
