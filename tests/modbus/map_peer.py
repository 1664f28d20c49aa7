#!/usr/bin/env python3
"""An independent msid-device/1 Modbus device written with pymodbus (its server and datastore).

It reads the device description with Python's tomllib, following docs/devices.md only (it imports nothing
of msid), serves exactly the registers the description names (any other address: exception 2; only the
drive channels' registers are writable) and runs a discrete-time plant behind them on the device's own cycle:

    at cycle k (device time k / cycle_hz) the device takes the latest setpoints u_k, publishes
    y_k = C x_k + D u_k (+ noise) on the output channels, the applied input (+ noise) on the input channels,
    its cycle count on a counter channel (wrapping at the register type's range) and the first drive channel's
    setpoint on a reference channel, then steps x_{k+1} = A x_k + B u_k.

A setpoint written between two cycles is applied from the next cycle on; a read returns what the last cycle
published. The device's clock runs (1 + ppm 1e-6) times the host's CLOCK_MONOTONIC.

The cycles are run lazily, at each request, up to the request's arrival (not by an asyncio task on a timer).
Nothing outside the device can see it between two requests, so running the cycles due by then, each with the
setpoint it would have taken, gives exactly what a free-running device would answer; a timer task in Python
would instead put the event loop's scheduling jitter into the cycle instants (cycles late and bunched on a
busy machine), which a hardware cycle does not have. It also costs no CPU while the device is idle.

The description and the plant file are read by map_peer_files.py, the registers encoded by map_peer_regs.py
(struct, every type and word order of docs/devices.md; integers round to nearest and saturate). On Modbus
RTU each frame also takes its line time at --baud (a pty carries bytes at once, a serial line does not);
requests for another unit are not answered there, and answered with exception 11 (gateway target failed to
respond) on TCP. Functions other than 3, 4, 6, 16 and 23 are refused with exception 1.

usage: map_peer.py --map DESC (--modbus-tcp HOST:PORT | --modbus-rtu DEVICE [--baud B]) --plant FILE
                   [--cycle-hz F] [--clock-ppm X] [--seed N] [--noise-y S] [--noise-u S] [--counter-start N]
                   [--state FILE] [--idle-exit S] [--late-every K:MS]
Ready line on stdout: "map_peer: ready on modbus-tcp HOST:PORT ..." (the port chosen for port 0) or
"map_peer: ready on modbus-rtu DEVICE ...". SIGTERM or SIGINT: writes --state (JSON: the final setpoints and
the counters) and exits 0. A bad description, plant or option: one message on stderr, exit 2."""
import argparse
import asyncio
import gc
import json
import logging
import math
import os
import signal
import sys
import time

import numpy as np
from pymodbus.constants import ExcCodes
from pymodbus.pdu import ExceptionResponse
from pymodbus.pdu.register_message import ReadWriteMultipleRegistersRequest
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from map_peer_files import Refused, read_description, read_plant
from map_peer_regs import INT_RANGE, counter_regs, decode, encode


# ---- the device: its cycle, its registers, its counters --------------------------------------------------

def step_affine(A, b, x, n):
    """x after n steps of x <- A x + b: one by one for a few, by repeated squaring of the affine map for many (a
    device left idle for minutes has run millions of cycles)."""
    if n <= 64:
        for _ in range(n):
            x = A @ x + b
        return x
    P, q = A, b            # the map applied 2^i times: x <- P x + q
    while n:
        if n & 1:
            x = P @ x + q
        P, q = P @ P, P @ q + q
        n >>= 1
    return x


