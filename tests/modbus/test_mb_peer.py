"""Conformance against an independent peer, pymodbus (PyPI), both ways:
- a pymodbus client talks to the simulator using only docs/modbus-registers.md: header, parameter
  upload (records and CRC-32 built here with struct and zlib), START, the ring in float32 CDAB;
  the inputs it reads are the design's excitation (msid excite --csv) to float32 precision;
- `msid modbus measure` reads a pymodbus server that serves the same map (peer_server.py) and
  finds its static gain inside the 95% regions, in every word order."""
import select
import socket
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

import mblib as c

HERE = Path(__file__).resolve().parent


def rec(p, idx, val):
    return bytes([p]) + idx.to_bytes(3, "little") + (val & 0xFFFFFFFF).to_bytes(4, "little")


def records(P, bins, nu, m, seed, periods, scale):
    r = [rec(0x01, 1, 0), rec(0x02, 0, P), rec(0x03, 0, len(bins)), rec(0x04, 0, nu), rec(0x05, 0, m),
         rec(0x06, 0, 0), rec(0x07, 0, 0), rec(0x08, 0, seed & 0xFFFFFFFF), rec(0x08, 1, seed >> 32)]
    r += [rec(0x09, l, b) for l, b in enumerate(bins)]
    r += [rec(0x10, 0, 0), rec(0x11, 0, struct.unpack("<I", struct.pack("<f", scale))[0]), rec(0x12, 0, 0),
          rec(0x13, 0, 0), rec(0x14, 0, periods)]
    crc = zlib.crc32(b"".join(r))
    return r + [rec(0x7F, 0, crc)], crc


def u32(regs, a):
    return (regs[a] << 16) | regs[a + 1]


def test_pymodbus_client_reads_the_simulator_as_documented(tmp_path):
    P, bins, seed, K = 64, [1, 3, 5, 7], 5, 2
    c.run_ok("excite", "--period", P, "--lines", "1:2:7", "--inputs", 2, "--experiments", 2, "--periods", K,
             "--seed", seed, "-o", tmp_path / "d.json", "--csv", tmp_path / "csv")
    u_ref = np.loadtxt(tmp_path / "csv" / "e1.csv", delimiter=",", skiprows=1)
    with c.Sim(tmp_path, "--noise-u", 0) as sim:
        cl = ModbusTcpClient("127.0.0.1", port=sim.port, timeout=2)
        assert cl.connect()
        h = cl.read_input_registers(0, count=40, device_id=1).registers
        assert h[0] == 0x4D53 and h[1] == 1 and (h[6], h[7]) == (2, 2) and h[11] == 64
        # stream format, then the parameter records through the mailbox (30 per write)
        assert not cl.write_registers(8, [2, 1], device_id=1).isError()        # float32, CDAB
        recs, crc = records(P, bins, 2, 2, seed, K, 0.001)
        seq = h[31]
        for i in range(0, len(recs), 30):
            blk = recs[i:i + 30]
            seq = (seq + 1) & 0xFFFF
            regs = [seq, len(blk)] + [x for r in blk for x in struct.unpack(">4H", r)]
            assert not cl.write_registers(16, regs, device_id=1).isError()
        h = cl.read_input_registers(0, count=40, device_id=1).registers
        assert h[2] == 2, f"state {h[2]}, error {h[4]}"                       # CONFIGURED
        assert u32(h, 26) == crc and u32(h, 28) == P and h[36] == len(bins) and h[31] == seq
        assert (h[8], h[9], h[10]) == (2, 1, 9)                                  # float32, CDAB, 1 + 4*2
        R = u32(h, 12)
        # START experiment 0
        assert not cl.write_registers(0, [h[30] + 1, 1, 0, 0, 0], device_id=1).isError()
        n, rows = K * P, []
        t0 = time.monotonic()
        while len(rows) < n and time.monotonic() - t0 < 120:   # a hang detector, not a speed check
            h = cl.read_input_registers(0, count=40, device_id=1).registers
            w = u32(h, 14)
            while len(rows) < w:
                k = min(w - len(rows), 125 // 9, R - len(rows) % R)
                regs = cl.read_input_registers(64 + (len(rows) % R) * 9, count=9 * k, device_id=1).registers
                for j in range(k):
                    s = regs[9 * j: 9 * j + 9]
                    assert s[0] == (len(rows) & 0xFFFF)                            # the tag
                    rows.append([struct.unpack(">f", struct.pack(">HH", s[2 + 2 * i], s[1 + 2 * i]))[0]
                                 for i in range(4)])                                # CDAB: low word first
        cl.close()
    assert h[2] == 4 and len(rows) == n                                          # DONE
    rows = np.array(rows)
    assert np.array_equal(rows[:, :2], u_ref.astype(np.float32).astype(float))


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def wait_listening(port, limit_s=60):
    """Until 127.0.0.1:port accepts a connection. A pymodbus server prints "ready" before it listens, and a
    fixed sleep after that raced on a loaded machine: the bound is a hang detector only."""
    t0 = time.monotonic()
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=5).close()
            return
        except OSError:
            if time.monotonic() - t0 > limit_s:
                raise RuntimeError(f"nothing listens on 127.0.0.1:{port}")
            time.sleep(0.05)


