"""msid.measure: a device measured in process from Python (tools/acquire under the compiled module),
against the real msid-devsim over Modbus TCP on 127.0.0.1 and against `msid measure` on the same
samples. No timing assertions; fixed seeds. docs/python.md."""
import json
import os
import signal
import socket
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, os.environ.get("MSID_PYTHON_DIR", ""))
sys.path.insert(0, str(HERE.parent / "common"))
from mblib import Sim, canlib, check_coverage, run  # noqa: E402
from no_process import refuse_processes  # noqa: E402
import msid  # noqa: E402

DESIGN = dict(period=256, lines="1:3:120", amplitudes=0.2, seed=7, inputs=2, experiments=2)


def uri(sim):
    return f"modbus-tcp://127.0.0.1:{sim.port}"


def same_bits(a, b):
    for k in ("G", "cov", "dof", "cov_known_input", "freq", "bins"):
        x, y = getattr(a, k), getattr(b, k)
        assert (x is None) == (y is None), k
        if x is not None:
            assert x.shape == y.shape and np.array_equal(x, y), k
    for k in ("periods_used", "periods_rejected", "noise_cov", "experiments"):
        ka, kb = a.meta.get(k), b.meta.get(k)
        if k == "experiments":   # the sources name the link (another port)
            ka = [{x: v for x, v in e.items() if x != "source"} for e in ka]
            kb = [{x: v for x, v in e.items() if x != "source"} for e in kb]
        assert ka == kb, k


def test_measure_in_process_same_bits_as_cli(tmp_path, monkeypatch):
    """The FRF of msid.measure equals `msid measure`'s on a second simulator with the same seed (the same
    samples) bit for bit, covers the simulator's true plant (exact regions, binomial interval), carries
    the acquisition block, and no process is started."""
    d = msid.design(**DESIGN)
    d.save(tmp_path / "design.json")
    states = []
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
    with Sim(tmp_path / "a", "--seed", 5, "--noise-y", 0.02) as sim:
        with monkeypatch.context() as mp:
            refuse_processes(mp)
            f = msid.measure(uri(sim), d, periods=6, skip_periods=1, progress=states.append)
        truth = sim.truth()
    out = tmp_path / "cli"
    with Sim(tmp_path / "b", "--seed", 5, "--noise-y", 0.02) as sim2:
        r = run("measure", "--device", uri(sim2), "--design", tmp_path / "design.json", "--periods", 6,
                "--skip-periods", 1, "--no-plots", "--quiet", "-o", out)
        assert r.returncode == 0, r.stderr
    same_bits(f, msid.read_frf(out / "frf.json"))
    assert f.reference_frf is None and not (out / "reference.json").exists()   # no reference path
    assert f.meta["complete"] is True and f.meta["experiments_completed"] == 2
    acq = f.meta["acquisition"]
    assert acq["transport"] == "modbus-tcp" and acq["samples_lost"] == 0 and acq["device"] == uri(sim)
    inside, n = check_coverage(msid.files.frf_to_doc(f), truth)
    assert n == 40 * 2
    # progress: both experiments, periods counted up to the last one (a poll of a fast link can bring several)
    seen = [(s["experiment"], s["periods"]) for s in states]
    assert seen == sorted(seen) and {e for e, _ in seen} == {1, 2}, seen
    assert max(k for e, k in seen if e == 1) == 6 and states[-1]["periods"] == 6, seen
    assert states[-1]["periods_total"] == 12 and states[-1]["experiments"] == 2
    assert set(states[0]) == {"experiment", "experiments", "periods", "periods_target", "periods_total", "rejected",
                              "samples_lost", "link_errors", "snr_db", "eta_s"}


@pytest.mark.parametrize("how", ["raise", "signal"])
def test_ctrl_c_keeps_the_complete_periods(tmp_path, how):
    """Ctrl-C during the second experiment: MeasurementInterrupted (a KeyboardInterrupt) holds the FRF of
    every complete period, marked incomplete, as `msid measure` keeps it. Both ways Python sees Ctrl-C:
    KeyboardInterrupt raised inside the progress callable, and a real SIGINT seen between polls."""
    d = msid.design(**DESIGN)

    def progress(s):
        if s["experiment"] == 2 and s["periods"] >= 3:
            if how == "raise":
                raise KeyboardInterrupt
            os.kill(os.getpid(), signal.SIGINT)

    with Sim(tmp_path, "--seed", 5, "--noise-y", 0.02) as sim:
        with pytest.raises(msid.MeasurementInterrupted) as stop:
            msid.measure(uri(sim), d, periods=40, skip_periods=1, progress=progress)
    f = stop.value.frf
    assert isinstance(stop.value, KeyboardInterrupt)
    assert f.meta["complete"] is False and f.meta["experiments_completed"] == 1
    assert "stopped by signal 2 during experiment 2 of 2" in f.meta["incomplete_reason"]
    used = [e["periods_used"] for e in f.meta["experiments"]]
    assert used[0] == 39 and 2 <= used[1] < 39, used
    assert any("complete periods acquired before the stop" in n for n in f.notes)
    assert np.all(np.isfinite(f.G)) and np.all(np.isfinite(f.cov))


