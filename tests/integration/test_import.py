"""FRFs measured by other tools (msid import; docs/frf-format.md, "FRFs from other tools").

Peers: scikit-rf reads the same Touchstone files, pyuff the same UFF 58 files; the values msid imports
must equal theirs. Theory: a continuous-time FRF without a sample time, fitted as one, gives back the
plant it was computed from. Bad input: one clear message, a non-zero exit, nothing written.
"""
import os
from pathlib import Path

import numpy as np
import pytest

import helpers
from helpers import cplx, load_json, run, run_ok

skrf = pytest.importorskip("skrf")
pyuff = pytest.importorskip("pyuff")

SKRF_DATA = Path(skrf.data.__file__).resolve().parent


def imported(path, tmp_path, *extra):
    """msid import PATH -> (document, G L x ny x nu, omega L)."""
    out = tmp_path / (Path(path).name + ".json")
    run_ok("import", path, "-o", out, *extra)
    doc = load_json(out)
    helpers.validate(doc, "msid-frf-1")
    G = np.array([cplx(ln["G"]) for ln in doc["lines"]])
    om = np.array([ln["omega"] for ln in doc["lines"]])
    return doc, G, om


# ---------------- Touchstone against scikit-rf ----------------

@pytest.mark.parametrize("name", ["ntwk1.s2p", "ring slot measured.s1p", "tee.s3p", "line.s2p", "ind.s2p"])
def test_touchstone_examples_equal_scikit_rf(name, tmp_path):
    ntwk = skrf.Network(str(SKRF_DATA / name))
    doc, G, om = imported(SKRF_DATA / name, tmp_path)
    assert doc["domain"] == "ct" and "sample_time" not in doc and doc["period_samples"] == 0
    assert doc["imported"]["format"] == "touchstone" and doc["imported"]["parameter"] == "S"
    np.testing.assert_allclose(om, 2 * np.pi * ntwk.f, rtol=1e-15)
    np.testing.assert_allclose(G, ntwk.s, rtol=1e-13, atol=1e-15)
    n = ntwk.nports
    assert doc["input_names"] == [f"a{k}" for k in range(1, n + 1)]
    assert doc["output_names"] == [f"b{k}" for k in range(1, n + 1)]


@pytest.mark.parametrize("form", ["ri", "ma", "db"])
@pytest.mark.parametrize("ports", [2, 4])
def test_touchstone_forms_and_multiline_rows_equal_scikit_rf(form, ports, tmp_path):
    """A random N-port written by scikit-rf in RI, MA and DB (4 ports: rows over several lines)."""
    rng = np.random.default_rng(11 + ports)
    f = skrf.Frequency(1, 3, 7, unit="MHz")
    s = rng.standard_normal((7, ports, ports)) + 1j * rng.standard_normal((7, ports, ports))
    nt = skrf.Network(frequency=f, s=s, name=f"rand{ports}")
    nt.write_touchstone(f"rand{ports}_{form}", dir=str(tmp_path), form=form)
    path = tmp_path / f"rand{ports}_{form}.s{ports}p"
    ref = skrf.Network(str(path))
    _, G, om = imported(path, tmp_path)
    np.testing.assert_allclose(om, 2 * np.pi * ref.f, rtol=1e-15)
    np.testing.assert_allclose(G, ref.s, rtol=1e-12, atol=1e-14)


def test_touchstone_z_parameters_in_ohm_and_noise_section_left_out(tmp_path):
    """Z parameters of 1.x are normalised to R: msid returns ohms, as scikit-rf's z; the noise
    parameters after a 2-port's data are not an FRF."""
    rows = ["! a 2-port in Z, normalised to R = 75", "# MHz Z RI R 75",
            "1 1.0 0.5 0.2 -0.1 0.3 0.05 2.0 -1.0",
            "2 0.9 0.6 0.25 -0.12 0.28 0.07 1.8 -1.1  ! trailing comment",
            "3 0.8 0.7 0.3 -0.15 0.26 0.09 1.6 -1.2",
            "! noise parameters: freq NFmin |Gamma_opt| angle Rn/R",
            "1 0.5 0.3 45 0.2", "3 0.6 0.35 50 0.25"]
    path = tmp_path / "z.s2p"
    path.write_text("\n".join(rows) + "\n")
    ref = skrf.Network(str(path))
    doc, G, om = imported(path, tmp_path)
    assert len(doc["lines"]) == 3 and "noise_parameters" in doc["imported"]
    np.testing.assert_allclose(om, 2 * np.pi * ref.f, rtol=1e-15)
    np.testing.assert_allclose(G, ref.z, rtol=1e-12)
    assert doc["input_units"] == ["A", "A"] and doc["output_units"] == ["V", "V"]


