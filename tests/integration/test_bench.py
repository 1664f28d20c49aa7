"""`msid bench frf` runs and reports both paths and the NumPy peer (smoke test:
speed is measured by the command, never asserted by tests)."""
import helpers as h


def test_bench_frf_smallest_config_runs():
    r = h.run("bench", "frf", "--quick", "--only", "1", "--min-seconds", "0.05")
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "P=1024 L=20 1x1" in out
    assert "stream" in out and "fft" in out
    assert "numpy" in out and "peer unavailable" not in out


def test_bench_bad_option():
    r = h.run("bench", "frf", "--only", "7")
    assert r.returncode == 2
    assert "--only" in r.stderr


def test_bench_fit_siso_runs():
    r = h.run("bench", "fit", "--only", "1", "--systems", "1", "--min-seconds", "0.01", timeout=600)
    assert r.returncode == 0, r.stderr
    assert "SISO n=4, 1000 lines" in r.stdout
    for m in ("subspace", "lmfd", "ml", "peer"):
        assert m in r.stdout
    assert "peer unavailable" not in r.stdout


def test_bench_fit_runs_bad_input():
    # --runs (the ml / vector fitting Monte Carlo of --only 3): one message, usage status, nothing run
    r = h.run("bench", "fit", "--only", "3", "--runs", "1001")
    assert r.returncode == 2 and "--runs must be at most 1000" in r.stderr and "Monte Carlo" not in r.stdout


def test_bench_io_times_every_format(tmp_path):
    # each timed `msid frf` is started by posix_spawn with stdout on /dev/null; the kept files
    # are the timed job's, so its FRF file must be a whole msid-frf/1 document
    r = h.run("bench", "io", "--no-peer", "--min-seconds", "0", "--keep", str(tmp_path), timeout=600)
    assert r.returncode == 0, r.stderr
    rows = [l.split() for l in r.stdout.splitlines() if l.split()[:1] in (["csv"], ["npy"], ["mat"])]
    assert [x[0] for x in rows] == ["csv", "npy", "mat"]
    for x in rows:
        assert x[2] == "ms" and float(x[1]) > 0 and x[6] == "ms" and float(x[5]) > 0   # wall, cpu (no peer: "-")
    frf = (tmp_path / "frf.json").read_text()
    assert '"format": "msid-frf/1"' in frf and frf.rstrip().endswith("}")


def test_bench_cissim_process_runs(tmp_path):
    # the whole `msid fit --method cissim` processes of both cases (no reference peer: --no-peer); the
    # kept model files are the timed fits', and each case's accuracy line is printed
    r = h.run("bench", "fit", "--cissim-process", "--no-peer", "--min-seconds", "0", "--keep", str(tmp_path),
              timeout=600)
    assert r.returncode == 0, r.stderr
    assert "--no-peer: no reference peer" in r.stdout
    for case in ("2x2", "sparse"):
        assert f"case {case}:" in r.stdout
        doc = h.load_json(tmp_path / f"{case}.model.json")
        assert doc["method"] == "cissim" and doc["order"] == 4 and doc["cissim"]["refinement"]["converged"]
    rows = [l for l in r.stdout.splitlines() if "msid fit --method cissim (.npy" in l]
    assert len(rows) == 2 and all(float(l.split()[-3]) < 0.01 for l in rows)   # H2 error against the truth
