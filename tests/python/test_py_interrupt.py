"""Ctrl-C lands during long calls. A SIGINT is sent at a random moment of each
long call (seeded: a random share of the call's own work), and the call must raise KeyboardInterrupt
long before it would have finished. Judged by the call's own progress (msid._msid._progress(): the
units of work the libraries' checkpoints counted), never by the wall clock: the work done after the
signal is a small share of the whole, and the call did not finish. Before the fix the interrupt
waited until the call returned (the whole work done), and the result was then thrown away."""
import os
import random
import signal
import threading
import time
import warnings

import numpy as np
import pytest

import msid
from msid import _msid as ext

RNG = random.Random(45)


class SigintAt:
    """Send SIGINT to this process once `step`'s progress has grown by `target` units (a thread of its
    own watches the counter); `at` is how far it had got once the signal had arrived (the extension's
    count of SIGINTs moved: from then on every checkpoint of the call stops, so the work counted after
    `at` is the blocks in flight, however late the kernel ran the handler on a loaded machine)."""

    def __init__(self, step, target):
        self.step, self.target = step, target
        self.base = ext._progress()[step]
        self.at = None
        self.t = threading.Thread(target=self._watch, daemon=True)
        self.t.start()

    def done(self):
        return ext._progress()[self.step] - self.base

    def _watch(self):
        while self.done() < self.target:
            time.sleep(0.0005)
        n0 = ext._sigints()
        os.kill(os.getpid(), signal.SIGINT)
        give_up = time.monotonic() + 60   # only against a hang: the handler runs once the kernel schedules it
        while ext._sigints() == n0 and time.monotonic() < give_up:
            time.sleep(0.0005)
        self.at = self.done()


def periodic_record(P, lines, periods, seed=1):
    d = msid.design(period=P, lines=lines, amplitudes=0.3, seed=seed, periods=periods)
    u = d.samples(0, periods)
    y = 0.5 * u[:, 0] + 0.01 * np.random.default_rng(seed).standard_normal(len(u))
    return d, np.column_stack([u[:, 0], y])


def test_frf_streaming_path():
    """msid.frf(dft="stream") on 2^20 samples of 1000 lines: interrupted after a random 5..50% of its rows."""
    d, rec = periodic_record(4096, "1:1000", 256)
    total = len(rec)
    s = SigintAt("rows", int(RNG.uniform(0.05, 0.5) * total))
    with pytest.raises(KeyboardInterrupt):
        msid.frf(rec, design=d, dft="stream")
    s.t.join()
    got = s.done()
    assert s.at is not None and s.at <= got < total, (s.at, got, total)
    assert got - s.at <= 0.05 * total, (s.at, got, total)
    # the module works on after it: the same call gives its FRF
    f = msid.frf(rec[: 4096 * 4], design=d, dft="stream")
    assert f.n_lines == 1000


def test_lpm_on_a_long_record():
    """msid.frf(method="lpm") on 2^21 samples of white noise (1,048,575 lines, blocks of 2048 on two
    threads; then the document, which takes most of the call): interrupted after a random 5..50% of its
    lines, at most the block each thread had in flight (2048 lines, to a multiple of 16) done after it."""
    rng = np.random.default_rng(3)
    N = 1 << 21
    u = rng.standard_normal(N)
    rec = np.column_stack([u, np.convolve(u, [0.5, 0.3, 0.1])[:N] + 0.01 * rng.standard_normal(N)])
    total = N // 2 - 1
    s = SigintAt("lines", int(RNG.uniform(0.05, 0.5) * total))
    with pytest.raises(KeyboardInterrupt):
        msid.frf(rec, method="lpm", n_inputs=1)
    s.t.join()
    got = s.done()
    assert s.at is not None and s.at <= got < total and got - s.at <= 2 * (2048 + 16), (s.at, got, total)


