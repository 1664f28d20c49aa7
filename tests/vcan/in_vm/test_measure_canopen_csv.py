"""msid measure over canopen:// in cyclic synchronous velocity with the closed-loop preset (preset = "csv-loop")
against msid-devsim --canopen 5 at 25 Hz (the VM, shared with other work, misses whole ticks at 50 Hz): the excitation is added to the velocity target at an operating point,
the drive's own PI velocity loop (its gains follow the SYNC period 0x1006) closes around the two-mass plant, and
the drive's velocity measurement noise (--noise-y) enters the loop. msid reads back, from the TPDOs of each SYNC,
the velocity target the drive applied (the reference r), the torque demand u and the actual values, estimates the
FRF from r to every signal (reference.json) and the plant through the reference (frf.json, G = G_yr G_ur^-1).
- coverage: over five seeds, the 95% regions cover, within binomial bounds (alpha 1e-3), the exact values computed
  here with numpy and scipy from the node's documented discrete model (docs/devices.md), not by msid: the plant
  from the torque demand to the velocity z e2' (zI - A)^-1 B, the control sensitivity C S from the reference to the
  demand and z T from the reference to the velocity (C the drive's PI at the SYNC period, T = Gp C S);
- a negative control: the same regions against the same values without the SYNC between the reference and
  the velocity of a TPDO set (plant / z, T instead of z T) cover fewer lines than the lower binomial bound;
- the node's own state after the end (read by the canopen package): out of "operation enabled", SYNC stopped;
- msid.measure in process on the same node: .reference_frf holds the reference path (one run).
The rated torque 0x6076 is set to 10 mN m by SDO before the runs (the torque's per mille counts then resolve
10 uN m, far below the loop's noise; at 1 N m a count is as large as the demand's share of a line, and the
demand's rounding would be a periodic distortion of the loop). No check depends on the VM being fast: a late
answer is a lost sample, counted, and a run left with too few usable periods is made again (comap.measure)."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import canlib
from comap import NODE, Drive, loop_parts, maplib, measure, state_name, syncs_within

RATE, P, LINES, BINS = 25, 32, "1:2:15", list(range(1, 16, 2))
NOISE = ("--noise-y", "0.1")   # rad/s on the velocity the drive measures (reported and fed back)
RATED_MNM = 10

DESC = """format = "msid-device/1"
transport = "canopen"
name = "simulated CiA 402 drive, velocity loop"
preset = "csv-loop"
velocity_scale = 0.001
velocity_unit = "rad/s"
position_scale = 1e-6
position_unit = "rad"

