"""map_peer.py's register codec, written from docs/devices.md with struct: int16, uint16, int32, uint32, float32,
float64 in word order ABCD (big-endian, high register first), CDAB (registers in reverse order), BADC (bytes
swapped in each register) or DCBA (both); physical value = raw x scale + offset."""
import math
import struct

from map_peer_files import TYPES

INT_RANGE = {"int16": (-2 ** 15, 2 ** 15 - 1), "uint16": (0, 2 ** 16 - 1), "int32": (-2 ** 31, 2 ** 31 - 1),
             "uint32": (0, 2 ** 32 - 1)}
FLOAT32_MAX = struct.unpack(">f", b"\x7f\x7f\xff\xff")[0]


def raw_to_regs(c, raw):
    """The registers of a raw value (an int for integer types, a float for float types) in c's word order."""
    fmt, n = TYPES[c.type]
    b = struct.pack(">" + fmt, raw)
    regs = list(struct.unpack(("<" if c.word_order in ("BADC", "DCBA") else ">") + "H" * n, b))
    return regs[::-1] if c.word_order in ("CDAB", "DCBA") else regs


def regs_to_raw(c, regs):
    fmt, n = TYPES[c.type]
    regs = list(regs)[::-1] if c.word_order in ("CDAB", "DCBA") else list(regs)
    b = struct.pack(("<" if c.word_order in ("BADC", "DCBA") else ">") + "H" * n, *regs)
    return struct.unpack(">" + fmt, b)[0]


def encode(c, v):
    """A physical value as c's registers: raw = (v - offset) / scale, integers rounded to nearest and saturated
    at the type's range, float32 beyond its range as an infinity (what a device's conversion does)."""
    raw = (v - c.offset) / c.scale
    if c.type in INT_RANGE:
        lo, hi = INT_RANGE[c.type]
        raw = lo if math.isnan(raw) or raw <= lo else hi if raw >= hi else round(raw)   # NaN: the low end
    elif c.type == "float32" and abs(raw) > FLOAT32_MAX:
        raw = math.copysign(math.inf, raw)
    return raw_to_regs(c, raw)


def decode(c, regs):
    return regs_to_raw(c, regs) * c.scale + c.offset


def counter_regs(c, k):
    """Cycle count k in a counter channel: an integer type wraps at its range (two's complement), a float type
    holds the count itself."""
    if c.type in INT_RANGE:
        bits = 16 * c.nregs
        u = k % (1 << bits)
        if c.type.startswith("int") and u >= 1 << (bits - 1):
            u -= 1 << bits
        return raw_to_regs(c, u)
    return raw_to_regs(c, float(k))