def _v2_text(N, s, *, param="S", order="12_21", matrix="Full", refs=None, freq_unit="MHz", noise=False, info=True):
    """A Touchstone 2.0 file of the N-port data s (F x N x N) in RI, written here from the
    specification (scikit-rf writes 1.x only): keywords, an information block (2.1; not for scikit-rf,
    which does not know it), the [Reference] over
    two lines, each point's numbers over two lines, [Noise Data] after a 2-port's network data."""
    F = s.shape[0]
    out = ["! written by msid's tests", "[Version] 2.0", f"# {freq_unit} {param} RI R 50",
           f"[Number of Ports] {N}"]
    if N == 2:
        out.append(f"[Two-Port Data Order] {order}")
    out += [f"[Number of Frequencies] {F}"]
    if refs is not None:
        out += ["[Reference] " + " ".join(repr(r) for r in refs[:1]), " ".join(repr(r) for r in refs[1:])]
    out += [f"[Matrix Format] {matrix}"]
    if info:
        out += ["[Begin Information]", "[Manufacturer] nobody", "[End Information]"]
    out += ["[Network Data]"]
    for k in range(F):
        vals = []
        for r in range(N):
            for c in range(N):
                if (matrix == "Lower" and c > r) or (matrix == "Upper" and c < r):
                    continue
                rr, cc = (c, r) if (N == 2 and order == "21_12") else (r, c)
                vals += [repr(float(s[k, rr, cc].real)), repr(float(s[k, rr, cc].imag))]
        half = len(vals) // 2
        out += [f"{k + 1} " + " ".join(vals[:half]), "   " + " ".join(vals[half:]) + "  ! the rest of the point"]
    if noise:
        out += ["[Noise Data]", "1 0.5 0.3 45 0.2"]
    out.append("[End]")
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("N,param,order,matrix", [(1, "S", None, "Full"), (2, "S", "12_21", "Full"),
                                                  (2, "S", "21_12", "Full"), (3, "S", None, "Lower"),
                                                  (3, "Z", None, "Upper"), (2, "Y", "12_21", "Full")])
