"""Soak with faults: msid-devsim -> Modbus TCP on 127.0.0.1 -> the daq adapter
(`msid modbus measure`) -> the core, round after round, each round with random faults drawn from a
fixed seed: busy exceptions, delayed replies, dropped connections, stalls that overrun the ring,
device restarts, garbage transaction ids, truncated, oversized and slow-drip replies.

Per round it asserts
  * no crash and no hang: the host exits 0 (a timeout far beyond the round's work is only a hang
    detector; nothing asserts how long anything took);
  * memory: the host's anonymous RSS (RssAnon), read from /proc/PID/status while it runs, does not grow from the first
    half of the run to the second (the measurement's memory is fixed at set-up: `--transient off`
    keeps no period history), and its VmHWM stays under a fixed bound; the same for the device;
  * every injected fault accounted for: the device's report against the host's counters, exactly;
  * no corrupted period used: a round whose faults cost no sample gives an FRF bit-identical to the
    honest device's; a round with an overrun declares exactly the samples the device overwrote, and
    its FRF is statistically consistent with the truth (the rows inside their 95% regions follow
    Bin(N, 0.95): canlib.check_coverage).

The work is bounded by samples (MSID_SOAK_PERIODS periods per experiment and round); the time
budget (MSID_SOAK_SECONDS, default 60) only decides how many rounds start. MSID_SOAK_SEED picks the
faults. The 30-minute run of docs/reliability.md: MSID_SOAK_SECONDS=1800 MSID_SOAK_PERIODS=400."""
import json
import os
import random
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "modbus"))
import mblib as c  # noqa: E402

BUDGET = float(os.environ.get("MSID_SOAK_SECONDS", "60"))
K = int(os.environ.get("MSID_SOAK_PERIODS", "16"))
SEED = int(os.environ.get("MSID_SOAK_SEED", "15"))
P = 256
RING = 512                     # a small ring, so that a stall overruns it
LINK = ("--response-timeout", 3000, "--byte-timeout", 1000, "--transient", "off")
HWM_HOST_MB = 64               # the host's peak RSS bound (measured ~12 MB: docs/reliability.md)
HWM_DEVICE_MB = 80             # the device: a fixed 48 MB arena, touched as used
GROWTH_KB = 512                # RSS growth allowed from the first half of a run to the second