def test_ctrl_c_before_two_periods_is_a_plain_interrupt(tmp_path):
    """Stopped before the first experiment has 2 usable periods: no FRF exists, KeyboardInterrupt with msid's
    reason (not MeasurementInterrupted)."""
    d = msid.design(**DESIGN)

    def progress(s):
        raise KeyboardInterrupt

    with Sim(tmp_path, "--seed", 5) as sim:
        with pytest.raises(KeyboardInterrupt, match="usable period") as stop:
            msid.measure(uri(sim), d, periods=6, skip_periods=1, progress=progress)
    assert not isinstance(stop.value, msid.MeasurementInterrupted)


def test_progress_exception_is_raised_again(tmp_path):
    """An error in the progress callable ends the run, and it is that error the caller gets."""
    d = msid.design(**DESIGN)

    def progress(s):
        if s["periods_total"] >= 4:
            raise RuntimeError("my progress bar broke")

    with Sim(tmp_path, "--seed", 5) as sim:
        with pytest.raises(RuntimeError, match="my progress bar broke"):
            msid.measure(uri(sim), d, periods=6, progress=progress)


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def test_bad_requests(tmp_path):
    """One exception each, with msid's message: ValueError for a bad request, OSError for a device that
    cannot be reached."""
    d = msid.design(**DESIGN)
    with pytest.raises(ValueError, match="is not a device URI"):
        msid.measure("192.168.1.20", d)
    with pytest.raises(ValueError, match="unknown parameter 'bogus'"):
        msid.measure("modbus-tcp://127.0.0.1:502?bogus=1", d)
    with pytest.raises(ValueError, match="periods must be 2"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, periods=1)
    with pytest.raises(ValueError, match="periods 4 with skip_periods 3 leaves fewer than 2 periods"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, periods=4, skip_periods=3)
    with pytest.raises(ValueError, match="rate must be a whole number"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, rate=10.5)
    with pytest.raises(TypeError, match="progress must be callable"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, progress=3)
    with pytest.raises(OSError, match="127.0.0.1"):
        msid.measure(f"modbus-tcp://127.0.0.1:{free_port()}", d, periods=4)
    with Sim(tmp_path, "--seed", 5) as sim:
        with pytest.raises(ValueError, match="the device has 2 input\\(s\\) but the design has 1"):
            msid.measure(uri(sim), msid.design(period=256, lines="1:3:120", amplitudes=0.2), periods=4)
        # the simulator still serves a good request after the refusals
        f = msid.measure(uri(sim), d, periods=3, skip_periods=1)
        assert f.meta["complete"] is True


def test_on_device_same_bits_as_cli(tmp_path, monkeypatch):
    """on_device=True: the device estimates (estimate/1) and msid.measure reads its result block; with
    stream_check the host's estimate from the streamed samples agrees bit for bit (.host_frf). Both equal
    `msid modbus measure --on-device` on a simulator with the same seed; no process is started."""
    d = msid.design(**DESIGN)
    d.save(tmp_path / "design.json")
    for sub in ("a", "b", "c"):
        (tmp_path / sub).mkdir()
    with Sim(tmp_path / "a", "--seed", 9, "--noise-y", 0.02) as sim:
        with monkeypatch.context() as mp:
            refuse_processes(mp)
            f = msid.measure(uri(sim), d, periods=5, skip_periods=1, on_device=True, stream_check=True)
        truth = sim.truth()
    acq = f.meta["acquisition"]
    assert acq["on_device"] is True and acq["estimate_mode"] == "estimate+stream"
    assert acq["stream_check"].startswith("bit-identical to the host's estimate")
    same_bits(f, f.host_frf)
    with Sim(tmp_path / "b", "--seed", 9, "--noise-y", 0.02) as sim2:
        only = msid.measure(uri(sim2), d, periods=5, skip_periods=1, on_device=True)
    assert only.meta["acquisition"]["estimate_mode"] == "estimate" and not hasattr(only, "host_frf")
    same_bits(only, f)
    out = tmp_path / "cli.json"
    with Sim(tmp_path / "c", "--seed", 9, "--noise-y", 0.02) as sim3:
        r = run("modbus", "measure", "--tcp", f"127.0.0.1:{sim3.port}", "--design", tmp_path / "design.json",
                "--periods", 5, "--skip-periods", 1, "--on-device", "-o", out)
        assert r.returncode == 0, r.stderr
    same_bits(f, msid.read_frf(out))
    inside, n = check_coverage(msid.files.frf_to_doc(f), truth)
    assert n == 40 * 2