class Peer:
    def __init__(self, csv_dir, seed):
        self.port = free_port()
        self.p = subprocess.Popen([sys.executable, str(HERE / "peer_server.py"), str(self.port), str(csv_dir),
                                   str(seed)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        r, _, _ = select.select([self.p.stdout], [], [], 20)
        if not r or "ready" not in self.p.stdout.readline():
            self.p.kill()
            raise RuntimeError(f"peer did not start: {self.p.stderr.read()}")
        wait_listening(self.port)

    def close(self):
        self.p.terminate()
        self.p.wait(10)


@pytest.mark.parametrize("fmt", [("float32", "CDAB"), ("int16", "BADC"), ("int32", "DCBA"), ("float32", "ABCD")])
def test_adapter_reads_a_pymodbus_server(tmp_path, fmt):
    P = 128
    c.run_ok("excite", "--period", P, "--lines", "1:2:41", "--inputs", 2, "--experiments", 2, "--periods", 6,
             "--seed", 9, "--amplitudes", 0.5, "-o", tmp_path / "d.json", "--csv", tmp_path / "csv")
    peer = Peer(tmp_path / "csv", 7)
    try:
        r = c.run("modbus", "measure", "--tcp", f"127.0.0.1:{peer.port}", "--design", tmp_path / "d.json",
                  "--encoding", fmt[0], "--word-order", fmt[1], "--scale", "1e-3" if fmt[0] == "int16" else "1e-6",
                  "--skip-periods", 0, "-o", tmp_path / "frf.json", timeout=120)
    finally:
        peer.close()
    assert r.returncode == 0, r.stderr
    import json
    doc = json.loads((tmp_path / "frf.json").read_text())
    a = doc["acquisition"]
    assert a["samples"] == 2 * 6 * P and a["samples_lost"] == 0 and (a["encoding"], a["word_order"]) == fmt
    D = [[1.0, 0.3], [-0.2, 0.7]]
    truth = {"lines": [{"bin": l["bin"], "G": {"re": D, "im": [[0, 0], [0, 0]]}} for l in doc["lines"]]}
    c.check_coverage(doc, truth, min_fraction=0.0)       # 42 rows: the binomial interval
    with pytest.raises(AssertionError):
        c.check_coverage(doc, truth, scale=1.02, min_fraction=0.0)


def test_not_an_msid_device(tmp_path):
    """A plain pymodbus server (all registers 0) is refused with a clear message."""
    peer = subprocess.Popen([sys.executable, "-c", (
        "import asyncio\nfrom pymodbus.server import ModbusTcpServer\n"
        "from pymodbus.simulator import DataType, SimData, SimDevice\n"
        "async def m():\n"
        "    b=[SimData(0,count=1,values=False,datatype=DataType.BITS)]\n"
        "    r=[SimData(0,count=200,values=0,datatype=DataType.REGISTERS)]\n"
        f"    s=ModbusTcpServer(SimDevice(id=1,simdata=(b,b,r,r)),address=('127.0.0.1',{(port := free_port())}))\n"
        "    print('ready', flush=True)\n    await s.serve_forever()\nasyncio.run(m())\n")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        select.select([peer.stdout], [], [], 20)
        peer.stdout.readline()
        wait_listening(port)
        d = c.excite(tmp_path, lines="1:2:9")
        r = c.run("modbus", "measure", "--tcp", f"127.0.0.1:{port}", "--design", d, "-o", tmp_path / "frf.json")
    finally:
        peer.terminate()
        peer.wait(10)
    c.fails(tmp_path, r, 1, "not an msid-modbus device", "0x0000")
