"""End to end, discrete time: msid excite -> simulated 2x2 plant -> msid frf,
checked against the JSON schemas, the NumPy peer and the true FRF."""
import numpy as np
import pytest

import helpers as h
from msid_peers import frf_peer


@pytest.fixture(scope="module")
def dt_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("dt")
    bench = h.make_dt_bench(d)
    out = d / "frf.json"
    r = h.run_ok(*h.frf_args(bench, out))
    return {"bench": bench, "doc": h.load_json(out), "stdout": r.stdout, "stderr": r.stderr, "dir": d}


def test_schemas(dt_run):
    h.validate(h.load_json(dt_run["bench"]["design"]), "msid-design-1")
    h.validate(dt_run["doc"], "msid-frf-1")


def test_document_header(dt_run):
    doc = dt_run["doc"]
    assert doc["format"] == "msid-frf/1"
    assert (doc["n_inputs"], doc["n_outputs"], doc["n_experiments"]) == (2, 2, 2)
    assert doc["period_samples"] == h.DT_P
    assert doc["domain"] == "dt"
    assert [l["bin"] for l in doc["lines"]] == list(range(1, 42, 2))
    assert doc["periods_used"] == 16 and doc["periods_rejected"] == 0
    for e, p in zip(doc["experiments"], dt_run["bench"]["experiments"]):
        assert e["source"] == str(p)
        assert e["samples"] == 8 * h.DT_P and e["periods_total"] == 8 and e["periods_used"] == 8
        assert e["leftover_samples"] == 0
    assert dt_run["stderr"] == ""   # no notes: whole periods, steady state
    assert "wrote" in dt_run["stdout"]


def test_matches_numpy_peer(dt_run):
    peer = frf_peer.estimate_files(dt_run["bench"]["experiments"], design=dt_run["bench"]["design"])
    h.compare_with_peer(dt_run["doc"], peer, rel=1e-9)


def test_close_to_true_frf(dt_run):
    doc = dt_run["doc"]
    bins = [l["bin"] for l in doc["lines"]]
    G0 = h.dt_frf(dt_run["bench"]["plant"], bins, h.DT_P)
    stats = []
    for l, line in enumerate(doc["lines"]):
        G = h.cplx(line["G"])
        for key in ("cov", "cov_known_input"):
            var = np.real(np.diag(h.cplx(line[key])))       # index i + ny*j
            err = (G - G0[l]).T.reshape(-1)                  # vec stacks columns
            t = np.abs(err) ** 2 / var
            assert np.all(t < 25), f"bin {line['bin']} {key}: |G - G0|^2/var = {t}"
            if key == "cov":
                stats.extend(t)
    # |e|^2/v ~ F(2, 2*14), mean 14/13; 84 values
    assert 0.6 < np.mean(stats) < 1.6, np.mean(stats)


def test_noise_level(dt_run):
    # white output noise: the time-domain estimate is sigma^2 I
    N = h.cplx(dt_run["doc"]["noise_cov"])
    assert np.allclose(np.diag(N).real, h.DT_SIGMA_Y ** 2, rtol=0.15)
    assert abs(N[0, 1]) < 0.15 * h.DT_SIGMA_Y ** 2


def test_peer_cli_matches_function(dt_run, tmp_path):
    """`python3 -m msid_peers.frf_peer` gives the same numbers as the function."""
    b = dt_run["bench"]
    out = tmp_path / "peer.json"
    args = ["--design", str(b["design"]), "-o", str(out)]
    for p in b["experiments"]:
        args += ["--experiment", str(p)]
    assert frf_peer.main(args) == 0
    h.compare_with_peer(dt_run["doc"], h.load_json(out), rel=1e-9)
