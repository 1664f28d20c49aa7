"""Host-only experiment (no CAN, no VM): how well msid frf's 95% regions cover msid-devsim's CANopen plant
(firmware_sim/sim_twomass.c, its default parameters; the node's TPDO pairing u[k] = tau[k-1], y[k] = omega[k]
+ noise, the bus's per mille and mrad/s steps) measured as `msid measure --map` does it: a random-phase
multisine on bins 1:2:31 of P = 64 samples, 0.2 N m peak, one period of raised-cosine fade-in from rest, then
PERIODS periods of which SKIP are skipped; each record estimated by `msid frf` (its transient and drift tests
on) and every line's p-value against the exact FRF z e2' (zI - A)^-1 B. It also prints the transient left in
the used periods (the noise-free response minus its periodic steady state) and how many runs msid flagged.

usage: MSID_BIN=build/tools/msid python3 scripts/co_transient_bias.py RATE NOISE SKIP PERIODS FADE B SEEDS
  (B: the viscous friction b_m = b_l, N m s/rad; 1e-4 is the node's, whose slow pole (b_m + b_l)/(J_m + J_l)
  has a time constant of 1.5 s). docs/devices.md, "Measuring a CiA 402 drive", has the figures."""
import json, os, subprocess, sys, tempfile
import numpy as np
import scipy.linalg, scipy.stats

MSID = os.environ["MSID_BIN"]
P, BINS = 64, list(range(1, 32, 2))

def plant_ab(ts, jm=1e-4, jl=2e-4, k=50.0, dmp=2e-3, bm=1e-4, bl=1e-4):
    f = np.array([[0, 1, 0, 0], [-k / jm, -(dmp + bm) / jm, k / jm, dmp / jm], [0, 0, 0, 1],
                  [k / jl, dmp / jl, -k / jl, -(dmp + bl) / jl]])
    m = np.zeros((5, 5)); m[:4, :4] = f; m[:4, 4] = [0, 1 / jm, 0, 0]
    e = scipy.linalg.expm(m * ts)
    return e[:4, :4], e[:4, 4]

def truth(A, b):
    C = np.array([0, 1.0, 0, 0])
    return np.array([np.exp(2j*np.pi*q/P) * C @ np.linalg.solve(np.exp(2j*np.pi*q/P)*np.eye(4) - A, b) for q in BINS])

def run(seed, rate, noise, skip, periods, fade, bm, tmp):
    rng = np.random.default_rng(seed)
    A, b = plant_ab(1.0/rate, bm=bm, bl=bm)
    ph = rng.uniform(0, 2*np.pi, len(BINS))
    n = np.arange(P)
    ms = sum(np.cos(2*np.pi*q*n/P + p) for q, p in zip(BINS, ph))
    ms *= 0.2 / np.max(np.abs(ms))
    N = (fade + periods) * P
    w = np.ones(N)
    if fade:
        w[:fade*P] = 0.5 - 0.5*np.cos(np.pi*np.arange(fade*P)/(fade*P))
    tau = np.round(np.tile(ms, fade + periods) * w * 1000) / 1000
    x = np.zeros(4); u = []; y = []
    prev = 0.0
    for k in range(N):
        u.append(prev); y.append(np.round((x[1] + noise*rng.standard_normal())*1000)/1000)
        x = A @ x + b * tau[k]; prev = tau[k]
    u = np.array(u[fade*P:]); y = np.array(y[fade*P:])
    csv = os.path.join(tmp, f"e{seed}.csv")
    np.savetxt(csv, np.c_[u, y], delimiter=",", header="u1,y1", comments="")
    out = os.path.join(tmp, f"f{seed}.json")
    r = subprocess.run([MSID, "frf", "--period", str(P), "--lines", "1:2:31", "--experiment", csv, "--skip-periods",
                        str(skip), "--transient", "flag", "-o", out], capture_output=True, text=True)
    if r.returncode: raise SystemExit(r.stderr)
    doc = json.load(open(out))
    G0 = truth(A, b)
    pv = []
    for line, g0 in zip(doc["lines"], G0):
        G = np.asarray(line["G"]["re"], float) + 1j*np.asarray(line["G"]["im"], float)
        V = np.asarray(line["cov"]["re"], float) + 1j*np.asarray(line["cov"]["im"], float)
        q = abs(G.ravel()[0] - g0)**2 / V.ravel()[0].real
        pv.append(scipy.stats.f.sf(q, 2, 2*line["dof"]))
    # the transient left in the used periods: the noise-free response minus its periodic steady state
    x = np.zeros(4); yy = []
    for k in range(N):
        yy.append(x[1]); x = A @ x + b * tau[k]
    yy = np.array(yy)
    ss = yy[-P:]   # (nearly) steady
    trans = yy[(fade + skip) * P:(fade + periods) * P] - np.tile(ss, periods - skip)
    doc["_trans_rms"] = float(np.sqrt(np.mean(trans**2))); doc["_trans_first"] = float(np.max(np.abs(trans[:P])))
    return np.array(pv), doc

if __name__ == "__main__":
    rate, noise, skip, periods, fade, bm, seeds = (float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]),
                                                  int(sys.argv[4]), int(sys.argv[5]), float(sys.argv[6]), int(sys.argv[7]))
    tmp = tempfile.mkdtemp(prefix="msid_co_bias_")
    allp, flagged, notes, tr, tf = [], 0, set(), [], []
    for s in range(1, seeds+1):
        pv, doc = run(s, rate, noise, skip, periods, fade, bm, tmp)
        allp.append(pv)
        e = doc["experiments"][0]
        if e["transient_flagged"] or e["drift"]: flagged += 1
        tr.append(doc["_trans_rms"]); tf.append(doc["_trans_first"])
    allp = np.concatenate(allp)
    inside = int(np.sum(allp > 0.05))
    lo = [int(np.sum(p > 0.05)) for p in np.split(allp, seeds)]
    print(f"rate {rate} noise {noise} skip {skip} periods {periods} fade {fade} bm {bm}: {inside}/{len(allp)} inside; "
          f"per-line inside over seeds: {np.sum(np.array(np.split(allp, seeds)) > 0.05, axis=0).tolist()}; "
          f"runs with a period flagged or drift: {flagged}/{seeds}; transient in the used periods: rms {np.median(tr):.3g}, "
          f"max in the first used period {np.median(tf):.3g} rad/s (medians); bins 1,3,5 inside: "
          f"{np.sum(np.array(np.split(allp, seeds))[:, :3] > 0.05, axis=0).tolist()} of {seeds}")