def rss_kb(pid):
    """(RssAnon, VmHWM) in kB of a running process, or None once it is gone. Growth is judged on the
    anonymous memory (heap, stacks, mappings): VmRSS also counts the binary's code pages, faulted in the
    first time a code path runs (an experiment's end, a restart), which is not a leak."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    v = {l.split(":")[0]: int(l.split()[1]) for l in text.splitlines() if l.startswith(("RssAnon", "VmHWM"))}
    return (v["RssAnon"], v["VmHWM"]) if len(v) == 2 else None


class Samples(list):
    """(RssAnon, VmHWM) samples of one process; acq_end: the index of the first sample that may have been
    taken after the host logged that its last experiment has all its periods or is done (the sample just
    before the log read that found the line; None if the host never logged it): acquisition
    ends there, and closing it, the final solve and the JSON allocate what they need (not a leak; the
    30-minute CAN soak saw 684 kB appear there, in a TCG VM slow enough to log it before "done")."""
    acq_end = None


# the last experiment has all its periods (its closing allocates what the FRF needs), or is done
ACQ_DONE = re.compile(r"experiment (\d+)/\1(: (\d+)/\3 periods acquired| done)")


def watch(p, other_pid, hang_s, what, log=None):
    """Sample (RssAnon, VmHWM) of p and of other_pid every 0.1 s until p exits; after hang_s seconds p is
    killed and the test fails (a hang detector with a generous margin, never a timing assertion). With
    `log` (the host's output file) the samples of p note where acquisition ended (Samples.acq_end)."""
    mine, other, limit = Samples(), Samples(), time.monotonic() + hang_s
    while p.poll() is None:
        for pid, out in ((p.pid, mine), (other_pid, other)):
            v = rss_kb(pid)
            if v:
                out.append(v)
        # the log is read after the sample: if it shows the end now, the sample just taken may already
        # be past it (the process printed the line, then allocated, then was sampled: the 30-minute CAN
        # soak failed on one such sample, RssAnon 1156 -> 1820 kB), so it counts as after the end. Every
        # sample before it was followed by a read of the log that did not show the end yet.
        if log is not None and mine.acq_end is None and ACQ_DONE.search(Path(log).read_text(errors="replace")):
            mine.acq_end = max(len(mine) - 1, 0)
        if time.monotonic() > limit:
            p.kill()
            pytest.fail(f"{what} hung")
        time.sleep(0.1)
    return mine, other


def draw_faults(rng, n_total):
    """2 to 4 fault modes, positions and periods from rng; `n_total` samples per experiment."""
    at = lambda: f"{rng.randrange(2)}:{rng.randrange(P, n_total - P)}"  # noqa: E731
    menu = {
        "exceptions": lambda: ["--exception-every", rng.randrange(40, 160)],
        "delays": lambda: ["--delay-every", f"{rng.randrange(40, 160)}:{rng.randrange(20, 400)}"],
        "drop": lambda: ["--drop-at", at()],
        "stall": lambda: ["--stall-at", f"{at()}:{rng.randrange(RING + 50, 3 * RING)}:{rng.randrange(50, 400)}"],
        "restart": lambda: ["--restart-at", at()],
        # a foreign transaction id costs a response timeout (the reader skips it and waits for the real
        # reply, which never comes): as rare as the truncated replies, which cost the same
        "garbage_tid": lambda: ["--garbage-tid-every", rng.randrange(60, 200)],
        "truncate": lambda: ["--truncate-every", rng.randrange(60, 200)],
        "oversize": lambda: ["--oversize-every", rng.randrange(30, 120)],
        "drip": lambda: ["--drip-every", f"{rng.randrange(60, 200)}:{rng.randrange(1, 3)}"],
    }
    names = rng.sample(sorted(menu), rng.randrange(2, 5))
    return names, [str(x) for n in names for x in menu[n]()]


def run_round(tmp, design, sim_args):
    """One device, one `msid modbus measure`; RSS sampled while it runs. Returns (doc, report,
    truth, host samples, device samples, stderr)."""
    with c.Sim(tmp, "--seed", 4, "--ring", RING, *sim_args) as sim:
        out = Path(tmp) / "frf.json"
        cmd = [c.MSID, "modbus", "measure", *sim.link, "--design", str(design), "--skip-periods", "1",
               *map(str, LINK), "-o", str(out)]
        # the host's output goes to a file: a pipe read only after exit filled up with the progress lines
        # of a 400-period round (64 kB) and blocked the host in write() (the first 30-minute run of the
        # MBAP reader hung there)
        log = Path(tmp) / "host.log"
        with open(log, "w") as f:
            p = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, text=True)
        host, dev = watch(p, sim.p.pid, 600 + 0.05 * K * P, f"msid modbus measure (faults {sim_args})", log)
        p.wait()
        err = log.read_text()
        assert p.returncode == 0, f"faults {sim_args}: exit {p.returncode}: {err}"
        doc = json.loads(out.read_text())
    return doc, sim.report(), sim.truth(), host, dev, err


def settled_rss(samples, settled=0.25):
    """The highest RssAnon (kB) from the first `settled` fraction of the samples to the 90% mark: the level a
    round's process reached once set up."""
    q, end = int(settled * len(samples)), (9 * len(samples)) // 10
    if getattr(samples, "acq_end", None) and samples.acq_end > q + 1:
        end = samples.acq_end
    return max(s[0] for s in samples[q + 1:end]) if end > q + 1 else max(s[0] for s in samples)


def check_memory(samples, hwm_mb, what, settled=0.25, ref_kb=0):
    """VmHWM under hwm_mb; RssAnon may not grow from the first `settled` fraction of the samples (set-up)
    to the 90% mark (or to the end of acquisition, Samples.acq_end) by more than GROWTH_KB above the higher of that early level and ref_kb (the settled
    level of the honest round, settled_rss: a round whose faults stretch its first experiment touches
    the second experiment's state late, and only growth beyond what the honest run needs is a leak)."""
    assert samples, f"{what}: no RSS sample taken"
    assert samples[-1][1] <= hwm_mb * 1024, f"{what}: VmHWM {samples[-1][1]} kB above {hwm_mb} MB"
    if len(samples) >= 8:
        # growth from the first quarter of the samples to the 90% mark: a leak grows with the work done;
        # set-up, the first touch of the second experiment's state and the final FRF and JSON (the last
        # samples) do not (the first 30-minute run failed on 528 kB of growth between the halves of a round)
        q, end = int(settled * len(samples)), (9 * len(samples)) // 10
        if getattr(samples, "acq_end", None) and samples.acq_end > q + 1:
            end = samples.acq_end   # up to the end of acquisition, where the FRF and its file are built
        first, later = max(max(s[0] for s in samples[:q + 1]), ref_kb), max(s[0] for s in samples[q + 1:end])
        assert later - first <= GROWTH_KB, f"{what}: RssAnon grew {later - first} kB during the run"