class Device:
    """The plant on the device's own cycle behind the description's registers. regs[table] are the pymodbus
    register lists of the holding and input tables, base[table] the address of their element 0."""

    def __init__(self, desc, plant, cycle_hz, ppm, sigma_y, sigma_u, seed, counter_start):
        self.desc = desc
        self.A, self.B, self.C, self.D = plant
        self.cycle_hz, self.ppm = cycle_hz, ppm
        self.sigma_y, self.sigma_u = sigma_y, sigma_u
        self.rng = np.random.default_rng(seed)
        self.counter_start = counter_start
        self.x = np.zeros(self.A.shape[0])
        self.u = np.array([c.safe for c in desc.drive])
        self.out_index = {c.name: j for j, c in enumerate(desc.outputs())}
        self.cycles = 0
        self.values = {}
        self.count = {"requests": 0, "reads": 0, "writes": 0, "refused_address": 0, "refused_function": 0,
                      "refused_unit": 0, "answers_late": 0, "writes_not_safe": 0, "writes_outside_range": 0,
                      "steps_over_max_step": 0, "setpoints_not_finite": 0}
        self.regs, self.base = {}, {}
        self.t0 = time.monotonic()
        self.last_request = self.t0

    def attach(self, table, base, registers):
        self.regs[table], self.base[table] = registers, base
        for c in self.desc.drive:
            if c.table == table:
                self._put(c, encode(c, c.safe))

    def _put(self, c, regs):
        i = c.addr - self.base[c.table]
        self.regs[c.table][i:i + len(regs)] = regs

    def _get(self, c):
        i = c.addr - self.base[c.table]
        return self.regs[c.table][i:i + c.nregs]

    def _publish_cycle(self):
        """The values a cycle publishes: y = C x + D u (+ noise), the applied input (+ noise), the setpoint."""
        u = self.u
        y = self.C @ self.x + self.D @ u
        for c in self.desc.measure:
            if c.role == "output":
                self.values[c.name] = y[self.out_index[c.name]] + self.sigma_y * self.rng.standard_normal()
            elif c.role == "input":
                self.values[c.name] = u[c.reads_back] + self.sigma_u * self.rng.standard_normal()
            elif c.role == "reference":
                self.values[c.name] = u[0]

    def advance(self, now):
        """Run the cycles started by host time now (cycle k starts at device time k / cycle_hz, each takes the
        setpoints as they are) and publish what the last one computed. Only the last cycle's values can be
        read, so the cycles before it only step the plant (their noise is never seen)."""
        dev_t = (now - self.t0) * (1.0 + 1e-6 * self.ppm)
        due = math.floor(dev_t * self.cycle_hz) + 1
        if due <= self.cycles:
            return
        A, Bu = self.A, self.B @ self.u
        self.x = step_affine(A, Bu, self.x, due - self.cycles - 1)
        self._publish_cycle()
        self.x = A @ self.x + Bu
        self.cycles = due
        k = self.counter_start + self.cycles - 1   # the count the last cycle publishes
        for c in self.desc.measure:
            self._put(c, counter_regs(c, k) if c.role == "counter" else encode(c, self.values[c.name]))

    def take_setpoints(self):
        """After a write: the drive registers as setpoints, each write checked against min, max and max_step and
        against the safe values."""
        outside = over = not_safe = False
        for i, c in enumerate(self.desc.drive):
            regs = self._get(c)
            not_safe |= regs != encode(c, c.safe)
            v = decode(c, regs)
            if not math.isfinite(v):
                self.count["setpoints_not_finite"] += 1
                continue
            tol = 1e-6 * max(abs(v), abs(self.u[i]), 1.0) + (abs(c.scale) if c.type in INT_RANGE else 0.0)
            outside |= bool(v < c.lo - tol or v > c.hi + tol)
            over |= bool(abs(v - self.u[i]) > c.max_step + tol)
            self.u[i] = v
        self.count["writes"] += 1
        self.count["writes_outside_range"] += int(outside)
        self.count["steps_over_max_step"] += int(over)
        self.count["writes_not_safe"] += int(not_safe)

    def state(self):
        return {"format": "map-peer-state/1", "description": self.desc.path, "cycle_hz": self.cycle_hz,
                "clock_ppm": self.ppm, "cycles": self.cycles, "counter_start": self.counter_start,
                "setpoints": {c.name: float(self.u[i]) for i, c in enumerate(self.desc.drive)},
                "counters": dict(self.count)}


# ---- pymodbus: the datastore, the request hooks, the server ----------------------------------------------

SERVED = {3, 4, 6, 16, 23}


def register_blocks(desc):
    """The SimData of each table: one entry per channel (addresses between channels stay invalid: exception 2);
    measure channels in holding registers are read-only."""
    blocks = {"holding": [], "input": []}
    for c in desc.drive + desc.measure:
        blocks[c.table].append(SimData(c.addr, values=[0] * c.nregs, datatype=DataType.REGISTERS,
                                       readonly=c.kind != "drive"))
    for t in blocks:
        if not blocks[t]:
            blocks[t] = [SimData(0, datatype=DataType.INVALID)]
    return blocks


def frame_bytes(pdu):
    """Bytes of an RTU frame carrying pdu: address, function code, data, CRC."""
    try:
        return 4 + len(pdu.encode())
    except Exception:   # noqa: BLE001 (a request pymodbus cannot encode back: its smallest frame)
        return 8


def line_time(baud, pdu):
    """Seconds pdu's frame takes on an RTU line at baud (10 bits a byte), with its 3.5-character silence
    (1.75 ms above 19200 baud, as the Modbus serial line specification fixes it)."""
    return frame_bytes(pdu) * 10.0 / baud + (1.75e-3 if baud > 19200 else 38.5 / baud)


