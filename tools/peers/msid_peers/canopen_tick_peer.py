#!/usr/bin/env python3
"""The SYNC loop a user would write without msid for a CiA 402 drive in cyclic synchronous torque mode, with the
canopen package (its RemoteNode from the drive's EDS): by SDO the RPDO1 mapping of the target torque 0x6071 and
the TPDO1 mapping of the torque demand 0x6074 and the velocity 0x606C (transmission type 1: on every SYNC), the
mode 10 (CST), the CiA 402 walk to "operation enabled" and NMT operational; then every tick the next target in
RPDO1, one SYNC, and a wait of at most 0.6 of a tick for the TPDO that SYNC asked for, paced by time.sleep to
the next deadline of time.monotonic(). At the end: the target 0, quick stop, disable voltage, NMT
pre-operational. It does in a tick what msid's CANopen tick loop does, and records each tick's lateness
(wake-up minus deadline; of the ticks it slept for apart) and round trip (wake-up to the TPDO received), and
prints one JSON line: ticks, ticks without their TPDO, lateness and round-trip quantiles, CPU seconds of the
loop. The CANopen peer of the SYNC bench.

usage: canopen_tick_peer.py IFACE NODE EDS RATE TICKS"""
import math
import resource
import sys
import time

import canopen

from pacing import report, sleep_until


def configure(node, rate):
    """PDO mappings, cycle period, CST, the state machine to "operation enabled", NMT operational."""
    node.nmt.state = "PRE-OPERATIONAL"
    node.tpdo.read()
    node.rpdo.read()
    node.rpdo[1].clear()
    node.rpdo[1].add_variable(0x6071)
    node.rpdo[1].trans_type = 1
    node.rpdo[1].enabled = True
    node.tpdo[1].clear()
    node.tpdo[1].add_variable(0x6074)
    node.tpdo[1].add_variable(0x606C)
    node.tpdo[1].trans_type = 1
    node.tpdo[1].enabled = True
    node.rpdo[1].save()
    node.tpdo[1].save()
    node.sdo[0x1006].raw = int(round(1e6 / rate))
    node.sdo[0x6060].raw = 10
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    node.nmt.state = "OPERATIONAL"


def main():
    iface, node_id, eds = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    rate, ticks = float(sys.argv[4]), int(sys.argv[5])
    net = canopen.Network()
    net.connect(interface="socketcan", channel=iface)
    node = canopen.RemoteNode(node_id, eds)
    net.add_node(node)
    configure(node, rate)
    T = 1.0 / rate
    late, wake, rtt, missing = [], [], [], 0
    target = node.rpdo[1][0x6071]
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.monotonic() + T
    for n in range(ticks):
        w = sleep_until(t0 + n * T, late, wake)
        target.raw = int(round(300 * math.sin(2 * math.pi * n / 64)))
        node.rpdo[1].transmit()
        net.sync.transmit()
        if node.tpdo[1].wait_for_reception(timeout=0.6 * T) is None:
            missing += 1
        else:
            demand, velocity = node.tpdo[1][0x6074].raw, node.tpdo[1][0x606C].raw   # noqa: F841 (read, as a user would)
        rtt.append(time.monotonic() - w)
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    target.raw = 0
    node.rpdo[1].transmit()
    net.sync.transmit()
    node.sdo[0x6040].raw = 0x02   # quick stop
    node.sdo[0x6040].raw = 0x00   # disable voltage
    node.nmt.state = "PRE-OPERATIONAL"
    net.disconnect()
    print(report(ticks, late, wake, rtt, cpu0, cpu1, stale=missing))


if __name__ == "__main__":
    main()
