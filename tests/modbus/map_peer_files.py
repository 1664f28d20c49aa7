"""The inputs of map_peer.py, read as docs/devices.md and msid-devsim's plant format describe them (nothing of
msid is imported): the msid-device/1 description with Python's tomllib, and the discrete-time plant file."""
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


class Refused(Exception):
    """A description, plant or option the peer cannot serve: the message names the file and the key."""


# ---- the description (docs/devices.md) -------------------------------------------------------------------

TYPES = {"int16": ("h", 1), "uint16": ("H", 1), "int32": ("i", 2), "uint32": ("I", 2), "float32": ("f", 2),
         "float64": ("d", 4)}
WORD_ORDERS = ("ABCD", "CDAB", "BADC", "DCBA")
ROLES = ("input", "output", "reference", "counter")
TOP_KEYS = {"format", "transport", "name", "unit", "fc23", "fade_periods", "clock", "cycle_hz", "dbc",
            "drive", "measure"}
CHANNEL_KEYS = {"name", "unit", "role", "scale", "offset", "register", "type", "word_order", "message", "signal",
                "min", "max", "max_step", "safe", "operating_point", "amplitude", "reads_back"}


@dataclass
class Channel:
    name: str
    kind: str                 # "drive" or "measure"
    table: str                # "holding" or "input"
    addr: int                 # first register, 0-based
    type: str
    word_order: str = "ABCD"
    scale: float = 1.0
    offset: float = 0.0
    role: str = ""            # measure channels
    safe: float = math.nan    # drive channels
    lo: float = -math.inf
    hi: float = math.inf
    max_step: float = math.inf
    reads_back: int = -1      # input channels: the drive channel they read back

    @property
    def nregs(self):
        return TYPES[self.type][1]


@dataclass
class Description:
    path: str
    unit: int
    cycle_hz: float           # NaN: not stated
    drive: list = field(default_factory=list)
    measure: list = field(default_factory=list)

    def outputs(self):
        return [c for c in self.measure if c.role == "output"]


def _number(where, t, key, default):
    v = t.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise Refused(f"{where}: {key} must be a number (got {v!r})")
    return float(v)


def _channel(path, t, kind):
    if not isinstance(t, dict):
        raise Refused(f"{path}: [[{kind}]] must be an array of tables")
    name = t.get("name")
    if not isinstance(name, str) or not name:
        raise Refused(f"{path}: a [[{kind}]] table without a name")
    where = f"{path}: {kind} channel '{name}'"
    unknown = sorted(set(t) - CHANNEL_KEYS)
    if unknown:
        raise Refused(f"{where}: unknown key '{unknown[0]}'")
    reg = t.get("register")
    if not isinstance(reg, str) or ":" not in reg:
        raise Refused(f"{where}: register must be \"holding:N\" or \"input:N\" (got {reg!r})")
    table, _, num = reg.partition(":")
    if table not in ("holding", "input") or not num.isdigit() or int(num) > 65535:
        raise Refused(f"{where}: register = \"{reg}\": must be \"holding:N\" or \"input:N\", N in 0..65535")
    typ = t.get("type")
    if typ not in TYPES:
        raise Refused(f"{where}: type = {typ!r}: must be one of {', '.join(TYPES)}")
    wo = t.get("word_order", "ABCD")
    if wo not in WORD_ORDERS:
        raise Refused(f"{where}: word_order = {wo!r}: must be one of {', '.join(WORD_ORDERS)}")
    c = Channel(name=name, kind=kind, table=table, addr=int(num), type=typ, word_order=wo,
                scale=_number(where, t, "scale", 1.0), offset=_number(where, t, "offset", 0.0))
    if c.scale == 0:
        raise Refused(f"{where}: scale must not be 0")
    if c.addr + c.nregs > 65536:
        raise Refused(f"{where}: register = \"{reg}\": a {typ} there runs past register 65535")
    if kind == "drive":
        if table != "holding":
            raise Refused(f"{where}: a drive channel is a holding register (got \"{reg}\")")
        if "safe" not in t:
            raise Refused(f"{where}: no safe value (key safe)")
        c.safe = _number(where, t, "safe", 0.0)
        c.lo = _number(where, t, "min", -math.inf)
        c.hi = _number(where, t, "max", math.inf)
        c.max_step = _number(where, t, "max_step", math.inf)
    else:
        c.role = t.get("role")
        if c.role not in ROLES:
            raise Refused(f"{where}: role = {c.role!r}: must be one of {', '.join(ROLES)}")
        c.reads_back = t.get("reads_back", "")
    return c


def _check_overlaps(d):
    owner = {}
    for c in d.drive + d.measure:
        for a in range(c.addr, c.addr + c.nregs):
            other = owner.setdefault((c.table, a), c.name)
            if other != c.name:
                raise Refused(f"{d.path}: channels '{other}' and '{c.name}' overlap at {c.table}:{a}")