class CheckedReadWrite(ReadWriteMultipleRegistersRequest):
    """Function 23 that writes nothing when its read range is refused (pymodbus writes first, then reads)."""

    async def datastore_update(self, context, device_id):
        if 1 <= self.read_count <= 125:   # a bad count: pymodbus's exception 3, before anything is written
            probe = await context.async_getValues(device_id, 3, self.read_address, self.read_count)
            if isinstance(probe, ExcCodes):
                return ExceptionResponse(self.function_code, probe)
        return await super().datastore_update(context, device_id)


def make_action(dev):
    """The hook pymodbus calls on every access of the device's registers (before it reads or writes them):
    run the cycles due by now and publish; for a write, place the values and take the setpoints."""

    async def action(fc, start, address, count, registers, values):
        now = time.monotonic()
        dev.last_request = now
        dev.advance(now)
        if values is not None:
            i = address - start
            registers[i:i + len(values)] = values
            dev.take_setpoints()
        return None

    return action


def make_trace(dev, unit, rtu, baud, late):
    """pymodbus's hook on each request it decodes: another unit's request unanswered on RTU (the line is shared)
    and answered with exception 11 on TCP; functions other than 3, 4, 6, 16, 23 refused with exception 1; every
    request counted; on RTU the request's and the answer's line time taken; with late = (K, S) every K-th answer
    held back S seconds after the device has read the request (a slow answer). Both are slept with time.sleep:
    asyncio.sleep's epoll wait rounds up to whole milliseconds, and pymodbus would answer a request that arrived
    meanwhile first, with the held answer's transaction id (it reads the handler's last request after the
    await). The event loop waits as a device busy with one request does."""
    def trace(sending, pdu):
        if sending:
            return pdu
        if pdu.dev_id != unit and rtu:
            dev.count["refused_unit"] += 1
            return None
        served = pdu.datastore_update

        async def update(context, device_id):
            dev.count["requests"] += 1
            if rtu:   # the request's bytes arrive over the line before the device sees them
                time.sleep(line_time(baud, pdu))
            if pdu.dev_id != unit:
                dev.count["refused_unit"] += 1
                r = ExceptionResponse(pdu.function_code, ExcCodes.GATEWAY_NO_RESPONSE)
            elif pdu.function_code not in SERVED:
                dev.count["refused_function"] += 1
                r = ExceptionResponse(pdu.function_code, ExcCodes.ILLEGAL_FUNCTION)
            else:
                r = await served(context, device_id)
                if isinstance(r, ExceptionResponse):
                    dev.count["refused_address"] += int(r.exception_code == ExcCodes.ILLEGAL_ADDRESS)
                elif pdu.function_code in (3, 4, 23):
                    dev.count["reads"] += 1
            if late and dev.count["requests"] % late[0] == 0:   # the device busy: later requests wait behind it
                dev.count["answers_late"] += 1
                time.sleep(late[1])
            if rtu:
                time.sleep(line_time(baud, r))
            return r

        pdu.datastore_update = update
        return pdu

    return trace


