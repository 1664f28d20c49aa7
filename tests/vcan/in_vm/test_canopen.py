"""msid's CANopen master against an independent node: the Python canopen package's LocalNode, from the
EDS data/drive402.eds, on vcan0. msid's SDO client (through co_probe, the calls behind `msid device
check|sdo|pdo`) writes and reads every size around the expedited limit and the 7-byte segment boundaries
and the node's own store holds each; the node's aborts arrive by their CiA 301 names; a node that never
answers is named; after a PDO configuration the node's own object dictionary holds the mapping msid wrote,
and a mapping longer than 8 bytes changes nothing on the node. The SYNC producer (CAN_BCM) sends its
counter in turn at its period and stops when stopped and when its process is killed."""
import os
import subprocess
from pathlib import Path

import pytest

import comap

EDS = Path(__file__).resolve().parent / "data" / "drive402.eds"
PROBE = os.environ.get("MSID_CO_PROBE", "")
NODE = 5
URI = f"canopen://vcan0?node={NODE}&timeout=1000"


def probe(*args):
    if not PROBE or not os.access(PROBE, os.X_OK):
        pytest.fail("MSID_CO_PROBE must name the co_probe executable (ctest sets it)")
    return subprocess.run([PROBE] + [str(a) for a in args], capture_output=True, text=True, timeout=60)


@pytest.fixture()
def node():
    with comap.package_node("LocalNode", NODE, EDS) as n:
        yield n


def u32(n, index, sub):
    return int.from_bytes(n.get_data(index, sub), "little")


def test_sdo_every_size_near_the_segment_boundaries(node):
    for size in range(0, 31):
        data = bytes((7 * i + size) & 0xFF for i in range(size))
        r = probe("write", URI, "0x2000:00", data.hex())
        assert r.returncode == 0, f"write of {size} bytes: {r.stderr}"
        assert node.data_store[0x2000][0] == data, f"{size} bytes written, the node holds {node.data_store[0x2000][0]!r}"
        if size == 0:
            # the node answers an upload of nothing with an abort (the expedited form cannot carry 0 bytes)
            r = probe("read", URI, "0x2000:00")
            assert r.returncode == 1 and "0x08000024: no data available" in r.stderr, r.stderr
            continue
        node.set_data(0x2000, 0, bytes(reversed(data)))
        r = probe("read", URI, "0x2000:00")
        assert r.returncode == 0, f"read of {size} bytes: {r.stderr}"
        assert r.stdout.strip() == bytes(reversed(data)).hex(), f"{size} bytes"


@pytest.mark.parametrize("op, entry, data, code, name", [
    ("read", "0x3000:00", None, "0x06020000", "object does not exist in the object dictionary"),
    ("read", "0x1018:09", None, "0x06090011", "sub-index does not exist"),
    ("write", "0x2001:00", "01000000", "0x06010002", "attempt to write a read only object"),
    ("write", "0x6040:00", "01000000", "0x06070010", "data type does not match, length of service parameter does not match"),
])
def test_the_nodes_aborts_named(node, op, entry, data, code, name):
    before = dict(node.data_store)
    r = probe(op, URI, entry, *([data] if data else []))
    assert r.returncode == 1, r.stdout
    assert f"the node aborted with {code}: {name}" in r.stderr, r.stderr
    assert f"{entry} on node {NODE}" in r.stderr, r.stderr
    assert dict(node.data_store) == before


def test_a_node_that_never_answers(node):
    r = probe("read", "canopen://vcan0?node=9&timeout=200", "0x1018:01")
    assert r.returncode == 1
    assert "node 9: no response within 200 ms (aborted: SDO protocol timed out)" in r.stderr, r.stderr