def test_on_device_refusals_and_stop(tmp_path):
    d = msid.design(**DESIGN)
    with pytest.raises(ValueError, match="stream_check applies to on_device=True"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, stream_check=True)
    with pytest.raises(ValueError, match="dft does not apply to on_device"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, on_device=True, dft="fft")
    with pytest.raises(ValueError, match="detect_lines is not available with on_device"):
        msid.measure("modbus-tcp://127.0.0.1:502", d, on_device=True, detect_lines=[2])
    with Sim(tmp_path, "--seed", 1, "--est-mem", 4096) as sim:
        with pytest.raises(OSError, match="cannot estimate on board: .*it has 4096"):
            msid.measure(uri(sim), d, periods=4, on_device=True)

    def stop(s):
        raise KeyboardInterrupt

    (tmp_path / "s").mkdir()
    with Sim(tmp_path / "s", "--seed", 1) as sim:
        with pytest.raises(KeyboardInterrupt, match="gives an FRF only for whole runs") as e:
            msid.measure(uri(sim), d, periods=40, rate=2000, on_device=True, progress=stop)
        assert not isinstance(e.value, msid.MeasurementInterrupted)
        # the device serves the next request
        f = msid.measure(uri(sim), d, periods=3, on_device=True)
    assert f.meta["acquisition"]["on_device"] is True


# ---- a described device (msid-device/1, docs/devices.md) -------------------------------------------------

def test_measure_a_described_device_in_process(tmp_path):
    import maplib
    A, B, C, D = maplib.siso_plant()
    plant = maplib.write_plant(tmp_path / "plant.txt", A, B, C, D)
    desc = maplib.description(tmp_path / "dev.toml", readback=True, counter=True)
    bins = list(range(1, 32, 2))
    truth = maplib.truth_doc(maplib.dt_frf(A, B, C, D, bins, 64), bins)
    seen = []
    with maplib.MapSim(tmp_path, desc, "--plant", plant, "--seed", 3, "--noise-y", "0.02") as sim:
        # a loaded machine can lose a sample in most periods: msid refuses such a run (counted, never a wrong
        # result), and it is made again, three times at most, as maplib.measure does for the command line
        for attempt in range(3):
            try:
                f = msid.measure(sim.uri, msid.design(period=64, lines="1:2:31", seed=3), map=desc, rate=200,
                                 periods=8, skip_periods=1, progress=seen.append)
                break
            except ValueError as e:
                if "usable period(s)" not in str(e) or attempt == 2:
                    raise
        # the device holds the safe value after the call, in its own registers
        assert maplib.float32_of(sim.holding(100, 2)) == 0.0
    acq = f.meta["acquisition"]
    assert acq["protocol"] == "msid-device/1" and acq["timing"]["samples_placed_by"] == "device counter"
    assert f.meta["input_names"] == ["Torque"] and f.meta["output_names"] == ["Speed"]
    assert f.reference_frf is None   # an open-loop description: the FRF is the device's own, no reference path
    assert seen and all("periods" in s for s in seen)
    # the 95% region of each line: |G - G0|^2 / v ~ F(2, 2 dof); 16 lines of one run: at least 12 inside
    # (P(Bin(16, 0.95) < 12) < 1e-3)
    G0 = {l["bin"]: canlib.cplx(l["G"])[0, 0] for l in truth["lines"]}
    inside = sum(canlib.f_sf(abs(f.G[k][0, 0] - G0[int(b)]) ** 2 / f.cov[k][0, 0].real, 2, 2 * int(f.dof[k])) > 0.05
                 for k, b in enumerate(f.bins))
    assert inside >= 12, f"{inside}/16 lines inside their 95% region"