def write_state(path, dev):
    """The device's state as JSON, written whole or not at all."""
    tmp = f"{path}.tmp.{os.getpid()}"
    with open(tmp, "w") as f:
        json.dump(dev.state(), f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


async def serve(a, desc, dev):
    blocks = register_blocks(desc)
    bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
    sim = SimDevice(id=desc.unit, simdata=(bits, list(bits), blocks["holding"], blocks["input"]),
                    action=make_action(dev))
    trace = make_trace(dev, desc.unit, a.modbus_rtu is not None, a.baud, a.late_every)
    if a.modbus_rtu is not None:
        server = ModbusSerialServer(sim, port=a.modbus_rtu, baudrate=a.baud, trace_pdu=trace,
                                    custom_pdu=[CheckedReadWrite])
    else:
        host, _, port = a.modbus_tcp.rpartition(":")
        server = ModbusTcpServer(sim, address=(host, int(port)), trace_pdu=trace, custom_pdu=[CheckedReadWrite])
    gc.freeze()   # what exists now lives as long as the device: the collector need not walk it on every request
    rt = server.context.devices[desc.unit]
    for table, key in (("holding", "h"), ("input", "i")):
        start, _, registers, _ = rt.block[key]
        dev.attach(table, start, registers)
    try:
        await server.serve_forever(background=True)
    except RuntimeError:
        raise Refused(f"cannot open {a.modbus_rtu}" if a.modbus_rtu is not None
                      else f"cannot listen on {a.modbus_tcp}") from None
    if a.modbus_rtu is not None:
        where = f"modbus-rtu {a.modbus_rtu} ({a.baud} baud, unit {desc.unit}"
    else:
        h, p = server.transport.sockets[0].getsockname()[:2]
        where = f"modbus-tcp {h}:{p} (unit {desc.unit}"
    print(f"map_peer: ready on {where}, described by {desc.path}, cycle {dev.cycle_hz:g} Hz)", flush=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for s in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(s, stop.set)
    while not stop.is_set():
        try:
            await asyncio.wait_for(stop.wait(), 0.5)
        except TimeoutError:
            pass
        if a.idle_exit > 0 and time.monotonic() - dev.last_request > a.idle_exit:
            break
    await server.shutdown()
    dev.advance(time.monotonic())
    if a.state:
        write_state(a.state, dev)


def options(argv):
    p = argparse.ArgumentParser(prog="map_peer.py", description="An msid-device/1 Modbus device (pymodbus).")
    p.add_argument("--map", required=True, help="the device description (msid-device/1 TOML)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--modbus-tcp", metavar="HOST:PORT", help="serve Modbus TCP (port 0: a free one)")
    where.add_argument("--modbus-rtu", metavar="DEVICE", help="serve Modbus RTU on a serial device or pty")
    p.add_argument("--baud", type=int, default=115200, help="RTU line rate, baud (default 115200)")
    p.add_argument("--plant", required=True, help="DT state space at the cycle rate (msid-devsim's plant format)")
    p.add_argument("--cycle-hz", type=float, help="the device's cycle rate (default: cycle_hz, else 1000)")
    p.add_argument("--clock-ppm", type=float, default=0.0, help="its clock against the host's, ppm (default 0)")
    p.add_argument("--seed", type=int, default=1, help="noise seed (default 1)")
    p.add_argument("--noise-y", type=float, default=0.05, help="output noise std, physical units (default 0.05)")
    p.add_argument("--noise-u", type=float, default=0.002, help="read-back input noise std (default 0.002)")
    p.add_argument("--counter-start", type=int, default=0,
                   help="the count of the first cycle (a device that has been running: its counter may wrap)")
    p.add_argument("--state", help="JSON of the final setpoints and counters, written at exit")
    p.add_argument("--idle-exit", type=float, default=0.0, help="exit after S seconds without a request")
    p.add_argument("--late-every", metavar="K:MS", help="hold every K-th answer back MS milliseconds (a slow answer)")
    a = p.parse_args(argv)
    if a.late_every is not None:
        k, _, ms = a.late_every.partition(":")
        try:
            a.late_every = (int(k), float(ms) * 1e-3)
        except ValueError:
            a.late_every = (0, 0.0)
        if not (a.late_every[0] >= 1 and 0 < a.late_every[1] <= 60):
            p.error(f"--late-every {k}:{ms}: give K:MS, K >= 1 requests, MS in (0, 60000]")
    if a.modbus_tcp is not None:
        host, _, port = a.modbus_tcp.rpartition(":")
        if not host or not port.isdigit() or int(port) > 65535:
            p.error(f"--modbus-tcp {a.modbus_tcp}: give HOST:PORT (port 0: a free one)")
    if not 300 <= a.baud <= 4000000:
        p.error(f"--baud {a.baud}: must be in 300..4000000")
    if a.cycle_hz is not None and not 0 < a.cycle_hz <= 1e6:
        p.error(f"--cycle-hz {a.cycle_hz:g}: must be in (0, 1e6]")
    if not abs(a.clock_ppm) < 1e5:
        p.error(f"--clock-ppm {a.clock_ppm:g}: must be below 1e5 in magnitude")
    if not (a.noise_y >= 0 and a.noise_u >= 0):
        p.error("--noise-y and --noise-u must be >= 0")
    if a.counter_start < 0:
        p.error("--counter-start must be >= 0")
    if a.state and not os.path.isdir(os.path.dirname(os.path.abspath(a.state))):
        p.error(f"--state {a.state}: its folder does not exist")
    return a


def main(argv):
    a = options(argv)
    logging.getLogger("pymodbus").setLevel(logging.ERROR)   # its warnings repeat what the peer says itself
    try:
        desc = read_description(a.map)
        plant = read_plant(a.plant)
        _, B, C, _ = plant
        ny = len(desc.outputs())
        if B.shape[1] != len(desc.drive) or C.shape[0] != ny:
            raise Refused(f"{a.plant}: the plant has {B.shape[1]} input(s) and {C.shape[0]} output(s), {a.map} "
                          f"{len(desc.drive)} drive and {ny} output channel(s)")
        cyc = a.cycle_hz or (desc.cycle_hz if not math.isnan(desc.cycle_hz) else 1000.0)
        dev = Device(desc, plant, cyc, a.clock_ppm, a.noise_y, a.noise_u, a.seed, a.counter_start)
        asyncio.run(serve(a, desc, dev))
    except Refused as e:
        print(f"map_peer: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
