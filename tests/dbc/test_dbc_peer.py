"""msid's DBC reader and codec against cantools (the pinned peer), on every signal of many DBC files.

For each file both read: the tables (identifier, length, cycle time; each signal's start, length,
byte order, sign, float type, factor, offset, range, unit, multiplexing) agree; every message's
frames, random payloads (fixed seeds) and edge payloads (all zeros, all ones, each signal at its sign
boundary, its most negative and its largest raw value), decoded by `msid can decode` (the command a
user runs) and by cantools, give the same signals present and the same values bit for bit; those
values encoded again by msid (tests/dbc/dbc_encode.c: no user command encodes) give cantools' bytes,
and each signal's physical minimum and maximum, and a value beyond its range, are encoded or refused
as cantools does. Files cantools cannot load are skipped and named; a file msid refuses must name a
feature msid does not read, or be one cantools reads only when not strict (a signal whose bits leave
its message); the reason is checked, and counts are printed (docs/can-protocol.md).
"""
import csv
import math
import os
import random
import subprocess
import zlib

import cantools
import pytest

from dbc_files import candump_line, corpora

MSID = os.environ.get("MSID_BIN", "msid")
ENCODE = os.environ.get("MSID_DBC_ENCODE", "dbc_encode")
RANDOM_PAYLOADS = 16
# what msid refuses to read, on purpose (msid_dbc.h): a refusal must name one of these
UNSUPPORTED = ("extended multiplexing",)


def load_cantools(path):
    """(cantools' database of a file, the same with its signals in file order, whether it loads strict,
    why not): strict first (signals inside their message, none overlapping), else not strict; (None,
    None, False, reason) when it cannot load it. The codec is the default load's (cantools builds its
    unpacking formats for signals sorted by start bit: a file-order load does not decode)."""
    why = None
    for strict in (True, False):
        try:
            db = cantools.database.load_file(str(path), database_format="dbc", strict=strict)
            in_order = cantools.database.load_file(str(path), database_format="dbc", strict=strict, sort_signals=None)
            return db, in_order, strict, why
        except Exception as e:  # noqa: BLE001 - any refusal of the peer skips the file
            why = f"{type(e).__name__}: {str(e)[:120]}"
    return None, None, False, why


def msid_tables(path):
    """msid's tables of a file ({(id, ext): (message fields, [signal fields])}), or its refusal."""
    r = subprocess.run([ENCODE, str(path), "--list"], capture_output=True, timeout=120)
    if r.returncode:
        return None, r.stderr.decode("utf-8", "replace").strip()
    msgs, cur = {}, None
    # names and units are the file's bytes: read as cantools reads DBC files (cp1252)
    for ln in r.stdout.decode("cp1252", "replace").splitlines():
        f = ln.split(" ")
        if f[0] == "M":
            ext = f[1].startswith("x")
            key = (int(f[1].lstrip("x"), 16), ext)
            cur = (dict(name=f[4], dlc=int(f[2]), cycle=int(f[3])), [])
            msgs[key] = cur
        else:
            name, start, length, order, sgn, typ, mux, muxv = f[1], *map(int, f[2:9])
            fac, off, lo, hi = (float.fromhex(x) for x in f[9:13])
            cur[1].append(dict(name=name, start=start, length=length, order=order, signed=sgn, type=typ, mux=mux,
                               muxv=muxv, factor=fac, offset=off, min=lo, max=hi, unit=" ".join(f[13:])))
    return msgs, None