def reference_json(bins, period):
    """A document as `msid measure --map` writes reference.json for the closed-loop preset (csv-loop), written
    out here for a discrete loop: plant Gp = 0.4 z^-1 / (1 - 0.7 z^-1) under a PI controller C = 0.8 + 0.3 z / (z - 1),
    the FRF from the velocity reference to [torque demand, velocity]: C S and T = Gp C S (S = 1 / (1 + Gp C)),
    each line's covariance of vec(G_zr) and noise covariance (2 x 2), dof, snr, input_snr."""
    rng = np.random.default_rng(11)
    lines = []
    for b in bins:
        z = np.exp(2j * np.pi * b / period)
        gp, c = 0.4 / z / (1 - 0.7 / z), 0.8 + 0.3 * z / (z - 1)
        cs = c / (1 + gp * c)
        g = np.array([[cs], [gp * cs]])
        a = rng.normal(size=(2, 2)) + 1j * rng.normal(size=(2, 2))
        cov = 1e-4 * (a @ a.conj().T)
        cm = lambda m: {"re": np.real(m).tolist(), "im": np.imag(m).tolist()}  # noqa: E731
        lines.append({"bin": b, "freq": b / period, "freq_hz": 25.0 * b / period, "G": cm(g), "cov": cm(cov),
                      "dof": 9.0, "noise_cov": cm(10 * cov), "snr": [41.5, 38.25], "cond": 1.0, "input_snr": None})
    return {"format": "msid-frf/1", "generator": "msid", "period_samples": period, "n_inputs": 1, "n_outputs": 2,
            "n_experiments": 1, "domain": "dt", "sample_time": 0.04, "fs_hz": 25.0,
            "input_names": ["Velocity reference"], "input_units": ["rad/s"],
            "output_names": ["Torque demand", "Velocity actual"], "output_units": ["N m", "rad/s"],
            "periods_used": 8, "periods_rejected": 0, "noise_cov": lines[0]["noise_cov"],
            "experiments": [{"source": "canopen://vcan0?node=5", "samples": 8 * period, "periods_total": 10,
                             "periods_skipped": 2, "periods_used": 8}],
            "notes": ["closed loop (preset csv-loop): ..."], "acquisition": {"protocol": "msid-device/1"},
            "lines": lines}


def test_the_reference_path_of_a_closed_loop_run(tmp_path):
    """msid.measure's .reference_frf: the closed-loop preset is CANopen only (SocketCAN, the vcan VM:
    tests/vcan/in_vm/test_measure_canopen_csv.py runs it), so here the conversion alone, on the document the
    extension hands over for such a run (reference.json's content): an msid.FRF with the document's bits, the
    same as msid.read_frf of that document written as the command line writes reference.json, with the reference
    and the signals' names; the run's notes; None for a run without a reference path."""
    bins = [1, 3, 5, 7]
    doc = reference_json(bins, 32)
    ref = msid.compute._reference_frf({"reference": json.loads(json.dumps(doc)), "notes": ["a note"]})
    assert isinstance(ref, msid.FRF)
    assert ref.G.shape == (4, 2, 1) and ref.cov.shape == (4, 2, 2) and list(ref.bins) == bins
    for k, line in enumerate(doc["lines"]):
        g = np.array(line["G"]["re"]) + 1j * np.array(line["G"]["im"])
        assert np.array_equal(ref.G[k], g) and ref.dof[k] == 9.0
    assert ref.signal_names() == (["Velocity reference"], ["Torque demand", "Velocity actual"])
    assert ref.gain_unit(0, 0) == "N m/rad/s"
    assert ref.notes == ["a note"]
    (tmp_path / "reference.json").write_text(json.dumps(doc, indent=1))
    read = msid.read_frf(tmp_path / "reference.json")
    same_bits(ref, read)
    assert ref.meta == read.meta and ref.line_extra == read.line_extra
    assert np.array_equal(ref.freq_hz, read.freq_hz) and np.array_equal(ref.real, read.real)
    # the rows are C S and T = Gp C S: the velocity's over the torque demand's is the plant Gp
    z = np.exp(2j * np.pi * np.array(bins) / 32)
    assert np.allclose(ref.G[:, 1, 0] / ref.G[:, 0, 0], 0.4 / z / (1 - 0.7 / z), rtol=1e-14, atol=0)
    assert msid.compute._reference_frf({"notes": []}) is None


@pytest.mark.parametrize("kw, err, msg", [
    (dict(rate=0), ValueError, "rate must be in (0, 100000]"),
    (dict(rate=200, scale=0.01), ValueError, "scale does not apply with map"),
    (dict(rate=200, on_device=True), ValueError, "on_device does not apply with map"),
    (dict(rate=200, map=3), TypeError, "map must be a path"),
])
def test_measure_a_described_device_refuses(tmp_path, kw, err, msg):
    import maplib
    desc = maplib.description(tmp_path / "dev.toml")
    kw.setdefault("map", desc)
    with pytest.raises(err, match=msg.replace("(", r"\(").replace("]", r"\]")):
        msid.measure("modbus-tcp://127.0.0.1:9", msid.design(period=64, lines="1:2:31"), **kw)


def test_measure_a_missing_description_is_an_oserror_or_valueerror(tmp_path):
    with pytest.raises((OSError, ValueError), match="nonexistent.toml"):
        msid.measure("modbus-tcp://127.0.0.1:9", msid.design(period=64, lines="1:2:31"),
                     map=str(tmp_path / "nonexistent.toml"), rate=100)
