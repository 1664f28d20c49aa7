"""The hostile-input campaign: Hypothesis (PyPI, pinned in scripts/deps.sh) drives every public
function of the package with generated arrays, strings, numbers and keyword sets. The rule: a result,
or ValueError, TypeError or OSError with a non-empty message; never another exception, a crash or a
hang (ctest's TIMEOUT is the hang detector; a crash ends the interpreter and fails the test).

The profile "ci" (the default) is derandomized with a fixed example budget per function, so that the
run is the same on every machine and ends in a couple of minutes on a busy 2-core box; the profile
"campaign" (MSID_HYPOTHESIS_PROFILE=campaign) is the long run of docs/reliability.md."""
import os
import string
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402
from hypothesis.extra import numpy as hnp  # noqa: E402

import msid  # noqa: E402
from child import quiet, small_frf  # noqa: E402

_COMMON = dict(derandomize=True, deadline=None, database=None, print_blob=False,
               suppress_health_check=list(HealthCheck))
settings.register_profile("ci", max_examples=60, **_COMMON)
settings.register_profile("campaign", max_examples=3000, **_COMMON)
PROFILE = os.environ.get("MSID_HYPOTHESIS_PROFILE", "ci")
settings.load_profile(PROFILE)


def budget(n):
    """Examples of one function: n in the ci profile (the slow ones fewer), the profile's otherwise."""
    return settings(max_examples=n if PROFILE == "ci" else settings().max_examples)


ALLOWED = (ValueError, TypeError, OSError)


