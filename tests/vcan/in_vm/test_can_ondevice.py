"""msid-can/1 extension estimate/1 (docs/can-protocol.md, "On-device estimation"): python-can and
cantools (the repo's DBC) as an independent host. It uploads a design, asks the simulator to
estimate on the device (EST_CTRL SETUP), runs both experiments, sends SOLVE and rebuilds the result
block from the EST frames, bit for bit.

- estimate and stream: the device's G equals numpy's estimate from the very sample frames it sent
  (period means of the DFT at the lines, G = Ybar Ubar^-1) to 1e-9, and its counts and dof are the
  theory's; a 1% change of the samples is detected (negative control);
- estimate only, paced at 50 kHz with 4 channels (beyond any classic bus): no sample frame crosses
  the bus, and G lies within its regions of the truth;
- estimator memory too small: EST STATE error with msid_status 2 and both byte counts.
"""
import socket
import struct

import numpy as np
import pytest

import canlib as c
from test_peer import P, LINES, db, recv_until, send, state_is, upload  # noqa: F401  (db is a fixture)

K, SKIP, M, NU, NY = 6, 1, 2, 2, 2
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
SCALE = float(np.float32(0.001))


def device(tmp_path, *args):
    import can
    sim = c.Sim(tmp_path, "--noise-u", 0, "--seed", 4, *args).__enter__()
    bus = can.Bus(interface="socketcan", channel="vcan0", fd=True)
    bus.socket.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, 16 << 20)
    return sim, bus


def est_is(state):
    return lambda n, s: n == "MSID_EST" and s["mux"] == 0 and str(s["est_state"]) == state


def setup(bus, db, mode):
    for w, word in enumerate(struct.unpack("<II", struct.pack("<d", 0.01))):
        send(bus, db, "MSID_EST_CTRL", command="alpha", word=w, alpha_word=word)
    send(bus, db, "MSID_EST_CTRL", command="setup", mode=mode, transient=1, skip_periods=SKIP)
    got = recv_until(bus, db, lambda n, s: n == "MSID_EST" and s["mux"] == 4)   # STATE, NEED, HAVE, PERIODS
    return {s["mux"]: s for n, s, _ in got if n == "MSID_EST"}


def run(bus, db):
    """Both experiments; the sample rows [u1 u2 y1 y2] each experiment streamed (decoded from the raw int16)."""
    rows = []
    for e in range(M):
        send(bus, db, "MSID_CTRL", command="start", experiment=e, version=1, periods=0)
        got = recv_until(bus, db, state_is("done"), timeout=60)
        r = {}
        for n, s, msg in got:
            if n.startswith("MSID_S16_"):
                k = int(n.rsplit("_", 1)[1])
                r.setdefault(s["seq"], [None] * 4)[2 * k: 2 * k + 2] = [v * SCALE for v in struct.unpack("<hh", msg.data[4:8])]
        rows.append(np.array([r[n] for n in sorted(r)]) if r else np.zeros((0, 4)))
    return rows


def solve(bus, db):
    send(bus, db, "MSID_EST_CTRL", command="solve")
    seen = {"states": 0}
    def end(n, s):
        if n == "MSID_EST" and s["mux"] == 0:
            seen["states"] += 1
        return seen["states"] == 2 or (seen["states"] == 1 and str(s.get("est_state")) == "error")
    got = recv_until(bus, db, end, timeout=60)
    size = [s["doubles"] for n, s, _ in got if n == "MSID_EST" and s["mux"] == 3]
    state = [s for n, s, _ in got if n == "MSID_EST" and s["mux"] == 0][0]
    if not size:
        return state, None
    words = np.zeros((size[0], 2), dtype=np.uint64)
    have = np.zeros((size[0], 2), dtype=bool)
    for n, s, msg in got:
        if n == "MSID_EST" and s["mux"] in (16, 17):
            w = s["mux"] - 16
            words[s["index"], w] = s["high_word" if w else "low_word"]
            have[s["index"], w] = True
    assert have.all(), f"{(~have).sum()} words missing"
    vals = (words[:, 0] | (words[:, 1] << np.uint64(32))).view(np.float64)
    return state, vals


def layout(L):
    """msid_mb_est.h: 29 doubles per experiment, the noise covariance, then per line G, cov, dof, ..."""
    g = NU * NY
    lines = M * 29 + 2 * NY * NY
    per_line = 2 * g + 4 * g * g + 2 + 2 * NY * NY + NY + 3
    return lines, per_line, {"G": 0, "cov": 2 * g, "dof": 2 * g + 2 * g * g, "status": per_line - 1}


