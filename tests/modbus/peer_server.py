#!/usr/bin/env python3
"""An independent msid-modbus/1 device written with pymodbus (its server and datastore), following
docs/modbus-registers.md only: the header, the parameter mailbox (records checked by zlib's CRC-32),
the command block and a ring of samples encoded with struct in the requested word order. It does
not rebuild the design: the excitation comes from `msid excite --csv` files, the plant is a static
gain y = D u plus white noise (so the true FRF is D at every line).

usage: peer_server.py PORT CSV_DIR SEED"""
import asyncio
import struct
import sys
import zlib
from pathlib import Path

import numpy as np
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

D = np.array([[1.0, 0.3], [-0.2, 0.7]])
SIGMA = 0.05
HR_N, RING = 138, 64
port, csv_dir, seed = int(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
st = {"state": 1, "crc": 0, "cmd_done": 0, "cfg_done": 0, "recs": [], "cfg": {}, "exp": 0, "w": 0, "W": 5,
      "R": 0, "enc": 0, "wo": 0, "periods": 0, "period": 0, "total": 0, "records": 0}
rng = np.random.default_rng(seed)


def put32(regs, a, v):
    regs[a], regs[a + 1] = (v >> 16) & 0xFFFF, v & 0xFFFF


def words(b4, wo):
    """4 big-endian bytes ABCD -> 2 registers in word order wo (ABCD, CDAB, BADC, DCBA)."""
    A, B, C, Dd = b4
    return {0: [(A << 8) | B, (C << 8) | Dd], 1: [(C << 8) | Dd, (A << 8) | B],
            2: [(B << 8) | A, (Dd << 8) | C], 3: [(Dd << 8) | C, (B << 8) | A]}[wo]


def encode(v, enc, wo, scale):
    if enc == 2:
        return words(struct.pack(">f", v), wo)
    if enc == 1:
        return words(struct.pack(">i", int(round(v / scale))), wo)
    (r,) = struct.unpack(">H", struct.pack(">h", int(round(v / scale))))
    return [((r & 0xFF) << 8) | (r >> 8)] if wo in (2, 3) else [r]


def header(ir):
    h = [0] * 40
    h[0], h[1], h[2], h[3], h[6], h[7] = 0x4D53, 1, st["state"], st["exp"], 2, 2
    h[8], h[9], h[10], h[11] = st["enc"], st["wo"], st["W"], RING
    put32(h, 12, st["R"])
    put32(h, 14, st["w"])
    put32(h, 24, st["total"])
    put32(h, 26, st["crc"])
    put32(h, 28, st["period"])
    h[30], h[31] = st["cmd_done"], st["cfg_done"]
    put32(h, 32, st["records"])
    put32(h, 38, st["periods"])
    ir[0:40] = h


def apply_records(hr):
    n = min(hr[17], 30)
    for i in range(n):
        rec = b"".join(struct.pack(">H", r) for r in hr[18 + 4 * i: 22 + 4 * i])
        p, idx, val = rec[0], int.from_bytes(rec[1:4], "little"), int.from_bytes(rec[4:8], "little")
        if p == 0x01:
            st["recs"], st["cfg"], st["records"] = [], {}, 0
        st["records"] += 1
        if p == 0x7F:
            ok = val == zlib.crc32(b"".join(st["recs"]))
            st["state"], st["crc"] = (2, val) if ok else (5, 0)
            c = st["cfg"]
            st["period"], st["periods"], st["scale"] = c[0x02], c[0x14], struct.unpack("<f", c[0x11].to_bytes(4, "little"))[0]
            st["enc"], st["wo"] = hr[8], hr[9]
            st["W"] = 1 + 4 * (1 if st["enc"] == 0 else 2)
            st["R"] = (65536 - RING) // st["W"]
            continue
        st["recs"].append(rec)
        st["cfg"].setdefault(p, val)


def start(ir, e, periods):
    u = np.loadtxt(csv_dir / f"e{e + 1}.csv", delimiter=",", skiprows=1, ndmin=2)
    P = st["period"]
    n = (periods or st["periods"]) * P
    u = np.resize(u[:P], (n, 2))      # one period repeated
    y = u @ D.T + SIGMA * rng.standard_normal((n, 2))
    W = st["W"]
    for k in range(n):
        regs = [k & 0xFFFF]
        for v in (*u[k], *y[k]):
            regs += encode(float(v), st["enc"], st["wo"], st["scale"])
        ir[RING + k * W: RING + (k + 1) * W] = regs
    st["exp"], st["w"], st["total"], st["state"] = e, n, n, 4   # written at once: DONE


async def action(fc, start_addr, address, count, registers, values):
    if fc == 4:
        header(registers)
    elif fc in (16, 6) and values is not None:
        hr = registers
        hr[address: address + len(values)] = values
        if address <= 16 < address + len(values) and hr[16] != st["cfg_done"]:
            st["cfg_done"] = hr[16]
            apply_records(hr)
        if address == 0 and hr[0] != st["cmd_done"]:
            st["cmd_done"] = hr[0]
            if hr[1] == 1:
                start(IR[0], hr[2], (hr[3] << 16) | hr[4])
    return None


IR = [None]


async def main():
    ir_block = [SimData(0, count=65536, values=0, datatype=DataType.REGISTERS)]
    hr_block = [SimData(0, count=HR_N, values=0, datatype=DataType.REGISTERS)]
    bits = [SimData(0, count=1, values=False, datatype=DataType.BITS)]
    dev = SimDevice(id=1, simdata=(bits, bits, hr_block, ir_block), action=action)
    server = ModbusTcpServer(dev, address=("127.0.0.1", port))
    task = asyncio.create_task(server.serve_forever())
    await asyncio.sleep(0.5)
    print(f"peer ready on 127.0.0.1:{port}", flush=True)
    IR[0] = server.context.devices[1].block["i"][2]   # the input register list the server reads from
    await task


asyncio.run(main())