def test_touchstone_2_equals_scikit_rf(tmp_path, N, param, order, matrix):
    """Touchstone 2.0 (.ts): the port count, the 2-port order, the point count, per-port references,
    full and triangular matrices, points over several lines, noise data left out. Z and Y of 2.0 are
    not normalised (ohms and siemens as written): equal to scikit-rf's z and y, S to its s."""
    rng = np.random.default_rng(100 + N)
    F = 5
    s = rng.standard_normal((F, N, N)) + 1j * rng.standard_normal((F, N, N))
    if matrix != "Full":
        s = (s + s.transpose(0, 2, 1)) / 2   # a reciprocal network: the triangle is the whole matrix
    refs = [50.0] * N if N >= 2 else None
    path = tmp_path / f"net{N}{param}{order}{matrix}.ts"
    kw = dict(param=param, order=order or "12_21", matrix=matrix, refs=refs, noise=N == 2)
    path.write_text(_v2_text(N, s, **kw))
    plain = tmp_path / "plain.ts"
    plain.write_text(_v2_text(N, s, info=False, **kw))
    ref = skrf.Network(str(plain))
    doc, G, om = imported(path, tmp_path)
    assert doc["imported"]["parameter"] == param and doc["imported"]["version"] == "2"
    np.testing.assert_allclose(om, 2 * np.pi * ref.f, rtol=1e-15)
    want = {"S": ref.s, "Z": ref.z, "Y": ref.y}[param]
    np.testing.assert_allclose(G, want, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(G, s, rtol=1e-15, atol=0)   # and exactly what was written


@pytest.mark.parametrize("edit,words", [
    (lambda t: t.replace("[Number of Frequencies] 5", "[Number of Frequencies] 6"), ["holds 5 points", "says 6"]),
    (lambda t: t.replace("[Two-Port Data Order] 12_21\n", ""), ["[Two-Port Data Order]"]),
    (lambda t: t.replace("[Network Data]", "[Mixed-Mode Order] D1,2 C1,2\n[Network Data]"), ["mixed-mode"]),
    (lambda t: t.replace("[Version] 2.0", "[Version] 3.0"), ["1.x and 2.x"]),
    (lambda t: t.replace("[Matrix Format] Full", "[Matrix Format] Diagonal"), ["Full, Lower or Upper"]),
    (lambda t: t.replace("[Network Data]", "[Frobnicate] 1\n[Network Data]"), ["[FROBNICATE]"]),
])
def test_touchstone_2_refusals(tmp_path, edit, words):
    s = np.ones((5, 2, 2), complex)
    path = tmp_path / "bad.ts"
    path.write_text(edit(_v2_text(2, s)))
    r = run("import", path, "-o", tmp_path / "o.json")
    assert r.returncode != 0 and not (tmp_path / "o.json").exists()
    for w in words:
        assert w in r.stderr, r.stderr


# ---------------- UFF 58 against pyuff ----------------

def _uff_sets(spacing, ord_type, x, binary=0):
    s = 2j * np.pi * x
    sets, truth = [], {}
    for i, (node, dr) in enumerate([(2, 3), (3, -2)]):
        for j, (rnode, rdr) in enumerate([(1, 3), (4, 1)]):
            w0 = 2 * np.pi * (30 + 10 * i + 5 * j)
            H = (1 + 0.1 * j) / (s ** 2 + 2 * 0.05 * w0 * s + w0 ** 2)
            truth[i, j] = H
            kw = dict(binary=binary, func_type=4, rsp_node=node, rsp_dir=dr, ref_node=rnode, ref_dir=rdr, data=H, x=x,
                      id1="msid test", rsp_ent_name="pt", ref_ent_name="pt", abscissa_spacing=spacing,
                      ord_data_type=ord_type, abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                      orddenom_spec_data_type=13, ordinate_axis_units_lab="m/s^2", orddenom_axis_units_lab="N",
                      abscissa_axis_units_lab="Hz")
            sets.append(pyuff.prepare_58(**kw))
    return sets, truth


@pytest.mark.parametrize("spacing,ord_type", [(1, 6), (0, 6), (1, 5), (0, 5)])
def test_uff58_equals_pyuff(spacing, ord_type, tmp_path):
    x = np.linspace(2, 100, 60) if spacing else np.geomspace(2, 100, 60)
    sets, _ = _uff_sets(spacing, ord_type, x)
    path = tmp_path / "frf.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    ref = pyuff.UFF(str(path)).read_sets()
    doc, G, om = imported(path, tmp_path)
    assert doc["n_outputs"] == 2 and doc["n_inputs"] == 2 and doc["domain"] == "ct"
    assert doc["output_names"] == ["pt:2+Z", "pt:3-Y"] and doc["input_names"] == ["pt:1+Z", "pt:4+X"]
    assert doc["output_units"] == ["m/s^2", "m/s^2"] and doc["input_units"] == ["N", "N"]
    for d in ref:
        i = [(2, 3), (3, -2)].index((int(d["rsp_node"]), int(d["rsp_dir"])))
        j = [(1, 3), (4, 1)].index((int(d["ref_node"]), int(d["ref_dir"])))
        np.testing.assert_allclose(om, 2 * np.pi * np.asarray(d["x"], float), rtol=1e-12)
        np.testing.assert_allclose(G[:, i, j], np.asarray(d["data"]), rtol=1e-12, atol=0)


@pytest.mark.parametrize("spacing", [1, 0])
def test_uff58b_binary_equals_pyuff(spacing, tmp_path):
    """Binary 58b as pyuff writes it (IEEE doubles in the machine's byte order, even and uneven
    abscissa; its id line counts half the bytes of complex data, which msid takes from record 7),
    one dataset in ASCII among the even ones: the values pyuff reads back."""
    x = np.linspace(2, 100, 60) if spacing else np.geomspace(2, 100, 60)
    sets, _ = _uff_sets(spacing, 6, x, binary=1)
    if spacing:   # an uneven ASCII abscissa is E13.5, a binary one every bit: not one abscissa
        sets[1]["binary"] = 0
    path = tmp_path / "frf.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    assert b"58b" in path.read_bytes()
    ref = pyuff.UFF(str(path)).read_sets()
    doc, G, om = imported(path, tmp_path)
    assert doc["n_outputs"] == 2 and doc["n_inputs"] == 2
    for d in ref:
        i = [(2, 3), (3, -2)].index((int(d["rsp_node"]), int(d["rsp_dir"])))
        j = [(1, 3), (4, 1)].index((int(d["ref_node"]), int(d["ref_dir"])))
        np.testing.assert_allclose(om, 2 * np.pi * np.asarray(d["x"], float), rtol=1e-15)
        np.testing.assert_array_equal(G[:, i, j], np.asarray(d["data"]))   # binary: every bit


def _58b_single_big_endian(tmp_path, H, x, cut=0, minus=True):
    """One 58b dataset written here from the format's description: complex single precision (type 5),
    big-endian (byte order 2), even abscissa, the id line's byte count right, a "-1" line in the data's
    bytes on purpose (b"\n    -1\n" as floats' bytes cannot be told from text)."""
    import struct
    data = np.empty(2 * H.size, ">f4")
    data[0::2], data[1::2] = H.real, H.imag
    raw = data.tobytes()
    n = H.size
    head = ["    -1", f"    58b{2:6d}{2:6d}{11:12d}{8 * n:12d}{0:6d}{0:6d}{0:12d}{0:12d}",
            "binary single", "NONE", "NONE", "NONE", "NONE",
            f"{4:5d}{0:10d}{0:5d}{0:10d} {'pt':10s}{2:10d}{3:4d} {'pt':10s}{1:10d}{3:4d}",
            f"{5:10d}{n:10d}{1:10d}{x[0]:13.5e}{x[1] - x[0]:13.5e}{0.0:13.5e}",
            f"{18:10d}{0:5d}{0:5d}{0:5d} {'Frequency':20s} {'Hz':20s}",
            f"{12:10d}{0:5d}{0:5d}{0:5d} {'acc':20s} {'m/s^2':20s}",
            f"{13:10d}{0:5d}{0:5d}{0:5d} {'force':20s} {'N':20s}",
            f"{0:10d}{0:5d}{0:5d}{0:5d} {'':20s} {'':20s}"]
    body = raw[:len(raw) - cut] + (b"    -1\n" if minus else b"")
    p = tmp_path / "single.uff"
    p.write_bytes(("\n".join(head) + "\n").encode() + body)
    return p


def test_uff58b_single_precision_big_endian(tmp_path):
    x = np.arange(60) * 0.5 + 2.0
    H = (1 / (2j * np.pi * x + 30)).astype(np.complex64)
    H[7] = np.frombuffer(b"\n -1", ">f4")[0] + 1j * np.frombuffer(b"\n\n\n\n", ">f4")[0]   # text-like bytes
    p = _58b_single_big_endian(tmp_path, H, x)
    doc, G, om = imported(p, tmp_path)
    np.testing.assert_array_equal(G[:, 0, 0], H.astype(complex))
    np.testing.assert_allclose(om, 2 * np.pi * (2.0 + 0.5 * np.arange(60)), rtol=1e-6)   # E13.5 abscissa
    assert doc["output_units"] == ["m/s^2"] and doc["input_units"] == ["N"]


def test_uff58b_truncated_or_without_its_end(tmp_path):
    x = np.arange(60) * 0.5 + 2.0
    H = (1 / (2j * np.pi * x + 30)).astype(np.complex64)
    _refused(tmp_path, _58b_single_big_endian(tmp_path, H, x, cut=12), "single.uff", "truncated")
    _refused(tmp_path, _58b_single_big_endian(tmp_path, H, x, cut=4), "single.uff", "no closing -1")
    _refused(tmp_path, _58b_single_big_endian(tmp_path, H, x, minus=False), "single.uff", "no closing -1")
    _refused(tmp_path, _58b_single_big_endian(tmp_path, H[:2].copy(), x, minus=False), "single.uff")


# ---------------- a CT FRF without a sample time: fit against the plant ----------------

def _ct_csv(path, omegas, G, names=("y1", "y2"), ins=("u1", "u2"), sd=None, extra_meta=()):
    cols = ["freq_hz"]
    for i, o in enumerate(names):
        for j, u in enumerate(ins):
            cols += [f"G_{o}_{u}_re", f"G_{o}_{u}_im"] + ([f"G_{o}_{u}_sd"] if sd is not None else [])
    lines = ["# a continuous-time FRF of an analogue instrument", "# units: u1=N, u2=N, y1=m, y2=m", *extra_meta,
             ",".join(cols)]
    for k, w in enumerate(omegas):
        v = [repr(float(w / (2 * np.pi)))]
        for i in range(len(names)):
            for j in range(len(ins)):
                v += [repr(float(G[k, i, j].real)), repr(float(G[k, i, j].imag))] + \
                    ([repr(float(sd[k, i, j]))] if sd is not None else [])
        lines.append(",".join(v))
    Path(path).write_text("\n".join(lines) + "\n")


def _same_poles(got, true, rel):
    """Every pole of the model near a true one and every true one near a model pole (ml's pole-residue
    realisation repeats each pole once per input)."""
    for p in got:
        assert np.min(np.abs(true - p)) <= rel * abs(p), (p, true)
    for p in true:
        assert np.min(np.abs(got - p)) <= rel * abs(p), (p, got)


@pytest.mark.parametrize("method", ["ml", "subspace"])
def test_ct_fit_without_sample_time_gives_back_the_plant(method, tmp_path):
    plant = helpers.ct_plant_2x2()
    om = np.geomspace(10, 5000, 80)
    G = helpers.ct_frf(plant, om)
    csv = tmp_path / "ct.csv"
    _ct_csv(csv, om, G)
    model = tmp_path / "m.json"
    r = run_ok("fit", "--method", method, "--order", "3", csv, "-o", model)
    assert "no FRF covariance: an unweighted fit" in r.stderr
    m = load_json(model)
    assert m["domain"] == "ct" and "sample_time" not in m
    assert m["settings"]["weight"] == "none" and "weight_reason" in m["settings"]
    assert "numerical device" in m["settings"]["frequency_axis"]
    assert m["cost"]["p_value"] is None
    assert m["input_names"] == ["u1", "u2"] and m["output_units"] == ["m", "m"]
    A, B, C, D = (np.array(m[k], float) for k in "ABCD")
    _same_poles(np.linalg.eigvals(A), np.linalg.eigvals(plant[0]), 1e-6)
    Gm = helpers.ct_frf((A, B, C, D), om)
    assert np.max(np.abs(Gm - G)) < 1e-6 * np.max(np.abs(G))
    # validate on the same file: the unweighted cost, no p-value, no verdict
    rep = tmp_path / "v.json"
    v = run_ok("validate", model, csv, "-o", rep)
    assert "no p-value, no verdict" in v.stdout and "verdict:" not in v.stdout
    assert load_json(rep)["p_value"] is None


def test_ct_fit_weighted_by_standard_deviations_has_a_p_value(tmp_path):
    plant = helpers.ct_plant_2x2()
    om = np.geomspace(10, 5000, 120)
    G0 = helpers.ct_frf(plant, om)
    rng = np.random.default_rng(5)
    sd = 1e-3 * np.abs(G0) + 1e-5
    G = G0 + sd * (rng.standard_normal(G0.shape) + 1j * rng.standard_normal(G0.shape)) / np.sqrt(2)
    csv = tmp_path / "ct_sd.csv"
    _ct_csv(csv, om, G, sd=sd)
    model = tmp_path / "m.json"
    r = run_ok("fit", "--method", "ml", "--order", "3", csv, "-o", model)
    assert "unweighted" not in r.stderr
    m = load_json(model)
    assert m["settings"]["weight"] == "cov"
    assert m["cost"]["p_value"] is not None and m["cost"]["p_value"] > 1e-3
    _same_poles(np.linalg.eigvals(np.array(m["A"])), np.linalg.eigvals(plant[0]), 1e-2)


@pytest.mark.skipif("ASAN_OPTIONS" in os.environ, reason="scripts/sanitize.sh: ml over every order on real data "
                    "takes minutes under ASan, and test_fit_cli takes its paths")
def test_real_network_analyser_data_fits_a_stable_model(tmp_path):
    """scikit-rf's measured ring-slot resonator (75-110 GHz, one port): ml with the order it chooses gives a
    stable, converged CT model that follows the measurement."""
    src = SKRF_DATA / "ring slot measured.s1p"
    doc, G, om = imported(src, tmp_path)
    model = tmp_path / "ring.json"
    r = run_ok("fit", "--method", "ml", "--order", "auto", src, "-o", model)
    assert r.stderr.count("no FRF covariance: an unweighted fit") == 1   # once, not once per order
    m = load_json(model)
    assert m["domain"] == "ct" and m["stability"]["stable"] is True and m["converged"] is True
    # the resonance of the ring near 86 GHz among the poles
    poles = np.linalg.eigvals(np.array(m["A"]))
    assert np.any(np.abs(np.abs(poles) / (2 * np.pi * 1e9) - 86) < 2) and np.all(poles.real < 0)
    Gm = np.array([cplx(e["G"]) for e in m["frf"]])
    rel = np.linalg.norm(Gm - G) / np.linalg.norm(G)
    assert rel < 0.1, rel
    # plotted like any FRF (no regions: no covariance)
    png = tmp_path / "ring.png"
    run_ok("plot", src, "--model", model, "-o", png)
    assert png.stat().st_size > 1000


# ---------------- idfrd-shaped .mat ----------------

def test_idfrd_mat_round_trip_through_msid_export(tmp_path):
    """CSV with standard deviations -> msid import -> msid export --mat -> msid import: the same lines,
    values, variances, names and units."""
    plant = helpers.ct_plant_2x2()
    om = np.geomspace(10, 5000, 30)
    G = helpers.ct_frf(plant, om)
    sd = 1e-3 * np.abs(G) + 1e-5
    csv = tmp_path / "a.csv"
    _ct_csv(csv, om, G, sd=sd, extra_meta=["# dof: 12"])
    doc, G1, om1 = imported(csv, tmp_path)
    run_ok("export", tmp_path / "a.csv.json", "--mat", tmp_path / "a.mat")
    mdoc, G2, om2 = imported(tmp_path / "a.mat", tmp_path)
    np.testing.assert_allclose(om2, om, rtol=1e-15)
    np.testing.assert_allclose(G2, G, rtol=1e-15)
    v1 = np.array([np.real(np.diag(cplx(ln["cov"]))) for ln in doc["lines"]])
    v2 = np.array([np.real(np.diag(cplx(ln["cov"]))) for ln in mdoc["lines"]])
    np.testing.assert_allclose(v2, v1, rtol=1e-14)
    assert [ln["dof"] for ln in mdoc["lines"]] == [12.0] * 30
    assert mdoc["input_names"] == ["u1", "u2"] and mdoc["output_units"] == ["m", "m"]
    assert mdoc["domain"] == "ct" and "sample_time" not in mdoc


def test_idfrd_mat_written_by_scipy(tmp_path):
    sio = pytest.importorskip("scipy.io")
    rng = np.random.default_rng(3)
    L = 25
    G = rng.standard_normal((1, 2, L)) + 1j * rng.standard_normal((1, 2, L))
    f_hz = np.linspace(1, 50, L)
    p = tmp_path / "id.mat"
    names = np.empty((2, 1), dtype=object)
    names[0, 0], names[1, 0] = "Force", "Torque"
    sio.savemat(p, {"ResponseData": G, "Frequency": f_hz[:, None], "Ts": 0.0, "FrequencyUnit": "Hz",
                    "InputName": names}, format="5", do_compression=True)
    doc, G1, om = imported(p, tmp_path)
    np.testing.assert_allclose(om, 2 * np.pi * f_hz, rtol=1e-15)
    np.testing.assert_array_equal(G1, np.transpose(G, (2, 0, 1)))
    assert doc["input_names"] == ["Force", "Torque"] and "cov" not in doc["lines"][0]


def _idfrd_content(rng, ny, nu, L, cov):
    G = rng.standard_normal((ny, nu, L)) + 1j * rng.standard_normal((ny, nu, L))
    v = {"ResponseData": G, "Frequency": np.linspace(1, 50, L)[:, None], "Ts": 0.0, "FrequencyUnit": "Hz",
         "InputName": [f"F{j + 1}" for j in range(nu)], "OutputName": [f"acc{i + 1}" for i in range(ny)],
         "InputUnit": ["N"] * nu, "OutputUnit": ["m/s^2"] * ny}
    if cov:
        C = np.zeros((ny, nu, L, 2, 2))
        C[..., 0, 0] = C[..., 1, 1] = rng.uniform(1e-4, 1e-3, (ny, nu, L))
        v["CovarianceData"] = C
        v["dof"] = np.full((L, 1), 7.0)
    return v


def _as_scipy(v):
    out = {}
    for k, x in v.items():
        if isinstance(x, list):
            c = np.empty((len(x), 1), dtype=object)
            for i, s in enumerate(x):
                c[i, 0] = s
            x = c
        out[k] = x
    return out


@pytest.mark.parametrize("ny,nu,cov", [(1, 1, False), (2, 2, True), (1, 2, True)])
def test_idfrd_mat_v73_equals_v5(tmp_path, ny, nu, cov):
    """The same idfrd content saved as v5 (scipy) and as v7.3 (HDF5, as MATLAB's save -v7.3 writes it):
    msid import gives the same document, bit for bit (names, units, covariance and dof included)."""
    sio = pytest.importorskip("scipy.io")
    v = _idfrd_content(np.random.default_rng(7 + ny + nu), ny, nu, 30, cov)
    p5, p73 = tmp_path / "v5.mat", tmp_path / "v73.mat"
    sio.savemat(p5, _as_scipy(v), format="5")
    helpers.write_mat73(p73, v)
    d5, G5, om5 = imported(p5, tmp_path)
    d73, G73, om73 = imported(p73, tmp_path)
    np.testing.assert_array_equal(G73, G5)
    np.testing.assert_array_equal(om73, om5)
    assert d73["lines"] == d5["lines"]
    for k in ("input_names", "output_names", "input_units", "output_units", "domain"):
        assert d73.get(k) == d5.get(k), k
    assert d73["input_names"] == [f"F{j + 1}" for j in range(nu)] and d73["output_units"] == ["m/s^2"] * ny
    assert ("cov" in d73["lines"][0]) == cov


def test_idfrd_mat_v73_refused(tmp_path):
    """v7.3 without ResponseData, with a wrong Frequency length, with h5py's complex in place of MATLAB's,
    and a dataset that claims far more than the file can hold (a chunked dataset never written): one
    message each, nothing written."""
    h5py = pytest.importorskip("h5py")
    base = _idfrd_content(np.random.default_rng(1), 1, 1, 10, False)
    p = tmp_path / "nor.mat"
    helpers.write_mat73(p, {k: x for k, x in base.items() if k != "ResponseData"})
    _refused(tmp_path, p, "no variable 'ResponseData'")
    p = tmp_path / "freq.mat"
    helpers.write_mat73(p, dict(base, Frequency=np.arange(1.0, 9.0)[:, None]))
    _refused(tmp_path, p, "Frequency has 8 values")
    # h5py's own complex128 (members 'r', 'i'): libmatio would read it by the names 'real' and 'imag'
    # without checking them, and return whatever memory held
    p = tmp_path / "h5pycomplex.mat"
    helpers.write_mat73(p, base)
    with h5py.File(p, "a") as f:
        G = base["ResponseData"]
        del f["ResponseData"]
        ds = f.create_dataset("ResponseData", data=np.transpose(G))
        helpers.matlab_class(ds, "double")
    _refused(tmp_path, p, "variable 'ResponseData' is a compound of 2 members ('r', 'i')")
    p = tmp_path / "huge.mat"
    helpers.write_mat73(p, base)
    with h5py.File(p, "a") as f:
        del f["ResponseData"]
        ds = f.create_dataset("ResponseData", shape=(1 << 20, 1 << 12, 1), dtype="<f8", chunks=(1024, 16, 1))
        helpers.matlab_class(ds, "double")
    _refused(tmp_path, p, "huge.mat", "ResponseData")


def test_idfrd_mat_v73_ct_in_hz_fitted_validated_and_plotted_directly(tmp_path):
    """A CT FRF (Ts = 0) in Hz, as an analogue analyser gives it, as v5 and as v7.3: `msid fit`,
    `validate` and `plot` read the v7.3 file directly, and its model is the v5 file's, byte for byte
    (but for the file's name)."""
    sio = pytest.importorskip("scipy.io")
    plant = helpers.ct_plant_2x2()
    om = np.geomspace(10, 5000, 40)
    v = {"ResponseData": np.transpose(helpers.ct_frf(plant, om), (1, 2, 0)), "Frequency": (om / (2 * np.pi))[:, None],
         "Ts": 0.0, "FrequencyUnit": "Hz", "InputName": ["u1", "u2"]}
    p5, p73 = tmp_path / "v5.mat", tmp_path / "v73.mat"
    sio.savemat(p5, _as_scipy(v), format="5")
    helpers.write_mat73(p73, v)
    models = []
    for p in (p5, p73):
        m = tmp_path / (p.stem + ".model.json")
        run_ok("fit", "--method", "ml", "--order", "4", p, "-o", m)
        models.append(m.read_text().replace(p.name, "FILE"))
        run_ok("validate", m, p, "-o", tmp_path / (p.stem + ".val.json"))
        png = tmp_path / (p.stem + ".png")
        run_ok("plot", p, "--model", m, "-o", png)
        assert png.stat().st_size > 1000
    assert models[0] == models[1]
    assert load_json(tmp_path / "v73.model.json")["domain"] == "ct"


def test_idfrd_mat_v73_refused_more(tmp_path):
    """A wrong name count, a cut file (libmatio alone lists no variables in it: it read as a file without
    ResponseData), h5py's default MATLAB_class attribute (a NUL-padded string libmatio does not read) and
    a char matrix where a row belongs (v5 refuses it too): one message each."""
    h5py = pytest.importorskip("h5py")
    base = _idfrd_content(np.random.default_rng(2), 1, 1, 10, False)
    p = tmp_path / "names.mat"
    helpers.write_mat73(p, dict(base, InputName=["a", "b"]))
    _refused(tmp_path, p, "names.mat", "variable 'InputName' must be a cell array of 1 char rows")
    good = tmp_path / "good.mat"
    helpers.write_mat73(good, base)
    cut = tmp_path / "cut73.mat"
    cut.write_bytes(good.read_bytes()[:1500])
    _refused(tmp_path, cut, "cut73.mat", "v7.3 (HDF5) file that HDF5 cannot open: truncated or corrupt")
    p = tmp_path / "h5py.mat"
    with h5py.File(p, "w", userblock_size=512) as f:
        f.create_dataset("ResponseData", data=np.ones((10, 1, 1))).attrs["MATLAB_class"] = np.bytes_("double")
    helpers.mat73_header(p)
    _refused(tmp_path, p, "h5py.mat", "variable 'ResponseData': an array without a MATLAB class", "h5py")
    p = tmp_path / "unit.mat"
    helpers.write_mat73(p, base)
    with h5py.File(p, "a") as f:
        del f["FrequencyUnit"]
        ds = f.create_dataset("FrequencyUnit", data=np.array([[ord("H"), ord("z")], [ord("H"), ord("z")]], "<u2"))
        helpers.matlab_class(ds, "char")
    _refused(tmp_path, p, "unit.mat", "variable 'FrequencyUnit': text that is not one row")


def test_idfrd_mat_round_trip_without_units(tmp_path):
    """An FRF without units: `msid export --mat` writes cells of empty char rows, each (libmatio) with a
    data element of 0 bytes, and `msid import` reads them back as unknown units (it used to read the
    empty element as the next cell: "variable 15 has a malformed cell")."""
    sio = pytest.importorskip("scipy.io")
    c = tmp_path / "f.csv"
    c.write_text("freq_hz,G_acc_force_re,G_acc_force_im,G_acc_force_sd,G_acc_torque_re,G_acc_torque_im,G_acc_torque_sd\n"
                 "1,0.5,0.1,0.01,0.2,0.3,0.01\n2,0.4,0.2,0.01,0.1,0.4,0.01\n3,0.3,0.3,0.01,0.0,0.5,0.01\n")
    doc, G, om = imported(c, tmp_path)
    run_ok("export", tmp_path / "f.csv.json", "--mat", tmp_path / "f.mat")
    units = sio.loadmat(tmp_path / "f.mat")["InputUnit"]
    assert units.shape == (2, 1) and all(u.size == 0 for u in units.flat)
    mdoc, G2, om2 = imported(tmp_path / "f.mat", tmp_path)
    np.testing.assert_array_equal(G2, G)
    np.testing.assert_array_equal(om2, om)
    assert mdoc["input_names"] == ["force", "torque"] and mdoc.get("input_units", ["", ""]) == ["", ""]


def test_truncated_mat(tmp_path):
    sio = pytest.importorskip("scipy.io")
    p = tmp_path / "full.mat"
    sio.savemat(p, {"ResponseData": np.ones((1, 1, 40)) * (1 + 2j), "Frequency": np.arange(1.0, 41.0)[:, None],
                    "Ts": 0.0}, format="5")
    data = p.read_bytes()
    cut = tmp_path / "cut.mat"
    cut.write_bytes(data[: len(data) - 200])
    _refused(tmp_path, cut, "cut.mat")


# ---------------- bad input: one message, non-zero exit, nothing written ----------------

def _refused(tmp_path, path, *words, extra=()):
    out = tmp_path / "out.json"
    r = run("import", path, "-o", out, *extra)
    assert r.returncode == 1, r.stdout + r.stderr
    assert not out.exists()
    msg = r.stderr.strip()
    assert msg.count("\n") == 0 and msg.startswith("msid import: error:"), msg
    for w in words:
        assert w in msg, msg
    # fit refuses it with the same message
    f = run("fit", "--method", "ml", "--order", "2", path, "-o", out, *extra)
    assert f.returncode == 1 and not out.exists()
    assert msg.split("error: ", 1)[1] in f.stderr
    return msg


def test_truncated_touchstone(tmp_path):
    text = (SKRF_DATA / "ntwk1.s2p").read_text().rstrip("\n")
    p = tmp_path / "cut.s2p"
    p.write_text(text[: text.rfind(" ")] + "\n")   # the last number of the last row cut off
    _refused(tmp_path, p, "cut.s2p", "8 numbers", "9")


def test_touchstone_whose_port_count_does_not_match(tmp_path):
    p = tmp_path / "wrong.s3p"
    p.write_text((SKRF_DATA / "ntwk1.s2p").read_text())
    _refused(tmp_path, p, "wrong.s3p", "3-port", "as many ports as its name says")
    q = tmp_path / "wrong.s1p"
    q.write_text((SKRF_DATA / "ntwk1.s2p").read_text())
    _refused(tmp_path, q, "wrong.s1p", "9 numbers", "1-port")


def test_csv_wrong_column_count_and_nan(tmp_path):
    p = tmp_path / "cols.csv"
    p.write_text("freq_hz,G_y_u_re,G_y_u_im\n1,0.5,0.1\n2,0.4\n")
    _refused(tmp_path, p, "cols.csv", "line 3", "2 columns", "header has 3")
    q = tmp_path / "nan.csv"
    q.write_text("freq_hz,G_y_u_re,G_y_u_im\n1,0.5,0.1\n2,nan,0.2\n")
    _refused(tmp_path, q, "nan.csv", "line 3", "not finite")


def _one_uff_lines(tmp_path):
    """The lines of a UFF file of one dataset 58 (60 values, even, complex double) written by pyuff."""
    sets, _ = _uff_sets(1, 6, np.linspace(2, 100, 60))
    p = tmp_path / "full.uff"
    pyuff.UFF(str(p)).write_sets(sets[:1], mode="add")
    return p.read_text().splitlines()


def test_truncated_uff(tmp_path):
    lines = _one_uff_lines(tmp_path)
    cut = tmp_path / "cut.uff"
    cut.write_text("\n".join(lines[:-6] + ["    -1"]) + "\n")   # data lines lost, the delimiter kept
    _refused(tmp_path, cut, "cut.uff", "announces 60 values", "truncated")
    half = tmp_path / "half.uff"
    half.write_text("\n".join(lines[:-6]) + "\n")   # no closing delimiter
    _refused(tmp_path, half, "half.uff", "no closing -1")


def test_uff_count_beyond_the_file_is_refused_before_allocating(tmp_path):
    lines = _one_uff_lines(tmp_path)
    i = next(k for k, ln in enumerate(lines) if ln.split()[:3] == ["6", "60", "1"])
    lines[i] = lines[i].replace("        60", "2000000000", 1)
    big = tmp_path / "big.uff"
    big.write_text("\n".join(lines) + "\n")
    _refused(tmp_path, big, "big.uff", "more than the dataset's data lines can hold")


def test_unknown_format_is_a_usage_error(tmp_path):
    out = tmp_path / "o.json"
    r = run("import", SKRF_DATA / "ntwk1.s2p", "--format", "hdf5", "-o", out)
    assert r.returncode == 2 and "--format must be" in r.stderr and not out.exists()


def test_format_by_content_for_other_extensions(tmp_path):
    """A CSV whose metadata starts with '#' is not taken for a Touchstone option line; a Touchstone
    file named otherwise is (a 1- or 2-port by its first row); --format names it outright."""
    c = tmp_path / "frf.txt"
    c.write_text("# units: F=N, x=m\nfreq_hz,G_x_F_re,G_x_F_im\n1,0.5,0.1\n2,0.4,0.2\n")
    doc, _, _ = imported(c, tmp_path)
    assert doc["imported"]["format"] == "csv" and doc["input_units"] == ["N"] and doc["output_units"] == ["m"]
    t = tmp_path / "vna.dat"
    t.write_text((SKRF_DATA / "ntwk1.s2p").read_text())
    doc, G, _ = imported(t, tmp_path)
    assert doc["imported"]["format"] == "touchstone" and G.shape[1:] == (2, 2)
    doc, _, _ = imported(c, tmp_path, "--format", "csv")
    assert doc["imported"]["format"] == "csv"
