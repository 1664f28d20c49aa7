"""Messages in Python's words, naming the right cause. Before the fix msid's
messages named command-line flags (--order, --window, --delta, --columns, "--method must be ..."),
"--period 2 does not fit the input" ended in "with 2, . Use", more than 16 outputs was "measurement
dimensions out of range", a path among arrays was "a 0-dimensional array of shape ()", a pandas
Float64 frame "dtype object", "(an FRF holds finite numbers only)" was appended to unrelated errors,
cissim's default lags were blamed on a --lags nobody gave, and a Measurement whose block was refused for
a NaN said "rejecting 0", and a Modbus host given by name was "libmodbus: Invalid argument"."""
import json
import re
import warnings

import numpy as np
import pytest

import msid
from msid import _msid as ext
from child import small_case

P, LINES = 256, "1:3:60"


@pytest.fixture(scope="module")
def data():
    return small_case(P, LINES)


def no_flag(text):
    assert not re.search(r"(^|[\s(,])--[a-z]", text), text
    return text


def test_python_words_rule():
    w = ext._python_words
    assert w("--skip-periods 3 leaves fewer; give --fs (msid's design)") == "skip_periods 3 leaves fewer; give fs (msid's design)"
    assert w("'a --b.csv' line 2 --order") == "'a --b.csv' line 2 order"   # quoted text is the user's
    # a command line named in prose stays one, to the end of its clause
    assert w("needs a model of msid fit --method multi (not --order)") == "needs a model of msid fit --method multi (not order)"


def test_options_rendered_per_front_end():
    """A library names an option neutrally (0x1f name 0x1f); the command line renders its flag, Python its keyword."""
    r = ext._render_options
    m = "\x1fskip_periods\x1f 3 leaves fewer than 2 periods; \x1fdirect\x1f needs \x1fdesign\x1f"
    assert r(m, False) == "--skip-periods 3 leaves fewer than 2 periods; --direct needs --design"
    assert r(m, True) == "skip_periods 3 leaves fewer than 2 periods; direct needs design"
    assert r("without \x1fno_realtime\x1f", False) == "without --no-realtime"
    assert r("without \x1fno_realtime\x1f", True) == "without realtime=False"   # the table's own words
    assert r("no option named", True) == "no option named"
    assert r("an unpaired \x1fmark", True) == "an unpaired mark"


def test_keyword_check_reports_flags():
    """The check every test_ext_* bad-input case passes through (keyword_messages.py) fails on a flag:
    its negative control."""
    from keyword_messages import checking_raises
    seen = []
    raises = checking_raises(pytest.raises, ext._python_words, seen)
    with pytest.raises(AssertionError, match="names a command-line flag"):
        with raises(ValueError):
            raise ValueError("--skip-periods 3 leaves fewer than 2 of the 3 periods")
    with raises(ValueError):
        raise ValueError("skip_periods 3 leaves fewer than 2 of the 3 periods")
    with raises(ValueError):   # a command line quoted in prose, and a quoted file name, stay as they are
        raise ValueError("'a --b.csv': needs a model of msid fit --method multi")
    assert len(seen) == 3


def test_keywords_not_flags(data):
    d, rec = data
    cases = [
        (dict(method="lpm", n_inputs=1, order=9), "order must be 0..8"),
        (dict(method="lpm", n_inputs=1, window=0), "window must be at least 1"),
        (dict(method="etfe", n_inputs=1, period=P, delta=1.5), "delta must be in (0, 1)"),
        (dict(method="arx", n_inputs=1), "method must be 'periodic', 'lpm' or 'etfe', not 'arx'"),
    ]
    for kw, want in cases:
        with pytest.raises(ValueError) as e:
            msid.frf(rec, **kw)
        assert no_flag(str(e.value)) == want, kw
    pd = pytest.importorskip("pandas")
    with pytest.raises(ValueError) as e:
        msid.frf(pd.DataFrame({"a": rec[:, 0], "b": rec[:, 1]}), design=d)
    assert "map them with columns u1=NAME,y1=NAME" in no_flag(str(e.value))