def same_tables(path, db, in_order, tables):
    """The tables agree field by field (msid's signals against cantools' in file order); the name map
    (msid's signal name -> cantools' Signal of the codec's database) per message."""
    ct = {(m.frame_id, m.is_extended_frame): m for m in in_order.messages}
    codec = {(m.frame_id, m.is_extended_frame): m for m in db.messages}
    assert set(ct) == set(tables), f"{path.name}: messages {sorted(set(ct) ^ set(tables))} in one reader only"
    names = {}
    for key, (mm, sigs) in tables.items():
        m = ct[key]
        where = f"{path.name} {m.name}"
        assert mm["dlc"] == m.length, where
        assert mm["cycle"] == (m.cycle_time or 0), where
        assert len(sigs) == len(m.signals), where
        names[key] = {}
        for s, c in zip(sigs, m.signals):
            w = f"{where}.{c.name}"
            assert (s["start"], s["length"]) == (c.start, c.length), w
            assert s["order"] == (1 if c.byte_order == "little_endian" else 0), w
            assert bool(s["signed"]) == c.is_signed, w
            assert (s["type"] != 0) == c.is_float, w
            assert s["factor"] == c.scale and s["offset"] == c.offset, w
            if c.minimum is None:
                assert s["min"] == 0 and s["max"] == 0, w
            else:   # an exact Python integer beyond 2^53 is its nearest double in msid
                assert (s["min"], s["max"]) == (float(c.minimum), float(c.maximum)), w
            assert s["unit"] == (c.unit or ""), w
            assert (s["mux"] == 1) == c.is_multiplexer, w
            if s["mux"] == 2:
                assert c.multiplexer_ids == [s["muxv"]], w
            else:
                assert not c.multiplexer_ids, w
            names[key][s["name"]] = codec[key].get_signal_by_name(c.name)
    return names


def raw_payload(m, raws):
    """A payload with these raw values (cantools places them); the signals the branch needs default to 0."""
    raws = dict(raws)
    for _ in range(len(m.signals) + 2):
        try:
            return bytearray(m.encode(raws, scaling=False, strict=False, padding=False)).ljust(m.length, b"\0")
        except KeyError as e:
            raws[e.args[0]] = 0
        except Exception:  # noqa: BLE001 - a raw the peer cannot place: no such edge
            return None
    return None


def edge_payloads(m):
    """All zeros, all ones, and per integer signal: its sign boundary, most negative and largest raw value."""
    out = [bytearray(m.length), bytearray(b"\xff" * m.length)]
    for s in m.signals:
        if s.is_float or s.is_multiplexer:
            continue
        L = s.length
        raws = [-(1 << (L - 1)), (1 << (L - 1)) - 1, -1] if s.is_signed else [(1 << L) - 1, 1 << (L - 1)]
        base = {}
        if s.multiplexer_ids:
            base[s.multiplexer_signal] = s.multiplexer_ids[0]
        for r in raws:
            p = raw_payload(m, {**base, s.name: r})
            if p is not None:
                out.append(p)
    return out