def obeys_the_rule(call, *args, **kwargs):
    """A result, or one of the three exception types with a message; anything else fails the test."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # msid's notes (NoteWarning, ConvergenceWarning) are results
        try:
            return call(*args, **kwargs)
        except ALLOWED as e:
            assert str(e).strip(), f"{type(e).__name__} without a message from {call.__name__}"
            return None


# ---- what the strategies draw ----

P, LINES = 64, "1:3:20"
INTS = st.one_of(st.integers(-3, 300), st.integers(-2 ** 70, 2 ** 70), st.sampled_from([0, 1, 2 ** 31, 2 ** 32, 2 ** 64]))
FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=64)
NUMBER = st.one_of(INTS, FLOATS, st.booleans(), st.none(), st.sampled_from([1e-320, 1e308, -0.0, 1.7]))
TEXT = st.one_of(st.text(alphabet=string.digits + ":,- ", max_size=14), st.text(max_size=10),
                 st.sampled_from(["1:1000000000", "1:10000000", "auto", "0:3:4000000000", "", "u1=1,y1=2", "--fs"]))
VALUE = st.one_of(NUMBER, TEXT, st.lists(INTS, max_size=4), st.tuples(FLOATS, FLOATS), st.just(object()))
DTYPES = st.sampled_from([np.float64, np.float32, np.int16, np.int64, np.uint8, np.complex128, np.bool_, np.float16])
ELEMS = st.one_of(st.floats(-1e3, 1e3), FLOATS, st.sampled_from([1e307, 1e308, -1e308, 5e-324]))


@st.composite
def arrays(draw):
    dtype = draw(DTYPES)
    shape = draw(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=300))
    if np.prod(shape) > 4000:
        shape = (min(shape[0], 1000), 2)[: max(len(shape), 1)]
    if np.dtype(dtype).kind == "f":
        def representable(x):
            with np.errstate(over="ignore"):
                return bool(np.isfinite(np.dtype(dtype).type(x))) or not np.isfinite(x)
        return draw(hnp.arrays(dtype, shape, elements=ELEMS.filter(representable)))
    return draw(hnp.arrays(dtype, shape))


# values a keyword takes when it is used well: drawn as often as hostile ones, so that the calls get past
# their first check into the libraries
PLAUSIBLE = st.one_of(st.integers(0, 12), st.floats(0.001, 1e4), st.sampled_from(
    ["auto", "flag", "drop", "off", "stream", "fft", "cov", "none", "ml", "lmfd", "poles", "yes", "no", "dt", "ct",
     "1:3:20", "1,4,7", "2:6", (0.01, 0.3), "0.01:0.3", True, False, None]))


def keywords(names):
    """A set of keywords of `names` (an unknown one now and then), each value hostile or plausible."""
    key = st.sampled_from(sorted(names) + ["bogus"])
    return st.dictionaries(st.sampled_from(sorted(names)), st.one_of(VALUE, PLAUSIBLE), max_size=5) | \
        st.dictionaries(key, VALUE, max_size=2)


@pytest.fixture(scope="module")
def valid():
    """A small design, its records, the FRF and an ml model: what the mutations start from."""
    d, rec, f = small_frf(P, LINES)
    m = quiet(msid.fit, f, method="ml", order=2)
    return d, rec, f, m


# ---- the public functions ----

FRF_KW = {"design", "period", "lines", "skip_periods", "fs", "method", "columns", "n_inputs", "detect_lines",
          "transient", "alpha", "dft", "block", "realisations", "direct", "order", "window", "band", "reference",
          "delta", "gstar", "threads"}


@budget(500)
@given(records=st.one_of(arrays(), st.lists(arrays(), max_size=3)), kw=keywords(FRF_KW))
def test_frf_on_generated_arrays(records, kw):
    obeys_the_rule(msid.frf, records, **kw)


@budget(400)
@given(data=st.data(), kw=keywords(FRF_KW - {"design"}))
def test_frf_keywords_on_good_records(valid, data, kw):
    d, rec, f, m = valid
    base = data.draw(st.sampled_from([dict(design=d), dict(period=P, lines=LINES, n_inputs=1),
                                      dict(method="lpm", n_inputs=1), dict(method="etfe", period=P, n_inputs=1)]))
    base.update(kw)
    obeys_the_rule(msid.frf, rec, **base)


DESIGN_KW = {"lines", "omega", "sample_time", "amplitudes", "phases", "seed", "inputs", "experiments", "pattern",
             "periods"}


@budget(300)
@given(period=VALUE, kw=keywords(DESIGN_KW))
def test_design(period, kw):
    d = obeys_the_rule(msid.design, period, **kw)
    if d is not None:   # a design that was built: its methods on generated arguments
        obeys_the_rule(d.samples, 0, 1)
        obeys_the_rule(d.crest_factor, 0, 0)


@budget(200)
@given(a=VALUE, b=VALUE)
def test_design_methods(valid, a, b):
    d = valid[0]
    obeys_the_rule(d.crest_factor, a, b)
    obeys_the_rule(d.samples, a, b if not isinstance(b, int) or b < 50 else 1)


MEAS_KW = {"skip_periods", "fs", "detect_lines", "transient", "alpha", "dft", "max_periods"}


@budget(300)
@given(kw=keywords(MEAS_KW), blocks=st.lists(st.one_of(arrays(), st.integers(0, 200)), max_size=4),
       experiment=st.one_of(st.just(0), VALUE))
def test_measurement(valid, kw, blocks, experiment):
    d, rec = valid[0], valid[1]
    m = obeys_the_rule(msid.Measurement, d, **kw)
    if m is None:
        return
    for b in blocks:
        obeys_the_rule(m.push, rec[: b] if isinstance(b, int) else b, experiment)
    obeys_the_rule(m.frf)
    obeys_the_rule(lambda: m.progress)


FIT_KW = {"nd", "nn", "domain", "weight", "noise_var", "r", "stable", "allow_unstable", "no_d", "pins", "start",
          "max_iter", "delta", "beta", "feedthrough", "param", "refine", "weight_smooth"}


@budget(250)
@given(method=st.one_of(st.sampled_from(["subspace", "lmfd", "ml", "cissim", "multi"]), TEXT),
       order=st.one_of(st.integers(-2, 6), VALUE), kw=keywords(FIT_KW | {"period", "lines", "n_inputs"}))
def test_fit(valid, method, order, kw):
    d, rec, f, m = valid
    data = rec if method in ("cissim", "multi") else f
    if isinstance(kw.get("max_iter"), int) and kw["max_iter"] > 50:
        kw["max_iter"] = 50   # a result after many iterations is a result: kept short
    obeys_the_rule(msid.fit, data, method, order, **kw)


@budget(200)
@given(kw=keywords({"weight", "lpm_lines", "records", "lags", "own_records", "columns", "n_inputs"}),
       which=st.sampled_from(["model", "frf", "both"]), other=VALUE)
def test_validate_and_modes(valid, kw, which, other):
    d, rec, f, m = valid
    model = other if which in ("model", "both") else m
    frf = other if which in ("frf", "both") else f
    obeys_the_rule(msid.validate, model, frf, **kw)
    obeys_the_rule(msid.modes, model)


@budget(300)
@given(content=st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode),
                         st.sampled_from([b"{", b'{"format": "msid-frf/1"}', b"\x93NUMPY", b'{"format": "msid-model/1"}',
                                          b"u1,y1\n1,2\xb0\n", b"[" * 5000])),
       suffix=st.sampled_from([".json", ".csv", ".s2p", ".uff", ".mat", ".npy", ""]))
def test_file_readers(tmp_path_factory, content, suffix):
    p = tmp_path_factory.mktemp("h") / ("x" + suffix)
    p.write_bytes(content)
    for call in (msid.read_frf, msid.read_model, msid.import_frf, msid.read_design):
        obeys_the_rule(call, p)
    obeys_the_rule(msid.fit, p, "ml", 2)
    obeys_the_rule(msid.export, p, p.with_name("out.csv"))


@budget(150)
@given(out=st.one_of(TEXT, st.sampled_from(["/nonexistent/dir/x.csv", "x.mat", "x.txt", "/proc/x.csv"])),
       known=VALUE)
def test_export_and_writers(valid, tmp_path_factory, out, known):
    d, rec, f, m = valid
    where = tmp_path_factory.mktemp("w")
    target = out if os.path.isabs(out) else str(where / out) if out else ""
    obeys_the_rule(msid.export, f, target, known_input=known)
    obeys_the_rule(msid.export, m, target)
    obeys_the_rule(msid.write_frf, target, f)
    obeys_the_rule(msid.write_model, target, m)


MEASURE_KW = {"periods", "skip_periods", "rate", "fs", "scale", "timeout", "detect_lines", "transient", "alpha",
              "dft", "progress", "on_device", "stream_check"}


@budget(40)
@given(device=st.one_of(TEXT, st.sampled_from(["modbus-tcp://127.0.0.1:1", "modbus-tcp://", "can://", "http://x",
                                               "modbus-rtu:///dev/null", "modbus-tcp://127.0.0.1:1?unit=300"])),
       kw=keywords(MEASURE_KW))
def test_measure_without_a_device(valid, device, kw):
    if kw.get("timeout") is not None and not (isinstance(kw["timeout"], (int, float)) and kw["timeout"] < 3):
        kw["timeout"] = 1.0   # a closed port is refused at once; a long timeout is a result of waiting
    obeys_the_rule(msid.measure, device, valid[0], **kw)
