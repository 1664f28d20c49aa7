#!/usr/bin/env python3
"""The tick loop a user would write without msid, with pymodbus: every tick write the torque command (float32,
holding 100..101) and read the measured values (input 0..2), paced by time.sleep to the next deadline of
time.monotonic(). It records each tick's lateness (wake-up minus deadline; of the ticks it slept for apart, the pacing's own
precision) and round trip, and prints one JSON line: ticks, lateness and round-trip quantiles, CPU seconds of
the loop. The peer of `msid bench ticks`.

usage: tick_peer.py HOST PORT RATE TICKS"""
import math
import resource
import struct
import sys
import time

from pymodbus.client import ModbusTcpClient

from pacing import report, sleep_until


def main():
    host, port, rate, ticks = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
    c = ModbusTcpClient(host, port=port, timeout=1)
    if not c.connect():
        sys.exit(f"tick_peer: cannot connect to {host}:{port}")
    T = 1.0 / rate
    late, wake, rtt, failed = [], [], [], 0
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.monotonic() + T
    for n in range(ticks):
        w = sleep_until(t0 + n * T, late, wake)
        u = 0.5 * math.sin(2 * math.pi * n / 64)
        hi, lo = struct.unpack(">HH", struct.pack(">f", u))
        a = c.write_registers(100, [hi, lo], device_id=1)
        r = c.read_input_registers(0, count=3, device_id=1)   # Torque (float32) and Speed (int16)
        rtt.append(time.monotonic() - w)
        failed += a.isError() or r.isError()
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    c.write_registers(100, [0, 0], device_id=1)
    c.close()
    print(report(ticks, late, wake, rtt, cpu0, cpu1, failed=failed))


if __name__ == "__main__":
    main()