def msid_decode(tmp_path, dbc, frames):
    """`msid can decode` of a log of these frames: per frame index, {signal: value}."""
    log, out = tmp_path / "peer.log", tmp_path / "peer.csv"
    t0 = 1700000000 * 1000000
    with open(log, "w") as f:
        for k, (m, data) in enumerate(frames):
            f.write(candump_line(t0 + k, m.frame_id, m.is_extended_frame, data, m.length > 8))
    r = subprocess.run([MSID, "can", "decode", "--dbc", str(dbc), str(log), "-o", str(out)], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    got = {}
    with open(out, newline="") as f:
        rd = csv.reader(f)
        assert next(rd) == ["time", "message", "signal", "value"]
        for t, _, sig, v in rd:
            sec, us = t.split(".")
            got.setdefault(int(sec) * 1000000 + int(us) - t0, {})[sig] = float(v)
    return got


def msid_encode(dbc, requests):
    """dbc_encode of [(message, start payload, [(signal, value)])]: [(payload, flags)]."""
    text = "".join(f"{m} {p.hex().upper()} " + " ".join(f"{s} {float(v).hex()}" for s, v in sv) + "\n"
                   for m, p, sv in requests)
    r = subprocess.run([ENCODE, str(dbc)], input=text, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = []
    for ln in r.stdout.splitlines():
        h, _, flags = ln.partition(" ")
        out.append((bytes.fromhex(h), flags))
    assert len(out) == len(requests)
    return out


def refuses_range(c, v):
    """cantools' range rule (message.py): outside [min, max] by more than |scale| 1e-6; msid checks only min < max."""
    if c.minimum is None or not c.minimum < c.maximum:
        return False
    tol = abs(c.scale) * 1e-6
    return v < c.minimum - tol or v > c.maximum + tol


def exact_int(c, v):
    """Can a double carry this value of an integer signal exactly (|v| < 2^53)?"""
    return c.is_float or not isinstance(v, int) or abs(v) < 2 ** 53


STATS = {"files": 0, "messages": 0, "signals": 0, "frames": 0, "values": 0, "encoded": 0, "edges": 0, "no_branch": 0, "peer_failed": 0, "peer_failed_msgs": set(),
         "skipped_cantools": [], "refused": []}


def compare_file(tmp_path, path, db, in_order, tables):
    names = same_tables(path, db, in_order, tables)
    rng = random.Random(zlib.crc32(path.name.encode()))
    frames = []
    for m in db.messages:
        if m.length == 0 or not m.signals:
            continue
        frames += [(m, p) for p in edge_payloads(m)]
        frames += [(m, bytearray(rng.getrandbits(8) for _ in range(m.length))) for _ in range(RANDOM_PAYLOADS)]
    got = msid_decode(tmp_path, path, frames)
    requests, expect = [], []
    for k, (m, data) in enumerate(frames):
        key = (m.frame_id, m.is_extended_frame)
        nm = names[key]
        ours = got.get(k, {})
        try:
            ct = m.decode(bytes(data), decode_choices=False, scaling=True)
        except cantools.database.DecodeError as e:
            if "expected multiplexer id" not in str(e):   # a float32 NaN; overlapping signals (not strict)
                STATS["peer_failed"] += 1
                STATS["peer_failed_msgs"].add((path.name, m.name))
                continue
            # a switch value no branch has: cantools refuses the frame, msid gives the switch and the
            # plain signals
            plain = {nm_s for nm_s, c in nm.items() if not c.multiplexer_ids}
            assert set(ours) == plain, f"{path.name} {m.name} payload {data.hex()}: {sorted(ours)} != {sorted(plain)}"
            STATS["no_branch"] += 1
            continue
        finite = {n: v for n, v in ct.items() if not (isinstance(v, float) and not math.isfinite(v))}
        back = {nm[n].name: v for n, v in ours.items()}
        assert set(back) == set(finite), f"{path.name} {m.name} payload {data.hex()}: signals differ"
        for n, v in finite.items():
            c = m.get_signal_by_name(n)
            if exact_int(c, v) or c.conversion.scale == 1 and c.conversion.offset == 0:
                assert back[n] == float(v), f"{path.name} {m.name}.{n} payload {data.hex()}: {back[n]!r} != {v!r}"
            else:   # beyond 2^53 cantools' exact integer and msid's double differ by the rounding of raw * factor
                assert math.isclose(back[n], float(v), rel_tol=4e-16), f"{path.name} {m.name}.{n}"
        STATS["values"] += len(finite)
        # encode the decoded values again into an all-ones payload (cantools pads with ones)
        if len(finite) == len(ct) and all(exact_int(m.get_signal_by_name(n), v) for n, v in ct.items()):
            msid_names = {c.name: s for s, c in nm.items()}
            requests.append((tables[key][0]["name"], bytearray(b"\xff" * m.length),
                             [(msid_names[n], v) for n, v in ct.items()]))
            expect.append((m, ct))
    # each signal's physical edges: its minimum, its maximum, and a value beyond the range
    for m in db.messages:
        key = (m.frame_id, m.is_extended_frame)
        if m.length == 0 or not m.signals:
            continue
        msid_names = {c.name: s for s, c in names[key].items()}
        for c in m.signals:
            if c.is_multiplexer or c.minimum is None or not c.minimum < c.maximum:
                continue
            base = {}
            if c.multiplexer_ids:
                base[c.multiplexer_signal] = c.multiplexer_ids[0]
            p = raw_payload(m, base)
            if p is None:
                continue
            try:
                vals = m.decode(bytes(p), decode_choices=False, scaling=True)
            except cantools.database.DecodeError:
                continue
            if c.name not in vals or any(not exact_int(m.get_signal_by_name(n), v) for n, v in vals.items()):
                continue
            for v in (c.minimum, c.maximum, c.maximum + 4 * abs(c.scale)):
                if not c.is_float and abs(v) >= 2 ** 53:
                    continue   # beyond a double's integers: msid's physical values are doubles (msid_dbc.h)
                vv = dict(vals)
                vv[c.name] = v
                requests.append((tables[key][0]["name"], bytearray(b"\xff" * m.length),
                                 [(msid_names[n], x) for n, x in vv.items()]))
                expect.append((m, vv))
                STATS["edges"] += 1
    for (m, vals), (payload, flags) in zip(expect, msid_encode(path, requests)):
        want_refused = []
        for n, v in vals.items():
            c = m.get_signal_by_name(n)
            want_refused.append(refuses_range(c, v))
        try:
            ref = m.encode(vals, scaling=True, strict=False, padding=True)
        except (OverflowError, ValueError):
            ref = None   # a raw that does not fit its bits: msid must refuse one of the signals
        where = f"{path.name} {m.name} {vals}"
        if ref is None:
            assert "R" in flags, f"{where}: cantools cannot place a raw value, msid encoded it ({flags})"
            continue
        assert [f == "R" for f in flags] == want_refused, f"{where}: refused {flags}, cantools' rule {want_refused}"
        if not any(want_refused):
            assert payload == ref, f"{where}: msid {payload.hex()} cantools {ref.hex()}"
            STATS["encoded"] += 1
    STATS["files"] += 1
    STATS["messages"] += len(db.messages)
    STATS["signals"] += sum(len(m.signals) for m in db.messages)
    STATS["frames"] += len(frames)


CORPORA = corpora()


@pytest.mark.parametrize("corpus,files", CORPORA, ids=[c for c, _ in CORPORA])
def test_codec_agrees_with_cantools(tmp_path, corpus, files):
    assert files, f"{corpus}: no DBC files"
    for k in STATS:
        STATS[k] = type(STATS[k])()
    for path in files:
        db, in_order, strict, why = load_cantools(path)
        if db is None:
            STATS["skipped_cantools"].append(f"{path.name} ({why})")
            continue
        tables, refusal = msid_tables(path)
        if tables is None:
            # a feature msid does not read, or a file cantools itself reads only when not strict
            # (a signal outside its message): msid refuses it, naming the line
            ok = any(u in refusal for u in UNSUPPORTED) or (not strict and "leave the" in refusal)
            assert ok, f"{path.name}: msid refuses a file cantools reads (strict={strict}): {refusal}"
            STATS["refused"].append(f"{path.name} ({refusal.split(': ', 1)[-1][:110]})")
            continue
        d = tmp_path / path.stem
        d.mkdir()
        compare_file(d, path, db, in_order, tables)
    print(f"\n{corpus}: {len(files)} files; compared {STATS['files']} ({STATS['messages']} messages, "
          f"{STATS['signals']} signals, {STATS['frames']} frames, {STATS['values']} values decoded, "
          f"{STATS['encoded']} payloads encoded, {STATS['edges']} range edges; {STATS['no_branch']} payloads "
          f"whose switch selects no branch: cantools refuses them, msid gives the switch and the plain signals; "
          f"{STATS['peer_failed']} payloads of {len(STATS['peer_failed_msgs'])} messages cantools cannot decode)")
    print(f"  cantools cannot load {len(STATS['skipped_cantools'])}: " + "; ".join(STATS["skipped_cantools"]))
    print(f"  msid refuses {len(STATS['refused'])}: " + "; ".join(STATS["refused"]))
    assert STATS["files"] >= 1