class SigintAtCheckpoint:
    """SIGINT raised by the checkpoint that counts the `target`-th more unit of `step`
    (msid._msid._interrupt_at): the signal placed by the work done, also in work that holds the GIL,
    where a watcher thread cannot look."""

    def __init__(self, step, target):
        self.step, self.target = step, target
        self.base = ext._progress()[step]
        ext._interrupt_at(step, target)

    def done(self):
        return ext._progress()[self.step] - self.base

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        ext._interrupt_at("", 0)   # a call that ended before the target must not leave it armed
        return False


def long_lpm_record():
    rng = np.random.default_rng(3)
    N = 1 << 21
    u = rng.standard_normal(N)
    return np.column_stack([u, np.convolve(u, [0.5, 0.3, 0.1])[:N] + 0.01 * rng.standard_normal(N)])


@pytest.mark.parametrize("phase", ["building", "conversion"])
def test_lpm_document_steps(phase):
    """The same LPM once its lines are done: the document of its 1,048,575 lines is built (without the
    GIL), then turned into NumPy arrays and Python objects (about 17 passes over the lines, with the GIL
    held) and freed, each pass counted per chunk of 1024 lines ("document"). SIGINT at a random chunk of
    the building or of the conversion: KeyboardInterrupt within 64 chunks of it (the building asks every
    20 ms, the conversion every chunk), nothing returned, and an LPM afterwards gives its earlier bits."""
    rec = long_lpm_record()
    small = rec[:4096]
    before = msid.frf(small, method="lpm", n_inputs=1)
    total = len(rec) // 2 - 1
    lines0 = ext._progress()["lines"]
    share = RNG.uniform(0.05, 0.9) if phase == "building" else RNG.uniform(1.1, 12.0)
    out = None
    with SigintAtCheckpoint("document", int(share * total)) as s, pytest.raises(KeyboardInterrupt):
        out = msid.frf(rec, method="lpm", n_inputs=1)
    got = s.done()
    assert out is None
    assert ext._progress()["lines"] - lines0 == total   # the lines' phase was done: the signal came after it
    assert s.target <= got <= s.target + 64 * 1024, (s.target, got, total)
    after = msid.frf(small, method="lpm", n_inputs=1)
    assert after.G.tobytes() == before.G.tobytes() and after.cov.tobytes() == before.cov.tobytes()


def test_lpm_document_passes_are_counted():
    """The negative control of the test above: uninterrupted, the document's passes count more than 12
    line counts (so a target up to 12 falls inside the call), and the call's result is whole."""
    rec = long_lpm_record()
    base = ext._progress()["document"]
    f = msid.frf(rec, method="lpm", n_inputs=1)
    total = len(rec) // 2 - 1
    assert f.n_lines == total and ext._progress()["document"] - base > 12 * total