def device_G(vals, l):
    lines, per, off = layout(len(LINES))
    b = lines + l * per
    z = vals[b + off["G"]: b + off["G"] + 2 * NU * NY]
    return (z[0::2] + 1j * z[1::2]).reshape(NY, NU), vals[b + off["dof"]], vals[b + off["cov"]: b + off["cov"] + 2 * 16]


def numpy_G(rows):
    """Period means of the line DFT after SKIP periods, per experiment; G = Ybar Ubar^-1 (m = nu)."""
    U, Y = [], []
    for r in rows:
        X = np.fft.fft(r[SKIP * P:].reshape(-1, P, 4), axis=1)[:, LINES, :].mean(axis=0)   # [L, 4]
        U.append(X[:, :NU])
        Y.append(X[:, NU:])
    U, Y = np.stack(U, axis=2), np.stack(Y, axis=2)   # [L, nu|ny, m]
    return [Y[l] @ np.linalg.inv(U[l]) for l in range(len(LINES))]


def test_estimate_and_stream_equals_numpy(tmp_path, db):
    sim, bus = device(tmp_path)
    try:
        upload(bus, db, periods=K)
        recv_until(bus, db, state_is("configured"))
        st = setup(bus, db, mode=2)
        assert str(st[0]["est_state"]) == "accumulating" and st[0]["ext_version"] == 1
        assert st[1]["need_bytes"] <= st[2]["have_bytes"]
        rows = run(bus, db)
        state, vals = solve(bus, db)
    finally:
        bus.shutdown()
        sim.__exit__(None, None, None)
    assert str(state["est_state"]) == "ready", state
    assert all(r.shape == (K * P, 4) for r in rows)
    for e in range(M):
        x = vals[e * 29: e * 29 + 13]
        assert (x[0], x[1], x[6], x[11]) == (K, SKIP, K - SKIP, K * P)   # offered, skipped, used, samples
    ref = numpy_G(rows)
    for l in range(len(LINES)):
        G, dof, _ = device_G(vals, l)
        assert np.max(np.abs(G - ref[l])) <= 1e-9 * np.max(np.abs(ref[l])), (l, G, ref[l])
        assert dof == M * (K - SKIP - 1)
    # negative control: the same check on samples changed by 1% in one output fails
    bad = [r.copy() for r in rows]
    bad[0][:, 2] *= 1.01
    assert max(np.max(np.abs(device_G(vals, l)[0] - numpy_G(bad)[l])) for l in range(len(LINES))) > 1e-6


def test_estimate_only_sends_no_samples(tmp_path, db):
    """The device paced at 50 kHz with 4 channels: 100 000 classic sample frames/s (13.5 Mbit/s with
    stuffing) would not fit a 1 Mbit/s bus; estimating on the device, none is sent."""
    sim, bus = device(tmp_path)
    try:
        upload(bus, db, periods=K, rate=50000)
        recv_until(bus, db, state_is("configured"))
        assert str(setup(bus, db, mode=1)[0]["est_state"]) == "accumulating"
        rows = run(bus, db)
        state, vals = solve(bus, db)
        truth = sim.truth()
    finally:
        bus.shutdown()
        sim.__exit__(None, None, None)
    assert all(len(r) == 0 for r in rows)   # no sample frame crossed the bus
    assert str(state["est_state"]) == "ready"
    inside = 0
    for l, t in enumerate(truth["lines"]):
        G, dof, cov = device_G(vals, l)
        Gt = np.array(t["G"]["re"]) + 1j * np.array(t["G"]["im"])
        var = cov[0::2].reshape(4, 4).diagonal()   # vec index i + ny j
        for i in range(NY):
            for j in range(NU):
                inside += abs(G[i, j] - Gt[i, j]) ** 2 / var[i + NY * j] < 2 * 3.0   # generous: 6 sigma^2
    assert inside >= 0.9 * len(LINES) * NU * NY, inside


def test_estimator_memory_too_small(tmp_path, db):
    sim, bus = device(tmp_path, "--est-mem", 64)
    try:
        upload(bus, db, periods=K)
        recv_until(bus, db, state_is("configured"))
        st = setup(bus, db, mode=1)
    finally:
        bus.shutdown()
        sim.__exit__(None, None, None)
    assert str(st[0]["est_state"]) == "error" and st[0]["status"] == 2   # MSID_E_MEM_SIZE
    assert st[1]["need_bytes"] > 64 and st[2]["have_bytes"] == 64
