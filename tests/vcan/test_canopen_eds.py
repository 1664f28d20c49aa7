"""msid's EDS reader (daq/src/msid_co_eds_file.cpp, through co_probe eds) against the canopen package's
own import of the same file: every entry, its data type, access type and PDO mapping flag, none more and
none less. On the in-VM tests' drive402.eds and a file of records, a compact array and mixed case. And a
PDO mapping the EDS refuses (a read-only target, an unknown or unmappable object, a size other than the
type's) refused with one message before any bus is opened."""
import os
import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
PROBE = os.environ.get("MSID_CO_PROBE", "")

EXTRA = """[DeviceInfo]
VendorName=x
[1003]
ParameterName=Pre-defined error field
ObjectType=0x8
DataType=0x0007
AccessType=ro
CompactSubObj=4
[2100]
ParameterName=Gain
DataType=0x0008
AccessType=RW
DefaultValue=1.5
PDOMapping=1
[2101]
ParameterName=Rec
ObjectType=0x9
SubNumber=3
[2101sub0]
ParameterName=n
DataType=0x0005
AccessType=const
DefaultValue=2
[2101sub1]
ParameterName=x
DataType=0x0004
AccessType=rww
PDOMapping=1
[2101sub2]
ParameterName=y
DataType=0x001B
AccessType=wo
"""


def msid_entries(path):
    if not PROBE or not os.access(PROBE, os.X_OK):
        pytest.fail("MSID_CO_PROBE must name the co_probe executable (ctest sets it)")
    r = subprocess.run([PROBE, "eds", str(path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    out = {}
    for line in r.stdout.split("\n"):
        if line:
            i, s, t, a, m = line.split()
            out[(int(i, 16), int(s, 16))] = (int(t, 16), a, m == "1")
    return out


def canopen_entries(path):
    import configparser
    import canopen
    from canopen.objectdictionary import ODArray, ODRecord
    od = canopen.import_od(str(path))
    ini = configparser.ConfigParser()
    ini.read(path)
    out = {}
    for obj in od.values():
        members = list(obj.values()) if isinstance(obj, (ODRecord, ODArray)) else [obj]
        section = f"{obj.index:04X}"
        compact = isinstance(obj, ODArray) and ini.has_option(section, "CompactSubObj")
        if compact:
            # canopen keeps a compact array's first member as the template of the others, made on access
            members = [obj[k] for k in range(0, int(ini.get(section, "CompactSubObj"), 0) + 1)]
        for v in members:
            out[(v.index, v.subindex)] = (v.data_type, v.access_type, bool(v.pdo_mappable))
        if compact:
            # its subindex 0 keeps canopen's default access ("rw"); CiA 306 makes the count read only
            out[(obj.index, 0)] = (out[(obj.index, 0)][0], "ro", False)
    return out


@pytest.mark.parametrize("which", ["drive402", "extra"])
def test_every_entry_as_canopen_reads_it(which, tmp_path):
    path = HERE / "in_vm" / "data" / "drive402.eds"
    if which == "extra":
        path = tmp_path / "extra.eds"
        path.write_text(EXTRA)
    ours, theirs = msid_entries(path), canopen_entries(path)
    assert sorted(ours) == sorted(theirs)
    for k in theirs:
        assert ours[k] == theirs[k], f"0x{k[0]:04X}:{k[1]:02X}: msid {ours[k]}, canopen {theirs[k]}"


@pytest.mark.parametrize("args, message", [
    (["rpdo", 1, "0x6040:00/16,0x6077:00/16"],
     "RPDO1 maps 0x6077:00 (Torque actual value), which is read only: it cannot be a target msid writes"),
    (["tpdo", 1, "0x6099:00/16"], "TPDO1 maps 0x6099:00 is not in "),
    (["tpdo", 1, "0x6076:00/32"], "TPDO1 maps 0x6076:00 (Motor rated torque), which is not PDO-mappable"),
    (["tpdo", 1, "0x606C:00/16"], "TPDO1 maps 0x606C:00 (Velocity actual value) with 16 bits: it is INTEGER32, 32 bits"),
])
def test_a_mapping_the_eds_refuses_is_refused_before_the_bus_is_opened(args, message):
    # this host has no CAN: a check made after opening the bus would fail on the bus instead
    eds = HERE / "in_vm" / "data" / "drive402.eds"
    r = subprocess.run([PROBE, "pdo", "canopen://vcan0?node=5", *map(str, args), "1", str(eds)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and message in r.stderr and r.stderr.count("\n") == 1, r.stderr
