"""Duplicated and replayed DONE frames on CAN (the adversarial device), through `msid can
replay` of msid-can/1 logs written here frame by frame (no CAN kernel needed; the live path shares
the decoder, and msid-devsim has the same faults live: --done-twice, --replay-done-at E:N). The run
either ends with the honest log's FRF or with one clear error; never an FRF from corrupted data."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_can_host import _hostile_log, c, write_log  # noqa: E402

P, K = 64, 4


def replay(tmp, name):
    r = c.run("can", "replay", "--log", tmp / f"{name}.log", "--skip-periods", 1, "-o", tmp / f"{name}.json")
    r.doc = json.loads((tmp / f"{name}.json").read_text()) if r.returncode == 0 else None
    return r


def variant(tmp, name, edit):
    """The honest log with `edit(lines, done_line, first_sample_line)` applied."""
    lines = (tmp / "ok.log").read_text().splitlines()
    done = lines[-1]
    first = next(i for i, l in enumerate(lines) if " 220#" in l)
    write_log(tmp / f"{name}.log", edit(list(lines), done, first))


def honest(tmp):
    _hostile_log(tmp / "ok.log", periods=K, P=P)
    r = replay(tmp, "ok")
    assert r.returncode == 0, r.stderr
    return r.doc


def test_duplicated_done_is_harmless(tmp_path):
    """DONE sent twice (a retransmission): the second one is ignored, the FRF is the honest one."""
    ok = honest(tmp_path)
    variant(tmp_path, "twice", lambda L, d, f: L + [d])
    r = replay(tmp_path, "twice")
    assert r.returncode == 0, r.stderr
    assert r.doc["lines"] == ok["lines"] and r.doc["acquisition"]["samples_lost"] == 0


def test_done_replayed_mid_experiment(tmp_path):
    """The experiment's DONE frame replayed after 2 of its K periods (a stale frame from an earlier run of
    the same experiment): the run must not close the experiment on it with half the data unnoticed. It
    either ignores the replay (the honest FRF) or ends with one clear error and nothing written."""
    ok = honest(tmp_path)
    at = lambda f: f + 2 * 2 * P  # noqa: E731  (2 frames per sample)
    variant(tmp_path, "replayed", lambda L, d, f: L[:at(f)] + [d] + L[at(f):])
    r = replay(tmp_path, "replayed")
    if r.returncode == 0:
        assert r.doc["lines"] == ok["lines"], "an FRF from a run closed early by a replayed DONE"
        assert r.doc["acquisition"]["samples_lost"] == 0
    else:
        c.fails(tmp_path, r, 1, absent=("replayed.json",))


def test_stale_done_with_a_smaller_count(tmp_path):
    """A replayed DONE that claims fewer samples than the design (P instead of K P) in the middle of the
    run: the same outcome as above, never an FRF from one period labelled complete."""
    ok = honest(tmp_path)

    def edit(L, d, f):
        stale = d[: d.index("#") + 1] + "00040000" + (P).to_bytes(4, "little").hex().upper()
        return L[:f + 3 * 2 * P] + [stale] + L[f + 3 * 2 * P:]

    variant(tmp_path, "stale", edit)
    r = replay(tmp_path, "stale")
    if r.returncode == 0:
        assert r.doc["lines"] == ok["lines"]
    else:
        c.fails(tmp_path, r, 1, absent=("stale.json",))


def test_negative_control_a_lost_sample_frame_changes_the_result(tmp_path):
    """The comparisons above can fail: dropping one sample frame changes the counts."""
    ok = honest(tmp_path)
    variant(tmp_path, "lossy", lambda L, d, f: L[:f + 200] + L[f + 201:])
    r = replay(tmp_path, "lossy")
    assert r.returncode == 0, r.stderr
    assert r.doc["acquisition"]["samples_lost"] >= 1 or r.doc["lines"] != ok["lines"]
