#!/usr/bin/env python3
"""Generate daq/can/msid.dbc, the DBC description of msid-can/1, from the
constants of daq/include/msid_daq/msid_can_proto.h (read from the header, so
the two cannot drift). `--check` fails if the file differs; `-o FILE` writes (or
checks) FILE instead of daq/can/msid.dbc, e.g. a DBC with another `--base` id.

usage: gen_dbc.py [--check] [--base 0x200] [-o FILE]
"""
import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HDR = ROOT / "daq" / "include" / "msid_daq" / "msid_can_proto.h"
EST_HDR = ROOT / "daq" / "include" / "msid_daq" / "msid_can_est.h"   # extension estimate/1
OUT = ROOT / "daq" / "can" / "msid.dbc"


def constants():
    text = HDR.read_text() + EST_HDR.read_text()
    c = {}
    for name, val in re.findall(r"#define\s+(MSID_CAN_\w+)\s+\(?(0x[0-9A-Fa-f]+|\d+)u?\)?", text):
        c[name] = int(val, 0)
    for name, val in re.findall(r"(MSID_CAN_\w+)\s*=\s*(0x[0-9A-Fa-f]+|\d+)", text):
        c[name] = int(val, 0)
    return c


def sig(name, start, size, signed=False, factor=1, lo=0, hi=None, unit="", mux="", recv="HOST"):
    if hi is None:
        hi = (1 << size) - 1
    m = f" {mux}" if mux else ""
    return (f' SG_ {name}{m} : {start}|{size}@1{"-" if signed else "+"} ({factor:g},0) '
            f'[{lo:g}|{hi:g}] "{unit}" {recv}')


def header_sigs():
    return [sig("seq", 0, 24), sig("experiment", 24, 6, hi=63), sig("period_start", 30, 1),
            sig("segment_start", 31, 1)]


