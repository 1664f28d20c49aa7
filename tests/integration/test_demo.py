"""msid demo: the built-in end-to-end run."""
import re
import shlex

import numpy as np

import helpers as h
from msid import frf_peer

FILES = ("design.json", "e1.csv", "e2.csv", "frf.json", "truth.json")


def test_demo(tmp_path):
    r = h.run("demo", "--out", "demo", "--quiet", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    d = tmp_path / "demo"
    assert sorted(p.name for p in d.iterdir()) == sorted(FILES)

    frf = h.load_json(d / "frf.json")
    design = h.load_json(d / "design.json")
    h.validate(frf, "msid-frf-1")
    h.validate(design, "msid-design-1")
    assert h.load_json(d / "truth.json")["format"] == "msid-demo-truth/1"

    # --quiet: no table, but the coverage line
    assert "|error|" not in r.stdout and "msid demo: 2x2" not in r.stdout
    m = re.search(r"^(\d+) of (\d+) true FRF values lie inside their 95% region "
                  r"\(expected ([\d.]+) \+- ([\d.]+)\)\.$", r.stdout, re.M)
    assert m, r.stdout
    inside, total, expct, sd = int(m[1]), int(m[2]), float(m[3]), float(m[4])
    L = len(frf["lines"])
    assert total == L * 4 == 56
    assert abs(expct - 0.95 * total) < 0.051 and abs(sd - (total * 0.95 * 0.05) ** 0.5) < 0.051
    assert expct - 4 * sd <= inside <= total

    # the printed reproduction command gives the same document, byte for byte
    cmd = re.search(r"^reproduce the estimate: (\S+) (frf .*)$", r.stdout, re.M)
    assert cmd, r.stdout
    assert cmd[1].endswith("msid")          # the path of the running binary, usable as printed
    args = shlex.split(cmd[2])
    args[args.index("-o") + 1] = "frf2.json"
    h.run_ok(*args, cwd=tmp_path)
    assert (tmp_path / "frf2.json").read_bytes() == (d / "frf.json").read_bytes()

    # and the NumPy peer agrees
    peer = frf_peer.estimate_files([d / "e1.csv", d / "e2.csv"], design=d / "design.json", skip=1, fs=1000.0)
    h.compare_with_peer(frf, peer, rel=1e-9)
    for a, b in zip(frf["lines"], peer["lines"]):
        assert a["freq_hz"] == b["freq_hz"]

    # the estimate is near the stored truth (coverage is asserted by the demo itself)
    truth = h.load_json(d / "truth.json")["lines"]
    for line, t in zip(frf["lines"], truth):
        assert line["bin"] == t["bin"]
        var = np.real(np.diag(h.cplx(line["cov"])))
        err = (h.cplx(line["G"]) - h.cplx(t["G"])).T.reshape(-1)
        assert np.all(np.abs(err) ** 2 / var < 36), line["bin"]