def test_wrong_period_is_one_sentence(data):
    d, rec = data
    with pytest.raises(ValueError) as e:
        msid.frf(rec, period=128, lines="1:3:60", n_inputs=1)
    text = no_flag(str(e.value))
    assert "period 128 does not fit the input: it repeats every 256 samples" in text and text.endswith("Use period 256")
    assert ", ." not in text and "with 128, ." not in text


def test_too_many_outputs_names_the_limit(data):
    d, rec = data
    wide = np.column_stack([rec[:, 0]] + [rec[:, 1]] * 17)
    with pytest.raises(ValueError, match="1 inputs and 17 outputs: msid estimates at most 16 inputs and 16 outputs"):
        msid.frf(wide, design=d)
    m = msid.Measurement(design=d)
    with pytest.raises(ValueError, match="at most 16 inputs and 16 outputs"):
        m.push(wide, experiment=0)


def test_records_of_the_wrong_kind(data, tmp_path):
    d, rec = data
    with pytest.raises(TypeError, match=r"'records\[1\]' is a path among arrays"):
        msid.frf([rec, str(tmp_path / "x.csv")], design=d)
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"u1": rec[:, 0], "y1": rec[:, 1]}).astype("Float64")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert np.array_equal(msid.frf(frame, design=d).G, msid.frf(rec, design=d).G)
    frame.loc[7, "y1"] = pd.NA
    with pytest.raises(ValueError, match=r"'records\[0\]' row 8, column y1: NaN or Inf is not allowed"):
        msid.frf(frame, design=d)


