"""A CiA 402 drive that is not msid's: the canopen package's LocalNode (its SDO server and NMT slave, the object
dictionary of data/drive402.eds) with a plant and a SYNC consumer written here, on vcan0, in the test's own
process. What it does, and nothing more:
- SDO: the LocalNode's server; every write lands in its own data store, where the tests read it back. A write of
  the controlword 0x6040 steps the CiA 402 state machine (switch on disabled, ready to switch on, switched on,
  operation enabled, quick stop active) and the statusword 0x6041 follows; the modes of operation 0x6060 take
  0 or 10 (CST: anything else is aborted with 0x06090030 value range) and show in 0x6061.
- PDOs: in NMT operational, the RPDOs and synchronous TPDOs (transmission type 1..240) as their communication
  and mapping parameters in the data store say (0x1400/0x1600, 0x1800/0x1A00: what msid wrote). On each SYNC,
  in the order of msid-devsim's node (docs/devices.md): (1) the TPDOs with the values held, (2) the targets of
  the RPDOs received since the last SYNC written to the store, (3) the demand and one step of the plant.
  So the TPDO of SYNC k carries the demand tau[k-1] and the state x[k].
- The plant: a motor and a load on a soft shaft (one lightly damped mode, about 7 Hz, zeta about 0.05),
  discretized here for a zero-order hold over the SYNC period 0x1006 by its own matrix exponential (Taylor
  series with scaling and squaring in numpy); the velocity 0x606C carries white noise of std `noise` rad/s.
  The demand is the target torque 0x6071 in "operation enabled" (per mille of the rated torque 0x6076), 0
  in every other state.
Bus units as msid-devsim's: torque per mille of 0x6076 (mN m), velocity mrad/s, position urad."""
import threading

import numpy as np

# mechanics (SI): motor and load inertia, shaft stiffness and damping, viscous friction of each
PARAMS = dict(jm=2e-4, jl=2e-4, k=0.2, d=4.5e-4, bm=4e-4, bl=4e-4)

STATES = {"switch on disabled": 0x0250, "ready to switch on": 0x0231, "switched on": 0x0233,
          "operation enabled": 0x0237, "quick stop active": 0x0217}


def continuous(jm, jl, k, d, bm, bl):
    """F, G of x = [theta_m, omega_m, theta_l, omega_l] driven by the motor torque."""
    F = np.array([[0, 1, 0, 0], [-k / jm, -(d + bm) / jm, k / jm, d / jm], [0, 0, 0, 1],
                  [k / jl, d / jl, -k / jl, -(d + bl) / jl]], dtype=float)
    G = np.array([0, 1 / jm, 0, 0], dtype=float)
    return F, G


def zoh(ts, params=PARAMS):
    """A, B of the step over ts: e^([F G; 0 0] ts) = [A B; 0 1], by 20 Taylor terms of the matrix scaled to
    norm <= 0.5 and squared back."""
    F, G = continuous(**params)
    M = np.zeros((5, 5))
    M[:4, :4], M[:4, 4] = F, G
    M *= ts
    s = max(0, int(np.ceil(np.log2(max(np.abs(M).sum(axis=1).max(), 1e-300) / 0.5))))
    Ms = M / 2.0 ** s
    E, term = np.eye(5), np.eye(5)
    for n in range(1, 21):
        term = term @ Ms / n
        E = E + term
    for _ in range(s):
        E = E @ E
    return E[:4, :4], E[:4, 4]


def u32(b):
    return int.from_bytes(b, "little")