def _resolve_readback(d):
    names = [c.name for c in d.drive]
    k = 0
    for c in d.measure:
        if c.role != "input":
            if c.reads_back:
                raise Refused(f"{d.path}: measure channel '{c.name}': reads_back goes with role = \"input\"")
            c.reads_back = -1
            continue
        if c.reads_back:
            if c.reads_back not in names:
                raise Refused(f"{d.path}: measure channel '{c.name}': reads_back = \"{c.reads_back}\" names no "
                              "drive channel")
            c.reads_back = names.index(c.reads_back)
        else:
            c.reads_back = k
            if k >= len(names):
                raise Refused(f"{d.path}: measure channel '{c.name}': more input channels than drive channels")
        k += 1


def read_description(path):
    """The description at path as a Description (Refused with a message naming the file and the key)."""
    try:
        with open(path, "rb") as f:
            t = tomllib.load(f)
    except OSError as e:
        raise Refused(f"cannot read the description {path}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise Refused(f"{path}: not TOML: {e}") from None
    if t.get("format") != "msid-device/1":
        raise Refused(f"{path}: format = {t.get('format')!r}: the peer reads \"msid-device/1\"")
    if t.get("transport") != "modbus":
        raise Refused(f"{path}: transport = {t.get('transport')!r}: the peer serves \"modbus\"")
    unknown = sorted(set(t) - TOP_KEYS)
    if unknown:
        raise Refused(f"{path}: unknown key '{unknown[0]}'")
    unit = t.get("unit", 0)
    if isinstance(unit, bool) or not isinstance(unit, int) or not 0 <= unit <= 247:
        raise Refused(f"{path}: unit must be an integer in 0..247 (got {unit!r})")
    cyc = _number(path, t, "cycle_hz", math.nan)
    if not (math.isnan(cyc) or cyc > 0):
        raise Refused(f"{path}: cycle_hz must be positive (got {cyc:g})")
    d = Description(path=str(path), unit=unit or 1, cycle_hz=cyc)
    for kind in ("drive", "measure"):
        tables = t.get(kind, [])
        if not isinstance(tables, list):
            raise Refused(f"{path}: {kind} must be an array of tables: [[{kind}]]")
        getattr(d, kind).extend(_channel(path, x, kind) for x in tables)
    names = [c.name for c in d.drive + d.measure]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup:
        raise Refused(f"{path}: two channels are named '{dup}'")
    if not d.drive or not d.outputs():
        raise Refused(f"{path}: the peer needs at least one [[drive]] and one measure channel with role = \"output\"")
    _check_overlaps(d)
    _resolve_readback(d)
    return d


# ---- the plant (msid-devsim's plant file format) ---------------------------------------------------------

def read_plant(path):
    """A DT state space from a plant file: 'type dt states N inputs NU outputs NY' then A (N*N), B (N*NU),
    C (NY*N) and D (NY*NU, optional) row-major; '#' starts a comment. Returns (A, B, C, D)."""
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise Refused(f"cannot read the plant file {path}: {e.strerror}") from None
    toks = " ".join(line.split("#", 1)[0] for line in text.splitlines()).split()
    dims, mats, i = {}, {}, 0
    while i < len(toks):
        key = toks[i]
        if key in ("type", "states", "inputs", "outputs", "h"):
            if i + 1 >= len(toks):
                raise Refused(f"{path}: '{key}' has no value")
            dims[key] = toks[i + 1]
            i += 2
            continue
        if key not in ("A", "B", "C", "D"):
            raise Refused(f"{path}: unknown key '{key}'")
        try:
            n, nu, ny = (int(dims[k]) for k in ("states", "inputs", "outputs"))
        except (KeyError, ValueError):
            raise Refused(f"{path}: give states, inputs and outputs (integers) before the matrices") from None
        shape = {"A": (n, n), "B": (n, nu), "C": (ny, n), "D": (ny, nu)}[key]
        cnt = shape[0] * shape[1]
        vals = toks[i + 1:i + 1 + cnt]
        try:
            x = np.array([float(v) for v in vals])
        except ValueError:
            raise Refused(f"{path}: {key} holds something that is not a number") from None
        if len(vals) < cnt or not np.all(np.isfinite(x)):
            raise Refused(f"{path}: {key} needs {cnt} finite numbers")
        mats[key] = x.reshape(shape)
        i += 1 + cnt
    if dims.get("type") != "dt":
        raise Refused(f"{path}: the device steps a discrete-time plant on its cycle: type must be dt")
    if "states" not in dims or not all(k in mats for k in "ABC" if int(dims["states"])):
        raise Refused(f"{path}: needs type, states, inputs, outputs and A, B, C (D optional)")
    n, nu, ny = (int(dims[k]) for k in ("states", "inputs", "outputs"))
    z = np.zeros
    return (mats.get("A", z((n, n))), mats.get("B", z((n, nu))), mats.get("C", z((ny, n))),
            mats.get("D", z((ny, nu))))