@pytest.fixture(scope="module")
def scan_frf():
    """A 2x2 FRF of 4 resonances (two inputs, two experiments, 300 lines): an ml order scan over it takes
    tens of seconds."""
    P, L = 2048, "2:2:600"
    d = msid.design(period=P, lines=L, amplitudes=0.3, seed=5, inputs=2, periods=6)
    rng = np.random.default_rng(5)
    recs = []
    poles = np.exp(np.array([-0.01 + 0.3j, -0.02 + 0.9j, -0.015 + 1.6j, -0.03 + 2.2j]))
    for e in range(2):
        u = d.samples(e, 6)
        y = np.zeros_like(u)
        for k, p in enumerate(poles):   # a second-order section per resonance, driven by both inputs
            a1, a2 = -2 * p.real, abs(p) ** 2
            x = u[:, 0] * (1 + 0.3 * k) + u[:, 1] * (0.5 - 0.1 * k)
            s = np.zeros(len(x))
            for n in range(2, len(x)):
                s[n] = x[n] - a1 * s[n - 1] - a2 * s[n - 2]
            y[:, 0] += 0.01 * s
            y[:, 1] += 0.01 * s * (1 - 0.2 * k)
        y += 0.001 * rng.standard_normal(y.shape)
        recs.append(np.column_stack([u, y]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return msid.frf(recs, design=d, skip_periods=1)


def test_fit_order_scan(scan_frf):
    """msid.fit(method="ml", order="2:30"): interrupted after a random 1..8 of its 15 orders."""
    total = 15   # 2, 4, .., 30 (two outputs: a step of 2)
    s = SigintAt("orders", RNG.randint(1, 8))
    with pytest.raises(KeyboardInterrupt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            msid.fit(scan_frf, method="ml", order="2:30")
    s.t.join()
    got = s.done()
    assert s.at is not None and s.at <= got <= s.at + 1 and got < total, (s.at, got)


def test_lmfd_at_high_order():
    """msid.fit(method="lmfd") at order 300 on 300 lines: its one long step, the SVD of the interpolation
    equations (600 x 903, seconds), counts one solve when it begins and one when it is done. SIGINT once
    it began: KeyboardInterrupt before it is done (the step is abandoned: it ends on its own thread)."""
    d, rec = periodic_record(4096, "1:300", 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d, skip_periods=1)
    s = SigintAt("solves", 1)
    with pytest.raises(KeyboardInterrupt):
        msid.fit(f, method="lmfd", order=300)
    s.t.join()
    assert s.at == 1 and s.done() == 1, (s.at, s.done())


def test_wait_behind_a_measurement_in_another_thread(tmp_path):
    """msid.frf in the main thread waits for the planner lock that msid.measure holds in another thread:
    interrupted while it waits, long before the measurement ends (its own progress: periods)."""
    from child import DESIGN, sim_module
    mblib = sim_module()
    d = msid.design(**DESIGN)
    small, rec = periodic_record(64, "1:5", 4)
    state = {"periods": 0, "stop": False}
    started = threading.Event()

    def progress(s):
        state["periods"] = s["periods_total"]
        started.set()
        if state["stop"]:
            raise KeyboardInterrupt

    total = 2 * 400
    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        out = {}

        def run():
            try:
                out["f"] = msid.measure(f"modbus-tcp://127.0.0.1:{sim.port}", d, periods=400, rate=2000,
                                        progress=progress)
            except KeyboardInterrupt as e:
                out["stopped"] = e

        t = threading.Thread(target=run)
        t.start()
        assert started.wait(60)
        at = state["periods"]
        threading.Timer(RNG.uniform(0.05, 0.5), os.kill, (os.getpid(), signal.SIGINT)).start()
        with pytest.raises(KeyboardInterrupt):
            msid.frf(rec, design=small)   # waits: the measurement holds the planner lock
        assert state["periods"] < total and t.is_alive(), (at, state)
        state["stop"] = True
        t.join(60)
        assert "stopped" in out and not t.is_alive()


def resonant_record(P, lines, periods, order, seed=1):
    """A periodic record of a plant of `order` states (order / 2 lightly damped resonances over the band)."""
    from scipy.signal import lfilter
    d = msid.design(period=P, lines=lines, amplitudes=0.3, seed=seed, periods=periods)
    u = d.samples(0, periods)[:, 0]
    y = np.zeros(len(u))
    for th in np.linspace(0.05, 2.8, order // 2):
        p = 0.97 * np.exp(1j * th)
        y += lfilter([0.1, 0.05], [1, -2 * p.real, abs(p) ** 2], u)
    y += 0.01 * np.random.default_rng(seed).standard_normal(len(u))
    return d, np.column_stack([u, y])


def test_subspace_dense_steps():
    """msid.fit(method="subspace") at order 200 on 1000 lines (tens of seconds): its dense steps (the QR of
    the data, the eigendecompositions of each block-row count, the SVD of the resolvent's eigenvectors,
    some of them on a second thread) count one solve when each begins and one when it is done. SIGINT
    after a random 1..16 of their (about 24) counts: KeyboardInterrupt with at most two more counted (a step
    begun on the other thread), and the model never evaluated at the lines (the fit's last part)."""
    d, rec = periodic_record(4096, "1:1000", 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d, skip_periods=1)
    lines0 = ext._progress()["lines"]
    s = SigintAt("solves", RNG.randint(1, 16))
    with pytest.raises(KeyboardInterrupt):
        msid.fit(f, method="subspace", order=200, refine="none")
    s.t.join()
    assert s.at is not None and s.done() - s.at <= 2, (s.at, s.done())
    assert ext._progress()["lines"] == lines0


@pytest.fixture(scope="module")
def cissim_record():
    return resonant_record(2048, "1:600", 8, 20)


def test_cissim_refinement(cissim_record):
    """msid.fit(method="cissim") at order 20 on 600 lines: the ML refinement's iterations (about 55, tens of
    milliseconds each) are counted. SIGINT after a random 3..30 of them: KeyboardInterrupt at most 3
    iterations later, before the FRF's covariance at the lines (the refinement's end) began."""
    d, rec = cissim_record
    lines0 = ext._progress()["lines"]
    s = SigintAt("iterations", RNG.randint(3, 30))
    with pytest.raises(KeyboardInterrupt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            msid.fit([rec], method="cissim", design=d, order=20)
    s.t.join()
    assert s.at is not None and s.done() - s.at <= 3, (s.at, s.done())
    assert ext._progress()["lines"] == lines0


def test_cissim_noise_covariance(cissim_record):
    """The same fit's noise covariance (the constrained least squares of its thousands of solver iterations,
    after the refinement's covariance at the 600 lines): SIGINT a random 100..2000 iterations into it,
    KeyboardInterrupt within a fifth of its iterations."""
    d, rec = cissim_record
    state = {}

    def watch():
        lines0 = ext._progress()["lines"]
        while ext._progress()["lines"] - lines0 < 600:   # the refinement is done
            time.sleep(0.0005)
        base = ext._progress()["iterations"]
        target = RNG.randint(100, 2000)
        while ext._progress()["iterations"] - base < target:
            time.sleep(0.0005)
        state["base"], state["at"] = base, ext._progress()["iterations"]
        os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    with pytest.raises(KeyboardInterrupt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            msid.fit([rec], method="cissim", design=d, order=20)
    t.join()
    got = ext._progress()["iterations"]
    assert "at" in state and got - state["at"] <= 1000, (state, got)


def test_multi_iterations():
    """msid.fit(method="multi") at order 16 on two records of 10^5 samples: about 10 iterations of a second
    or more each (every record filtered and projected per iteration). SIGINT after a random 1..6: at most one
    more iteration begins."""
    from scipy.signal import lfilter
    rng = np.random.default_rng(2)
    recs = []
    for _ in range(2):
        u = rng.standard_normal(100000)
        y = np.zeros(len(u))
        for th in np.linspace(0.2, 2.5, 8):
            p = 0.95 * np.exp(1j * th)
            y += lfilter([0.1, 0.05], [1, -2 * p.real, abs(p) ** 2], u)
        recs.append(np.column_stack([u, y + 0.01 * rng.standard_normal(len(u))]))
    s = SigintAt("iterations", RNG.randint(1, 6))
    with pytest.raises(KeyboardInterrupt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            msid.fit(recs, method="multi", order=16, n_inputs=1)
    s.t.join()
    assert s.at is not None and s.done() - s.at <= 1, (s.at, s.done())


def multi_records(n_records, samples, seed, n_inputs=1):
    """Records of an order-16 system (eight resonances) driven by `n_inputs` white inputs: columns u.., y."""
    from scipy.signal import lfilter
    rng = np.random.default_rng(seed)
    recs = []
    for _ in range(n_records):
        u = rng.standard_normal(samples) if n_inputs == 1 else rng.standard_normal((samples, n_inputs))
        y = np.zeros(samples)
        for th in np.linspace(0.2, 2.5, 8):
            p = 0.95 * np.exp(1j * th)
            for k in range(n_inputs):
                y += lfilter([0.1 + 0.02 * k, 0.05], [1, -2 * p.real, abs(p) ** 2], u if n_inputs == 1 else u[:, k])
        recs.append(np.column_stack([u, y + 0.01 * rng.standard_normal(samples)]))
    return recs


def test_multi_within_one_evaluation():
    """Within one evaluation of the multi fit (two records of 10^5 samples at order 16: each record's
    filters, free-response basis by four columns, its QR and projections, then the stacked QR, each
    counted as a solve; the cost of the first start value alone is 16 of them): SIGINT at a random 1..16th
    solve, inside the first evaluation: KeyboardInterrupt within 8 more solves (the token asks every
    20 ms), no iteration begun, and a small fit afterwards gives the bits it gave before."""
    import json
    small = multi_records(1, 3000, 7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        before = msid.fit(small, method="multi", order=4, n_inputs=1)
    recs = multi_records(2, 100000, 2)
    it0 = ext._progress()["iterations"]
    with SigintAtCheckpoint("solves", RNG.randint(1, 16)) as s, pytest.raises(KeyboardInterrupt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            msid.fit(recs, method="multi", order=16, n_inputs=1)
    got = s.done()
    assert s.target <= got <= s.target + 8, (s.target, got)
    assert ext._progress()["iterations"] == it0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        after = msid.fit(small, method="multi", order=4, n_inputs=1)
    assert json.dumps(after.doc, sort_keys=True) == json.dumps(before.doc, sort_keys=True)


def test_multi_stacked_least_squares():
    """The stacked least squares of the multi fit's evaluation (the column-pivoting QR of every record's
    projected rows, then the linear parameters and the basis of its columns: seconds of Eigen's work
    without a checkpoint inside; here two records of 10^5 samples, four inputs at order 16, a stack of
    2 x 10^5 rows by 68 columns) counts one solve when it begins and one when it is done. SIGINT once it
    began (the 15th solve of the call: each record counts 3 + 16/4 before it, the Prony start none):
    KeyboardInterrupt with no further solve counted, the step abandoned on its thread instead of run to
    its end (where its end was counted before the interrupt landed), and a small fit afterwards, while
    the abandoned step may still run, gives the bits it gave before."""
    import json
    small = multi_records(1, 3000, 7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        before = msid.fit(small, method="multi", order=4, n_inputs=1)
    recs = multi_records(2, 100000, 3, n_inputs=4)
    begun = 2 * (3 + 16 // 4) + 1
    s = SigintAt("solves", begun)
    with pytest.raises(KeyboardInterrupt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            msid.fit(recs, method="multi", order=16, n_inputs=4, start="prony")
    s.t.join()
    assert s.at == begun and s.done() == begun, (begun, s.at, s.done())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        after = msid.fit(small, method="multi", order=4, n_inputs=1)
    assert json.dumps(after.doc, sort_keys=True) == json.dumps(before.doc, sort_keys=True)


def test_validate_at_high_order():
    """msid.validate of an order-200 model on 1000 lines (a solve of order 200 per line: seconds): SIGINT
    after a random 50..500 lines, KeyboardInterrupt within a tenth of the lines."""
    from msid.files import Model
    n = 200
    d, rec = periodic_record(4096, "1:1000", 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d, skip_periods=1)
    rng = np.random.default_rng(4)
    A = np.zeros((n, n))
    for k, th in enumerate(np.linspace(0.01, 3.1, n // 2)):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = 0.9 * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    doc = {"format": "msid-model/1", "source": "", "domain": "dt", "sample_time": f.sample_time or 1.0,
           "method": "external", "settings": {"weight": "cov"}, "order": n, "n_inputs": 1, "n_outputs": 1,
           "A": (Q @ A @ Q.T).tolist(), "B": rng.standard_normal((n, 1)).tolist(),
           "C": rng.standard_normal((1, n)).tolist(), "D": [[0.5]], "n_params": 0, "stable": True,
           "stability": {"stable": True, "enforced": False, "max_abs_pole": 0.9}}
    s = SigintAt("lines", RNG.randint(50, 500))
    with pytest.raises(KeyboardInterrupt):
        msid.validate(Model(doc), f)
    s.t.join()
    assert s.at is not None and s.done() - s.at <= 100 and s.done() < 1000, (s.at, s.done())


def quiet_fit(*args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return msid.fit(*args, **kw)


def counted(step, call):
    """`call`'s result and the units of `step` its checkpoints counted."""
    base = ext._progress()[step]
    r = call()
    return r, ext._progress()[step] - base


def test_ml_starts(scan_frf):
    """msid.fit(method="ml", param="poles") tries several starts (vector fitting, its relaxed form, the
    subspace models), each with its cost at its poles and some LM iterations, before the best one
    continues. Each start counts a solve when it begins, after the subspace fit's solves and before the
    fit's covariance (two: abandonable); the negative control counts them (one per start in `starts`).
    SIGINT as the first start begins, then as a random later one begins: KeyboardInterrupt there, with the
    earlier starts' iterations done (at least one each) and the model never evaluated at the lines (the
    fit's end); the same fit afterwards gives the bits it gave before."""
    kw = dict(method="ml", order=8, param="poles")
    before, total = counted("solves", lambda: quiet_fit(scan_frf, **kw))
    n_starts = len(before.doc["starts"])
    assert n_starts >= 3, before.doc["starts"]
    first = total - 2 - n_starts   # the solves before the first start: the subspace fit's
    assert first > 0, (total, n_starts)
    lines0 = ext._progress()["lines"]
    iters = []
    for k in (1, RNG.randint(2, n_starts)):
        it0 = ext._progress()["iterations"]
        with SigintAtCheckpoint("solves", first + k) as s, pytest.raises(KeyboardInterrupt):
            quiet_fit(scan_frf, **kw)
        assert s.done() == s.target and ext._progress()["lines"] == lines0, (k, s.target, s.done(), total)
        iters.append((k, ext._progress()["iterations"] - it0))
    (_, i1), (k, ik) = iters
    assert ik >= i1 + k - 1, iters
    after = quiet_fit(scan_frf, **kw)
    assert after.doc == before.doc


@pytest.mark.parametrize("param", ["poles", "lmfd"])
def test_ml_model_covariance(scan_frf, param):
    """The end of msid.fit(method="ml") in both parametrisations: the model's FRF and its covariance at
    each of the 300 lines (parameters^2 per entry and line: seconds at high orders on thousands of lines),
    counted per line after the Fisher covariance (abandonable). The negative control counts every line
    once, and them only. SIGINT at a random line of it: KeyboardInterrupt there, nothing returned, and
    the same fit afterwards gives the bits it gave before."""
    kw = dict(method="ml", order=8, param=param)
    before, total = counted("lines", lambda: quiet_fit(scan_frf, **kw))
    assert total == scan_frf.n_lines == 300, total
    out = None
    with SigintAtCheckpoint("lines", RNG.randint(1, total - 1)) as s, pytest.raises(KeyboardInterrupt):
        out = quiet_fit(scan_frf, **kw)
    assert out is None and s.done() == s.target, (s.target, s.done())
    after = quiet_fit(scan_frf, **kw)
    assert after.doc == before.doc


def test_multi_covariance():
    """The multi fit's covariance at its end: the normal matrix of the full Jacobian (every sample's rows
    by the parameters; here a record of 2 x 10^4 samples, four inputs at order 16: 80 parameters), made in
    blocks of 8 of its columns from 4096 rows on, a solve counted before each: 10 solves after those of the
    last evaluation. The negative control: the same fit (no iteration: the start, its Jacobian, the model's
    evaluation and covariance) counts 10 solves more than on the record's first 4000 samples (one product).
    SIGINT at a random block but the first: KeyboardInterrupt there, nothing returned, and the same fit
    afterwards gives the bits it gave before (each block is the one product's columns, entry for entry)."""
    recs = multi_records(1, 20000, 3, n_inputs=4)
    kw = dict(method="multi", order=16, n_inputs=4, start="prony", max_iter=0)
    before, total = counted("solves", lambda: quiet_fit(recs, **kw))
    _, short = counted("solves", lambda: quiet_fit([recs[0][:4000]], **kw))
    assert len(before.doc["parameters"]["names"]) == 80, before.doc["parameters"]["names"]
    blocks = 10
    assert total - short == blocks, (total, short)
    out = None
    with SigintAtCheckpoint("solves", total - blocks + RNG.randint(2, blocks)) as s, pytest.raises(KeyboardInterrupt):
        out = quiet_fit(recs, **kw)
    assert out is None and s.done() == s.target, (s.target, s.done(), total)
    after = quiet_fit(recs, **kw)
    assert after.doc == before.doc
