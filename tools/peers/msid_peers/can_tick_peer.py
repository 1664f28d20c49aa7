#!/usr/bin/env python3
"""The tick loop a user would write without msid for a CAN device described by a DBC, with python-can and
cantools: every tick take the status frames that arrived (waiting at most 0.6 of a tick for a fresh one), decode
the newest with cantools, encode the next torque command with cantools and send it, paced by time.sleep to the
next deadline of time.monotonic(). It does what msid's tick loop does in a tick (docs/devices.md, "CAN exchange"),
and records each tick's lateness (wake-up minus deadline; of the ticks it slept for apart, the pacing's own
precision) and round trip (wake-up to the command sent), and prints one JSON line: ticks, ticks without a fresh
status frame, lateness and round-trip quantiles, CPU seconds of the loop. The CAN peer of `msid bench ticks`.

usage: can_tick_peer.py IFACE DBC COMMAND_MESSAGE SIGNAL STATUS_MESSAGE RATE TICKS"""
import math
import resource
import sys
import time

import can
import cantools

from pacing import report, sleep_until


def main():
    iface, dbc, cmd_name, cmd_sig, st_name = sys.argv[1:6]
    rate, ticks = float(sys.argv[6]), int(sys.argv[7])
    db = cantools.database.load_file(dbc)
    cmd, st = db.get_message_by_name(cmd_name), db.get_message_by_name(st_name)
    bus = can.Bus(interface="socketcan", channel=iface, can_filters=[{"can_id": st.frame_id, "can_mask": 0x7FF}])
    T = 1.0 / rate
    late, wake, rtt, stale = [], [], [], 0
    others = {s.name: 0 for s in cmd.signals if s.name != cmd_sig}
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.monotonic() + T
    for n in range(ticks):
        w = sleep_until(t0 + n * T, late, wake)
        # the frames that arrived since the last tick, the newest wins; wait for one at most 0.6 of a tick
        newest = None
        f = bus.recv(timeout=0.0)
        while f is not None:
            newest = f
            f = bus.recv(timeout=0.0)
        if newest is None:
            newest = bus.recv(timeout=0.6 * T)
        if newest is None:
            stale += 1
        else:
            db.decode_message(newest.arbitration_id, newest.data, decode_choices=False)
        u = 0.5 * math.sin(2 * math.pi * n / 64)
        bus.send(can.Message(arbitration_id=cmd.frame_id, is_extended_id=cmd.is_extended_frame,
                             data=cmd.encode({cmd_sig: u, **others}, strict=False)))
        rtt.append(time.monotonic() - w)
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    bus.send(can.Message(arbitration_id=cmd.frame_id, is_extended_id=cmd.is_extended_frame,
                         data=cmd.encode({cmd_sig: 0.0, **others}, strict=False)))
    bus.shutdown()
    print(report(ticks, late, wake, rtt, cpu0, cpu1, stale=stale))


if __name__ == "__main__":
    main()