class Drive402:
    """The LocalNode drive on `net` (a connected canopen.Network); `lock` guards its state against the test."""

    def __init__(self, net, node_id, eds, *, seed=1, noise=0.0):
        import canopen
        self.net, self.id = net, node_id
        self.node = canopen.LocalNode(node_id, str(eds))
        net.add_node(self.node)
        self.lock = threading.Lock()
        self.rng = np.random.default_rng(seed)
        self.noise = noise
        self.state = "switch on disabled"
        self.cw = 0
        self.x = np.zeros(4)
        self.tau_pm = 0
        self.ts = None
        self.A = self.B = None
        self.syncs = 0
        self.pending = {}
        self.tpdo_counts = [0] * 4
        self.node.add_write_callback(self._on_write)
        self._store(0x6041, 0, STATES[self.state])
        self._store(0x6061, 0, 0)
        for k in range(4):
            net.subscribe(self._rpdo_cob(k), self._on_rpdo)
        net.subscribe(0x80, self._on_sync)

    # ---- the object dictionary ----------------------------------------------------------------------------------
    def _var(self, index, sub):
        o = self.node.object_dictionary[index]
        return o if not hasattr(o, "subindices") else o[sub]

    def _store(self, index, sub, value):
        self.node.data_store.setdefault(index, {})[sub] = self._var(index, sub).encode_raw(value)

    def raw(self, index, sub=0):
        return self._var(index, sub).decode_raw(self.node.get_data(index, sub))

    def _on_write(self, index, subindex, od, data):
        from canopen.sdo import SdoAbortedError
        v = od.decode_raw(data)
        with self.lock:
            if index == 0x6040:
                self._controlword(v)
            elif index == 0x6060:
                if v not in (0, 10):
                    raise SdoAbortedError(0x06090030)
                self._store(0x6061, 0, v)
            elif index == 0x1006 and v:
                self.ts = v * 1e-6
                self.A, self.B = zoh(self.ts)

    def _controlword(self, cw):
        """CiA 402's transitions 2..12 and 16 (quick stop option code 6: quick stop active until disabled)."""
        s = self.state
        if cw & 0x02 == 0:
            s = "switch on disabled"
        elif cw & 0x06 == 0x02:
            s = "quick stop active" if s in ("operation enabled", "quick stop active") else "switch on disabled"
        elif cw & 0x87 == 0x06 and s != "quick stop active":
            s = "ready to switch on"
        elif cw & 0x8F == 0x07 and s in ("ready to switch on", "operation enabled"):
            s = "switched on"
        elif cw & 0x8F == 0x0F and s in ("ready to switch on", "switched on", "quick stop active"):
            s = "operation enabled"
        self.state, self.cw = s, cw
        self._store(0x6041, 0, STATES[s])

    # ---- PDOs -----------------------------------------------------------------------------------------------------
    def _rpdo_cob(self, k):
        return (0x200 + 0x100 * k) + self.id

    def _mapping(self, index):
        n = self.raw(index, 0)
        out = []
        for i in range(1, n + 1):
            m = self.raw(index, i)
            out.append(((m >> 16) & 0xFFFF, (m >> 8) & 0xFF, m & 0xFF))
        return out

    def _valid(self, comm):
        cob = self.raw(comm, 1)
        return (cob & 0x80000000) == 0, cob & 0x7FF

    def _on_rpdo(self, cob_id, data, timestamp):
        with self.lock:
            for k in range(4):
                ok, cob = self._valid(0x1400 + k)
                if ok and cob == cob_id:
                    self.pending[k] = bytes(data)

    def _apply_rpdo(self, k, data):
        off = 0
        for index, sub, bits in self._mapping(0x1600 + k):
            n = bits // 8
            if off + n > len(data):
                return                                   # shorter than its mapping: not processed (CiA 301)
            self.node.data_store.setdefault(index, {})[sub] = bytes(data[off:off + n])
            off += n

    def _send_tpdo(self, k, cob):
        data = b""
        for index, sub, bits in self._mapping(0x1A00 + k):
            data += self.node.get_data(index, sub)[:bits // 8]
        self.net.send_message(cob, data)

    def _on_sync(self, cob_id, data, timestamp):
        with self.lock:
            self.syncs += 1   # every SYNC on the bus, in any NMT state (the tests check that SYNC stopped)
            if self.node.nmt.state != "OPERATIONAL":
                return
            for k in range(4):
                ok, cob = self._valid(0x1800 + k)
                ttype = self.raw(0x1800 + k, 2)
                if ok and 1 <= ttype <= 240:
                    self.tpdo_counts[k] += 1
                    if self.tpdo_counts[k] >= ttype:
                        self.tpdo_counts[k] = 0
                        self._send_tpdo(k, cob)
            for k, d in sorted(self.pending.items()):
                if 1 <= self.raw(0x1400 + k, 2) <= 240:
                    self._apply_rpdo(k, d)
            self.pending.clear()
            self._step()

    def _step(self):
        if self.A is None:
            self.ts = self.raw(0x1006) * 1e-6 or 1e-3
            self.A, self.B = zoh(self.ts)
        rated = (self.raw(0x6076) or 1) * 1e-3
        pm = self.raw(0x6071) if self.state == "operation enabled" and self.raw(0x6061) == 10 else 0
        self.tau_pm = int(pm)
        tau = self.tau_pm * 1e-3 * rated
        self.x = self.A @ self.x + self.B * tau
        w = self.x[1] + (self.noise * self.rng.standard_normal() if self.noise > 0 else 0.0)
        self._store(0x6074, 0, self.tau_pm)
        self._store(0x6077, 0, self.tau_pm)
        self._store(0x606C, 0, int(np.clip(round(w * 1e3), -2**31, 2**31 - 1)))
        pos = int(round(self.x[0] * 1e6)) & 0xFFFFFFFF
        self._store(0x6064, 0, pos - (1 << 32) if pos >= 1 << 31 else pos)

    def snapshot(self):
        """The node's own view: its state, statusword, target torque, NMT state and SYNCs counted."""
        with self.lock:
            return {"state": self.state, "statusword": self.raw(0x6041), "target_torque": self.raw(0x6071),
                    "nmt": self.node.nmt.state, "syncs": self.syncs, "mode": self.raw(0x6061),
                    "tpdo1": self._mapping(0x1A00), "rpdo1": self._mapping(0x1600)}