def check_accounting(doc, rep, names, sim_args):
    """Every fault the device injected is in the host's counters (exact equations)."""
    a, inj, adv = doc["acquisition"], rep["injected"], rep["adversarial"]
    why = f"faults {sim_args}: host {a}, device {rep}"
    assert a["exceptions"] == inj["exceptions"], why
    # an oversized reply: read whole and rejected (bad reply), or beyond the MBAP length limit (malformed)
    assert a["bad_replies"] + a["malformed_frames"] == adv["oversized"], why
    # With 3 s response timeouts, a timeout is a truncated reply or a request the stalled device left
    # unanswered -- or a reply lost with a dropped connection (the 30-minute soak found it): the device
    # sent it and marked its ring slots read, so it may overwrite them without counting an overrun,
    # while the host times out once and finds newer tags there: it declares those samples missing (at
    # most one read's worth per drop). The host is right (tags prove every sample it used); the
    # device's count cannot know what the link lost.
    # A reply with a foreign transaction id is skipped and counted; the real reply never comes: one
    # timeout each (a foreign reply lost with a dropped connection is neither skipped nor timed out).
    drops, per_read = inj["dropped"], 125 // a["sample_regs"]
    assert 0 <= adv["garbage_tid"] - a["skipped_replies"] <= drops, why
    assert 0 <= a["timeouts"] - adv["truncated"] - rep["unanswered"] - a["skipped_replies"] <= drops, why
    assert a["io_errors"] >= drops, why
    assert a["reconnects"] == a["timeouts"] + a["io_errors"] + a["malformed_frames"], why
    assert a["device_restarts"] == inj["restarts"], why
    assert a["samples_lost"] == a["overrun_samples"] and a["device_overruns"] == rep["overrun_samples"], why
    assert 0 <= a["samples_lost"] - rep["overrun_samples"] <= drops * per_read, why
    assert 0 <= a["overrun_events"] - len(rep["overrun_ranges"]) <= drops, why
    assert a["crc_errors"] == 0 and rep["experiments_done"] == 2, why
    for n, key in (("exceptions", inj["exceptions"]), ("delays", inj["delayed"]), ("drop", inj["dropped"]),
                   ("stall", inj["stalls"]), ("restart", inj["restarts"]), ("garbage_tid", adv["garbage_tid"]),
                   ("truncate", adv["truncated"]), ("oversize", adv["oversized"]), ("drip", adv["dripped"])):
        if n in names:
            assert key >= 1, f"{n} drawn but never injected: {why}"


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("design"), period=P, lines="1:3:100", periods=K)


def test_soak_modbus_tcp(design, tmp_path):
    rng = random.Random(SEED)
    (tmp_path / "honest").mkdir()
    ref, rep0, truth, host, dev, _ = run_round(tmp_path / "honest", design, [])
    check_memory(host, HWM_HOST_MB, "host (honest)")
    check_accounting(ref, rep0, [], [])
    c.check_coverage(ref, truth)
    t0, rounds, summary = time.monotonic(), 0, []
    while rounds < 2 or time.monotonic() - t0 < BUDGET:
        names, args = draw_faults(rng, K * P)
        tmp = tmp_path / f"round{rounds}"
        tmp.mkdir()
        doc, rep, truth, host, dev, err = run_round(tmp, design, args)
        check_memory(host, HWM_HOST_MB, f"host, faults {args}")
        check_memory(dev, HWM_DEVICE_MB, f"device, faults {args}")
        check_accounting(doc, rep, names, args)
        if doc["acquisition"]["samples_lost"] == 0 and doc["acquisition"]["device_restarts"] == 0:
            assert c.frf_equal(doc, ref), f"faults {args} cost no sample but changed the FRF"
        else:
            c.check_coverage(doc, truth)
            assert doc["periods_rejected"] >= (1 if doc["acquisition"]["samples_lost"] else 0)
        a = doc["acquisition"]
        summary.append(f"round {rounds}: {' '.join(args)}: requests {a['requests']}, retries {a['retries']}, "
                       f"timeouts {a['timeouts']}, bad replies {a['bad_replies']}, skipped {a['skipped_replies']}, "
                       f"malformed {a['malformed_frames']}, exceptions {a['exceptions']}, "
                       f"lost {a['samples_lost']}, restarts {a['device_restarts']}, host HWM {host[-1][1]} kB")
        rounds += 1
    print(f"\nsoak: seed {SEED}, {rounds} rounds of 2 x {K} x {P} samples in {time.monotonic() - t0:.0f} s")
    print("\n".join(summary))