[[drive]]
safe = 0.0
operating_point = 2.0
min = -10.0
max = 10.0
max_step = 20.0
amplitude = 3.0
"""


def loop_truth(rate=RATE, bins=BINS):
    """The exact FRFs of the node's closed loop at the bins (docs/devices.md, "The simulated drive"): the TPDO of
    SYNC k+1 carries the target r[k] applied at SYNC k, the demand tau[k] = kp e[k] + I[k], I[k] = I[k-1] +
    ki T e[k], e[k] = r[k] - w[k] (w the measured velocity, which 0x606C shows), and w[k+1]. With
    Gp = e2' (zI - A)^-1 B, C = kp + ki T z / (z - 1), S = 1 / (1 + C Gp): plant z Gp, reference to demand C S,
    reference to velocity z Gp C S. Gains: wc = min(2 pi 20, 0.2 / T), kp = J wc, ki = J wc^2 / 4, J = 3e-4."""
    z, gp, C = loop_parts(rate, bins, P)
    S = 1.0 / (1.0 + C * gp)
    return z * gp, C * S, z * gp * C * S


def pvalues(doc, output, truth):
    i = doc["output_names"].index(output)
    out = []
    for line, g0 in zip(doc["lines"], truth):
        G, V = canlib.cplx(line["G"]), canlib.cplx(line["cov"])
        q = abs(G[i, 0] - g0) ** 2 / V[i, i].real
        out.append(canlib.f_sf(q, 2, 2 * line["dof"]))
    assert [l["bin"] for l in doc["lines"]] == BINS
    return np.array(out)


def test_closed_loop_plant_and_sensitivity_through_the_reference(tmp_path):
    desc = tmp_path / "csv.toml"
    desc.write_text(DESC)
    plant, cs, zt = loop_truth()
    # the negative control: the same values without the one SYNC between the reference and demand and the
    # velocity of a TPDO set (what a reader that ignores the node's sampling would take for the truth)
    z = np.exp(2j * np.pi * np.array(BINS) / P)
    pv = {"plant": [], "cs": [], "zt": [], "plant/z": [], "T": []}
    for s in range(1, 6):
        with Drive(tmp_path, "--seed", s, *NOISE) as sim:
            assert sim.write(0x6076, RATED_MNM) == RATED_MNM
            r = measure(tmp_path, sim, desc, seed=s, out=f"run{s}", period=P, lines=LINES, rate=RATE, periods=10)
            assert syncs_within(0.5) == 0
            st = sim.state()
            assert state_name(st["statusword"]) in ("switch on disabled", "quick stop active"), st
        doc = r.doc
        ref = json.loads((tmp_path / f"run{s}" / "reference.json").read_text())
        a = doc["acquisition"]
        assert a["mode"].startswith("cyclic synchronous velocity"), a
        assert a["rated_torque_nm"] == RATED_MNM * 1e-3, a
        assert doc["input_names"] == ["Torque demand"], doc["input_names"]
        assert doc["output_names"] == ["Torque actual", "Velocity actual", "Position actual"]
        assert ref["input_names"] == ["Velocity reference"]
        assert ref["output_names"] == ["Torque demand", "Torque actual", "Velocity actual", "Position actual"]
        assert doc["reference"]["input"] == "Torque demand" and doc["reference"]["signal"] == "Velocity reference"
        pv["plant"].append(pvalues(doc, "Velocity actual", plant))
        pv["plant/z"].append(pvalues(doc, "Velocity actual", plant / z))
        pv["T"].append(pvalues(ref, "Velocity actual", zt / z))
        pv["cs"].append(pvalues(ref, "Torque demand", cs))
        pv["zt"].append(pvalues(ref, "Velocity actual", zt))
    found = {k: np.concatenate(v) for k, v in pv.items()}
    print({k: f"{int(np.sum(v > 0.05))}/{len(v)}" for k, v in found.items()})
    for k in ("plant", "cs", "zt"):
        maplib.covered(found[k])
    for k in ("plant/z", "T"):
        lo, _ = canlib.binom_interval(len(found[k]), 0.95, 1e-3)
        assert int(np.sum(found[k] > 0.05)) < lo, f"{k} is covered as well: the test cannot fail"


def test_msid_measure_in_process_returns_the_reference_path(tmp_path):
    """msid.measure(..., map=) with the preset in process (docs/python.md): the FRF returned is the plant through
    the reference and .reference_frf the FRF from the reference to every signal (reference.json's content) as an
    msid.FRF: the signals' names, the plant G_yr / G_ur of the reference path at every line, and one run's C S and
    z T rows inside their 95% regions at 12 or more of the 16 (P(Bin(16, 0.95) < 12) < 1e-3); the negative
    control, T without the SYNC, at 4 or fewer of 8 (P(Bin(8, 0.95) <= 4) < 1e-3). Skipped only when the build
    has no Python module (MSID_PYTHON_DIR unset)."""
    if not os.environ.get("MSID_PYTHON_DIR"):
        pytest.skip("this build has no Python module (MSID_PYTHON_DIR)")
    sys.path.insert(0, os.environ["MSID_PYTHON_DIR"])
    import msid
    desc = tmp_path / "csv.toml"
    desc.write_text(DESC)
    _, cs, zt = loop_truth()
    with Drive(tmp_path, "--seed", 2, *NOISE) as sim:
        assert sim.write(0x6076, RATED_MNM) == RATED_MNM
        # a run a loaded VM left with too few usable periods, or whose probe met a stalled node, is made again
        for attempt in range(3):
            try:
                f = msid.measure(sim.uri, msid.design(period=P, lines=LINES, seed=2), map=str(desc), rate=RATE,
                                 periods=10, skip_periods=2, timeout=600)
                break
            except (ValueError, OSError) as e:
                if not any(w in str(e) for w in ("usable period(s)", "one tick's exchange failed")) or attempt == 2:
                    raise
        assert syncs_within(0.5) == 0
    ref = f.reference_frf
    assert isinstance(ref, msid.FRF), ref
    assert ref.signal_names() == (["Velocity reference"],
                                  ["Torque demand", "Torque actual", "Velocity actual", "Position actual"])
    assert f.signal_names() == (["Torque demand"], ["Torque actual", "Velocity actual", "Position actual"])
    assert f.meta["reference"]["input"] == "Torque demand"
    assert list(ref.bins) == BINS and list(f.bins) == BINS
    assert ref.meta["acquisition"]["protocol"] == "msid-device/1" and ref.notes == f.notes
    assert np.allclose(f.G[:, :, 0], ref.G[:, 1:, 0] / ref.G[:, :1, 0], rtol=1e-12, atol=0)
    doc = msid.files.frf_to_doc(ref)
    p = np.concatenate([pvalues(doc, "Torque demand", cs), pvalues(doc, "Velocity actual", zt)])
    z = np.exp(2j * np.pi * np.array(BINS) / P)
    p_t = pvalues(doc, "Velocity actual", zt / z)
    print(f"C S and z T: {int(np.sum(p > 0.05))}/16 inside; T: {int(np.sum(p_t > 0.05))}/8")
    assert int(np.sum(p > 0.05)) >= 12
    assert int(np.sum(p_t > 0.05)) <= 4, "T is covered as well: the test cannot fail"


def test_the_preset_csv_loop_refuses_a_description_of_two_drives(tmp_path):
    desc = tmp_path / "two.toml"
    desc.write_text(DESC + "\n[[drive]]\nname = \"second\"\nsafe = 0.0\n")
    r = subprocess.run([str(canlib.MSID), "measure", "--device", f"canopen://vcan0?node={NODE}", "--map", str(desc),
                        "--rate", str(RATE), "--period", str(P), "--lines", LINES, "-o", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert "preset = \"csv-loop\" takes one [[drive]] table" in r.stderr, r.stderr