def test_check_reads_identity_and_mapping_and_writes_nothing(node):
    r = probe("check", URI)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "device type 0x1000: 0x00020192 (profile CiA 402, a drive)" in out
    assert "identity 0x1018: vendor 0x4D534944 product 0x00000402 revision 0x00010002 serial 0x00C0FFEE" in out
    assert "error register 0x1001: 0x00 (no error)" in out
    assert "TPDO1: COB-ID 0x185 (valid), transmission type 255, inhibit 0 x 100 us, 16 bits: 0x6041:00/16" in out
    assert "RPDO2: COB-ID 0x305 (valid), transmission type 255, 0 bits: nothing mapped" in out
    # vcan reports no bit rate: said plainly, with the rate a measurement's budget assumes
    assert ("bus bit rate: not reported: vcan0 is a virtual interface (vcan); a measurement's bus budget assumes "
            "1000000 bit/s unless the URI gives bitrate=BPS") in out, out
    r = probe("check", URI + "&bitrate=500000")
    assert r.returncode == 0, r.stderr
    assert "bus bit rate: 500000 bit/s (the URI's bitrate=)" in r.stdout, r.stdout
    assert node.data_store == {}  # nothing written: the node's store holds only what was written to it


def test_pdo_mapping_held_by_the_node(node):
    r = probe("pdo", URI, "tpdo", 1, "0x6074:00/16,0x6077:00/16,0x606C:00/32", 1)
    assert r.returncode == 0, r.stderr
    assert node.get_data(0x1A00, 0) == b"\x03"
    assert [u32(node, 0x1A00, k) for k in (1, 2, 3)] == [0x60740010, 0x60770010, 0x606C0020]
    assert node.get_data(0x1800, 2) == b"\x01"
    assert u32(node, 0x1800, 1) == 0x40000185  # valid again, RTR bit as the node had it
    assert "TPDO1: COB-ID 0x185 (valid), transmission type 1" in r.stdout
    r = probe("pdo", URI, "rpdo", 1, "0x6040:00/16,0x6071:00/16", 1)
    assert r.returncode == 0, r.stderr
    assert [u32(node, 0x1600, k) for k in (1, 2)] == [0x60400010, 0x60710010]
    assert node.get_data(0x1600, 0) == b"\x02" and u32(node, 0x1400, 1) == 0x205


def test_a_mapping_longer_than_8_bytes_writes_nothing(node):
    r = probe("pdo", URI, "tpdo", 1, "0x6064:00/32,0x606C:00/32,0x6077:00/16", 1)
    assert r.returncode == 2
    assert "TPDO1 maps 80 bits (10 bytes): a PDO carries at most 8 bytes" in r.stderr
    assert node.data_store == {}


def sync_frames(bus, seconds):
    """The SYNC frames (0x80) received for `seconds`, as (kernel timestamp, data)."""
    import time
    out, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        m = bus.recv(0.05)
        if m is not None and m.arbitration_id == 0x80 and not m.is_extended_id:
            out.append((m.timestamp, bytes(m.data)))
    return out


@pytest.fixture()
def bus():
    import can
    b = can.Bus(interface="socketcan", channel="vcan0")
    try:
        yield b
    finally:
        b.shutdown()


def test_sync_by_the_broadcast_manager_with_a_counter_and_stopped(bus):
    import time
    p = subprocess.Popen([PROBE, "sync", "vcan0", "2000", "5", "2"], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "started"
    got = sync_frames(bus, 1.0)
    assert p.wait(timeout=30) == 0 and p.stdout.readline().strip() == "stopped"
    stopped = time.time()
    assert len(got) >= 10
    counts = [d[0] for _, d in got if len(d) == 1]
    assert len(counts) == len(got)
    # 1..5 in turn, as CiA 301 counts
    assert all(b == a % 5 + 1 for a, b in zip(counts, counts[1:])), counts[:20]
    # the kernel's own timer: the middle spacing is the period (a loaded emulator may delay single frames)
    gaps = sorted(b[0] - a[0] for a, b in zip(got, got[1:]))
    assert 0.001 < gaps[len(gaps) // 2] < 0.004, gaps[len(gaps) // 2]
    # stopped: what is still queued here was received (kernel time stamp) before the producer stopped
    assert [t for t, _ in sync_frames(bus, 0.5) if t > stopped] == []


def test_sync_stops_when_msid_is_killed(bus):
    # the kernel deletes a socket's cyclic messages with the socket: SYNC ends with the process, however it ends
    p = subprocess.Popen([PROBE, "sync", "vcan0", "1000", "0", "0"], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "started"
    got = sync_frames(bus, 0.5)
    assert got and all(d == b"" for _, d in got)
    import time
    p.kill()
    p.wait(timeout=30)
    gone = time.time()
    assert [t for t, _ in sync_frames(bus, 0.5) if t > gone] == []