def test_negative_control_accounting_sees_a_missing_count(design, tmp_path):
    """check_accounting is not vacuous: a host counter off by one fails it."""
    doc = json.loads(json.dumps({"acquisition": {"exceptions": 1, "bad_replies": 0, "timeouts": 0, "io_errors": 0,
                                                 "skipped_replies": 0, "malformed_frames": 0,
                                                 "sample_regs": 5,
                                                 "reconnects": 0, "device_restarts": 0, "samples_lost": 0,
                                                 "overrun_samples": 0, "device_overruns": 0, "overrun_events": 0,
                                                 "crc_errors": 0}}))
    rep = {"injected": {"exceptions": 2, "delayed": 0, "dropped": 0, "stalls": 0, "restarts": 0},
           "adversarial": {"garbage_tid": 0, "oversized": 0, "truncated": 0, "dripped": 0},
           "unanswered": 0, "overrun_samples": 0, "overrun_ranges": [], "experiments_done": 2}
    with pytest.raises(AssertionError):
        check_accounting(doc, rep, ["exceptions"], [])
    rep["injected"]["exceptions"] = 1
    check_accounting(doc, rep, ["exceptions"], [])
    # a foreign reply the host did not skip (or skipped without the timeout it costs) fails it too
    rep["adversarial"]["garbage_tid"] = 2
    doc["acquisition"].update(skipped_replies=1, timeouts=1, reconnects=1)
    with pytest.raises(AssertionError):
        check_accounting(doc, rep, ["exceptions", "garbage_tid"], [])
    doc["acquisition"].update(skipped_replies=2, timeouts=2, reconnects=2)
    check_accounting(doc, rep, ["exceptions", "garbage_tid"], [])


def test_check_memory_tells_a_leak_from_a_late_first_touch():
    """The memory check on synthetic RSS traces (kB): a process that settles late at the honest round's level
    passes; the same trace beyond that level by more than GROWTH_KB, and a steady leak, fail."""
    flat = [(6000, 6000)] * 100
    late = [(4900, 4900)] * 55 + [(6064, 6064)] * 45           # the CAN soak round that first failed
    check_memory(flat, 64, "flat")
    check_memory(late, 64, "late first touch", settled=0.5, ref_kb=settled_rss(flat, settled=0.5))
    with pytest.raises(AssertionError, match="grew"):
        check_memory(late, 64, "late, no reference", settled=0.5)
    beyond = [(4900, 4900)] * 55 + [(6000 + GROWTH_KB + 100, 7000)] * 45
    with pytest.raises(AssertionError, match="grew"):
        check_memory(beyond, 64, "beyond the reference", settled=0.5, ref_kb=6000)
    final = Samples([(1150, 1150)] * 80 + [(1840, 1840)] * 20)   # the final FRF and JSON after acquisition
    with pytest.raises(AssertionError, match="grew"):
        check_memory(final, 64, "final phase, end unknown", settled=0.5)
    final.acq_end = 79
    check_memory(final, 64, "final phase after acquisition", settled=0.5)
    final.acq_end = 90                                             # growth before the end of acquisition
    with pytest.raises(AssertionError, match="grew"):
        check_memory(final, 64, "growth during acquisition", settled=0.5)
    leak = [(5000 + 20 * i, 5000 + 20 * i) for i in range(100)]   # 20 kB per sample
    with pytest.raises(AssertionError, match="grew"):
        check_memory(leak, 64, "leak", ref_kb=6000)


def test_watch_ends_acquisition_before_a_sample_that_may_follow_the_log_line(tmp_path):
    """A process that logs the end of acquisition and right after allocates (as `msid ... measure` closes
    its last experiment): no sample before Samples.acq_end may hold that allocation, however the 0.1 s
    sampling falls. The rule of the first 30-minute CAN soak counted the sample taken just before the
    log read that found the line, and with it 664 kB of the final phase as growth."""
    log = tmp_path / "host.log"
    child = ("import sys, time\n"
             "time.sleep(0.6)\n"
             "f = open(sys.argv[1], 'a'); f.write('msid can: experiment 2/2 done\\n'); f.flush()\n"
             "big = b'\\x01' * (48 << 20)\n"   # written, so resident at once
             "time.sleep(0.6)\n")
    for _ in range(3):
        log.write_text("msid can: experiment 2/2: 31/32 periods acquired\n")
        with open(tmp_path / "out", "w") as f:
            p = subprocess.Popen([sys.executable, "-c", child, str(log)], stdout=f, stderr=subprocess.STDOUT)
        mine, _ = watch(p, p.pid, 60, "child", log)
        assert p.wait() == 0
        assert mine.acq_end is not None and mine.acq_end >= 2, f"end not found: {mine.acq_end} of {len(mine)}"
        during = max(s[0] for s in mine[:mine.acq_end])
        after = max(s[0] for s in mine[mine.acq_end:])
        assert after - during > 40 << 10, f"the allocation was not seen after the end: {during} -> {after} kB"
        assert during < 40 << 10, f"a sample before acq_end holds the final allocation: {during} kB"