def generate(base):
    c = constants()
    ver = c["MSID_CAN_PROTO_VERSION"]
    L = ['VERSION "msid-can/%d"' % ver, "", "NS_ :", "\tCM_", "\tBA_DEF_", "\tBA_", "\tVAL_", "\tBA_DEF_DEF_",
         "\tSIG_VALTYPE_", "", "BS_:", "", "BU_: HOST DEVICE", ""]
    vals, valtype, fd_ids, cms = [], [], [], []
    ctrl = base + c["MSID_CAN_ID_CTRL"]
    L += [f"BO_ {ctrl} MSID_CTRL: 8 HOST", sig("command", 0, 8, recv="DEVICE"),
          sig("experiment", 8, 8, recv="DEVICE"), sig("version", 16, 8, recv="DEVICE"),
          sig("periods", 32, 32, recv="DEVICE"), ""]
    vals.append(f'VAL_ {ctrl} command 1 "start" 2 "stop" 3 "reset" 4 "query" ;')
    cfg = base + c["MSID_CAN_ID_CFG"]
    L += [f"BO_ {cfg} MSID_CFG: 8 HOST", sig("param", 0, 8, recv="DEVICE"), sig("index", 8, 24, recv="DEVICE"),
          sig("value", 32, 32, recv="DEVICE"), ""]
    params = sorted((v, k[len("MSID_CAN_P_"):].lower()) for k, v in c.items() if k.startswith("MSID_CAN_P_"))
    vals.append(f"VAL_ {cfg} param " + " ".join(f'{v} "{n}"' for v, n in params) + " ;")
    st = base + c["MSID_CAN_ID_STATUS"]
    L += [f"BO_ {st} MSID_STATUS: 8 DEVICE", sig("mux", 0, 8, mux="M"),
          sig("state", 8, 8, mux="m0"), sig("experiment", 16, 8, mux="m0"), sig("error", 24, 8, mux="m0"),
          sig("samples", 32, 32, mux="m0"),
          sig("version", 8, 8, mux="m1"), sig("n_inputs", 16, 8, mux="m1"), sig("n_outputs", 24, 8, mux="m1"),
          sig("config_crc", 32, 32, mux="m1"),
          sig("tec", 8, 8, mux="m2"), sig("rec", 16, 8, mux="m2"), sig("restarts", 24, 8, mux="m2"),
          sig("tx_dropped", 32, 32, mux="m2"), ""]
    states = sorted((v, k[len("MSID_CAN_STATE_"):].lower()) for k, v in c.items() if k.startswith("MSID_CAN_STATE_"))
    vals.append(f"VAL_ {st} state " + " ".join(f'{v} "{n}"' for v, n in states) + " ;")
    errs = sorted((v, k[len("MSID_CAN_ERR_"):].lower()) for k, v in c.items() if k.startswith("MSID_CAN_ERR_"))
    vals.append(f"VAL_ {st} error " + " ".join(f'{v} "{n}"' for v, n in errs) + " ;")
    # extension estimate/1 (msid_can_est.h): EST_CTRL host -> device, EST device -> host
    ectl = base + c["MSID_CAN_ID_EST_CTRL"]
    L += [f"BO_ {ectl} MSID_EST_CTRL: 8 HOST", sig("command", 0, 8, mux="M", recv="DEVICE"),
          sig("mode", 8, 8, mux="m1", recv="DEVICE"), sig("transient", 16, 8, mux="m1", recv="DEVICE"),
          sig("skip_periods", 32, 16, mux="m1", recv="DEVICE"),
          sig("word", 8, 8, mux="m2", recv="DEVICE"), sig("alpha_word", 32, 32, mux="m2", recv="DEVICE"), ""]
    ecmds = sorted((v, k[len("MSID_CAN_EST_CMD_"):].lower()) for k, v in c.items() if k.startswith("MSID_CAN_EST_CMD_"))
    vals.append(f"VAL_ {ectl} command " + " ".join(f'{v} "{n}"' for v, n in ecmds) + " ;")
    est = base + c["MSID_CAN_ID_EST"]
    L += [f"BO_ {est} MSID_EST: 8 DEVICE", sig("mux", 0, 8, mux="M"),
          sig("est_state", 8, 8, mux="m0"), sig("mode", 16, 8, mux="m0"), sig("ext_version", 24, 8, mux="m0"),
          sig("status", 32, 16, mux="m0"), sig("bad", 48, 16, mux="m0"),
          sig("need_bytes", 32, 32, mux="m1"), sig("have_bytes", 32, 32, mux="m2"),
          sig("doubles", 32, 32, mux="m3"), sig("periods", 32, 32, mux="m4"),
          sig("index", 8, 24, mux=f"m{c['MSID_CAN_EST_MUX_LO']}"), sig("low_word", 32, 32, mux=f"m{c['MSID_CAN_EST_MUX_LO']}"),
          sig("index", 8, 24, mux=f"m{c['MSID_CAN_EST_MUX_HI']}"), sig("high_word", 32, 32, mux=f"m{c['MSID_CAN_EST_MUX_HI']}"),
          ""]
    estates = sorted((v, k[len("MSID_CAN_EST_STATE_"):].lower()) for k, v in c.items() if k.startswith("MSID_CAN_EST_STATE_"))
    vals.append(f"VAL_ {est} est_state " + " ".join(f'{v} "{n}"' for v, n in estates) + " ;")
    fmts = [("S16", "MSID_CAN_ID_S16", 16, 8, 2, 16), ("F32", "MSID_CAN_ID_F32", 32, 8, 1, 32),
            ("FD_S16", "MSID_CAN_ID_FD_S16", 2, 64, 30, 16), ("FD_F32", "MSID_CAN_ID_FD_F32", 3, 64, 15, 32)]
    for tag, key, chunks, length, per, bits in fmts:
        for k in range(chunks):
            mid = base + c[key] + k
            L.append(f"BO_ {mid} MSID_{tag}_{k}: {length} DEVICE")
            L += header_sigs()
            for j in range(per):
                ch = k * per + j + 1
                if bits == 16:
                    L.append(sig(f"ch{ch}", 32 + 16 * j, 16, signed=True, factor=0.001, lo=-32.767, hi=32.767))
                    vals.append(f'VAL_ {mid} ch{ch} -32768 "invalid" ;')
                else:
                    L.append(sig(f"ch{ch}", 32 + 32 * j, 32, signed=True, lo=-3.4e38, hi=3.4e38))
                    valtype.append(f"SIG_VALTYPE_ {mid} ch{ch} : 1;")
            L.append("")
            if length == 64:
                fd_ids.append(mid)
    cms.append(f'CM_ "msid-can/{ver}: see docs/can-protocol.md. Identifiers for base 0x{base:X}. Channel chN is '
               f'column N of the sample row [u1..u_nu, y1..y_ny]. int16 channels: the factor is the default '
               f'SCALE 0.001; a device configured with another SCALE uses that value; raw -32768 marks an '
               f'out-of-range value.";')
    L += cms + [""]
    L.append('BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","reserved","reserved",'
             '"reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved",'
             '"StandardCAN_FD","ExtendedCAN_FD";')
    L.append('BA_DEF_ "BusType" STRING ;')
    L.append('BA_DEF_DEF_ "VFrameFormat" "StandardCAN";')
    L.append('BA_DEF_DEF_ "BusType" "CAN FD";')
    L += [f'BA_ "VFrameFormat" BO_ {i} 14;' for i in fd_ids]
    L += vals + valtype
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser(description="Generate the DBC of msid-can/1 from the protocol header.")
    ap.add_argument("--check", action="store_true", help="fail if the file differs from the generated text")
    ap.add_argument("--base", default="0x200", help="base CAN id of the device (default 0x200)")
    ap.add_argument("-o", "--output", type=Path, default=OUT, help=f"the DBC file (default {OUT.relative_to(ROOT)})")
    a = ap.parse_args()
    try:
        base = int(a.base, 0)
    except ValueError:
        ap.error(f"--base: '{a.base}' is not an integer (e.g. 0x200)")
    text = generate(base)
    out = a.output
    if a.check:
        if not out.exists() or out.read_text() != text:
            print(f"{out} is out of date: run scripts/gen_dbc.py", file=sys.stderr)
            sys.exit(1)
        print(f"{out.name} is current")
        return
    if not out.parent.is_dir():
        ap.error(f"-o {out}: directory {out.parent} does not exist")
    tmp = out.with_name(out.name + ".tmp")   # whole file or nothing
    tmp.write_text(text)
    tmp.replace(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