def test_finite_note_only_for_non_finite_numbers(data):
    d, rec = data
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d)
    del f.meta["period_samples"]
    with pytest.raises(ValueError) as e:
        msid.fit(f, method="ml", order=2)
    assert "period_samples" in str(e.value) and "finite numbers only" not in str(e.value)
    f2 = msid.frf(rec, design=d)
    f2.G = f2.G.copy()
    f2.G[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite numbers only"):
        msid.fit(f2, method="ml", order=2)


def test_default_lags_are_not_blamed_on_a_lags_keyword(data):
    d, rec = data
    with pytest.raises(ValueError) as e:
        msid.fit([rec[: 3 * P]], method="cissim", design=d, order=40, skip_periods=0)
    text = no_flag(str(e.value))
    assert "order 40 needs 1601 noise correlation lags" in text and "lags 1601" not in text, text


def test_a_refused_block_is_said_so(data):
    """A block whose last row is NaN is refused whole (the rows stay aligned with the periods); before the
    fix frf() then said only "rejecting 0"."""
    d, rec = data
    m = msid.Measurement(design=d)
    bad = rec.copy()
    bad[-1, 1] = np.nan
    with pytest.raises(ValueError, match=f"row {len(rec)}, column 2: NaN or Inf is not allowed: the block of "
                                         f"{len(rec)} rows is not taken"):
        m.push(bad, experiment=0)
    with pytest.raises(ValueError, match=f"experiment 0: only 0 usable period\\(s\\) were taken \\(at least 2 are "
                                         f"needed\\): {len(rec)} rows came in blocks refused for NaN or Inf"):
        m.frf()


def test_modbus_host_names_are_resolved(tmp_path):
    """modbus-tcp://localhost:PORT reaches the device as 127.0.0.1 does; before the fix libmodbus took a
    dotted IPv4 address only and said "Invalid argument" (or, resolving to ::1, "Network is unreachable")."""
    from child import DESIGN, sim_module
    mblib = sim_module()
    d = msid.design(**DESIGN)
    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        f = msid.measure(f"modbus-tcp://localhost:{sim.port}", d, periods=3, skip_periods=1)
    assert f.meta["complete"] is True


def test_a_scale_that_zeroes_the_inputs_is_named(tmp_path):
    """A scale (the value of one integer step of the streamed samples) more than twice an input's largest
    sample sends that input as zeros: refused before the device runs, naming the scale, by msid.measure
    and msid measure alike; before the fix the run ended in "the input matrix is singular at line 1"."""
    import os
    import subprocess
    from child import DESIGN, sim_module
    mblib = sim_module()
    d = msid.design(**DESIGN)
    d.save(tmp_path / "d.json")
    want = ("scale 1e+09 (the value of one step of the samples' integers) is more than twice the largest sample "
            "of input 1 (at most 8): the input would be sent as zeros and its lines not excited; a scale of at "
            "most 0.00781 keeps 10 bits of it")
    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        uri = f"modbus-tcp://127.0.0.1:{sim.port}"
        with pytest.raises(ValueError) as e:
            msid.measure(uri, d, periods=3, scale=1e9)
        assert no_flag(str(e.value)) == want
        r = subprocess.run([os.environ["MSID_BIN"], "measure", "--device", uri, "--design", tmp_path / "d.json",
                            "--periods", "3", "--scale", "1e9", "--quiet", "--no-plots", "-o", tmp_path / "out"],
                           capture_output=True, text=True)
        assert r.returncode == 2 and r.stderr.strip().endswith("--" + want), r.stderr
        # the device serves the next run at a usable scale
        f = msid.measure(uri, d, periods=3, skip_periods=1)
    assert f.meta["complete"] is True


def test_notes_name_keywords_not_flags(data):
    """msid's notes (NoteWarning, .notes) in Python's words, as its errors are: before the fix a start-up
    transient's note said "use --skip-periods or --transient drop" and an interpolating LMFD's "--method ml"."""
    d, rec = data
    bad = rec.copy()
    bad[:100, 1] += 5 * np.exp(-np.arange(100) / 20)   # a start-up transient in the first period
    with pytest.warns(msid.NoteWarning) as w:
        f = msid.frf(bad, design=d)
    transient = [n for n in f.notes if "start-up transient" in n]
    assert transient and transient[0].endswith("kept (use skip_periods or transient drop)"), f.notes
    for n in f.notes + [str(x.message) for x in w]:
        no_flag(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d, skip_periods=1)
        m = msid.fit(f, method="lmfd", order=200)
    assert any("a lower order, or method ml, fits the plant" in n for n in m.notes), m.notes
    for n in m.notes:
        no_flag(n)


def test_an_unresolvable_modbus_host_is_an_oserror():
    """A host name that does not resolve: an OSError naming it and the URI, and nothing on stderr; before the
    fix "libmodbus: Invalid argument" and a stray line of libmodbus's on stderr."""
    from child import DESIGN, run_child
    r = run_child("""
        import json, sys
        import msid
        d = msid.design(**json.loads(sys.argv[1]))
        try:
            msid.measure("modbus-tcp://no-such-host.invalid:502", d, periods=3)
        except OSError as e:
            print(type(e).__name__ + ": " + str(e))
    """, json.dumps(DESIGN))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().startswith("OSError: cannot resolve host 'no-such-host.invalid'"), r.stdout
    assert r.stdout.strip().endswith("(modbus-tcp://no-such-host.invalid:502)"), r.stdout
    assert r.stderr == "", r.stderr


def test_a_device_killed_mid_run_is_said_so(tmp_path):
    """msid-devsim killed (SIGKILL) while msid.measure runs: an OSError saying the device no longer answers
    (the connection refused), not "bad request"; before the fix "read input registers 0..39: bad request"."""
    import threading
    from child import DESIGN, sim_module
    mblib = sim_module()
    d = msid.design(**DESIGN)
    started = threading.Event()

    def progress(s):
        if s["periods_total"] >= 1:
            started.set()

    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        sim.expect_exit = -9

        def kill():
            if started.wait(60):
                sim.p.kill()

        t = threading.Thread(target=kill)
        t.start()
        with pytest.raises(OSError) as e:
            msid.measure(f"modbus-tcp://127.0.0.1:{sim.port}", d, periods=400, rate=2000, progress=progress)
        t.join()
    text = no_flag(str(e.value))
    assert started.is_set() and "bad request" not in text, text
    assert re.search(r"no valid reply to .* after \d+ attempts: cannot connect to 127\.0\.0\.1:\d+: Connection refused",
                     text), text
