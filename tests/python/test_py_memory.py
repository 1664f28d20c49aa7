"""A range of lines is checked before anything is sized from it. Before the fix
msid.frf(..., lines="1:1000000000") expanded the string into a Python list first (24 GB: the kernel
killed the interpreter; under a memory limit an empty MemoryError), and "1:10000000" built a list of
ten million integers before msid said "beyond Nyquist"; detect_lines and design(lines=...) did the
same. Each case runs in a child interpreter whose address space is limited to what it uses at the
start plus 160 MiB, far below such lists: now the range is refused unexpanded, or expanded only up
to its first bin beyond Nyquist, with msid's message."""
import json

from child import run_child

SCRIPT = """
import json, resource
import numpy as np
import msid

def vm_bytes():
    for line in open("/proc/self/status"):
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024

u = msid.design(period=256, lines="1:3:60", amplitudes=0.3, seed=2).samples(0, 8)
rec = np.column_stack([u[:, 0], 0.5 * u[:, 0]])   # periodic: the line checks are reached
limit = vm_bytes() + (160 << 20)
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
out = {}
cases = {
    "frf_huge": lambda: msid.frf(rec, period=256, lines="1:1000000000", n_inputs=1),
    "frf_long": lambda: msid.frf(rec, period=256, lines="1:10000000", n_inputs=1),
    "frf_step": lambda: msid.frf(rec, period=256, lines="1:3:30000000", n_inputs=1),
    "detect": lambda: msid.frf(rec, period=256, lines="1:3:60", detect_lines="100:2:20000000", n_inputs=1),
    "design": lambda: msid.design(period=256, lines="1:40000000"),
    "design_huge": lambda: msid.design(period=4096, lines="5,1:4000000000"),
}
for name, call in cases.items():
    try:
        call()
        out[name] = "no error"
    except BaseException as e:
        out[name] = f"{type(e).__name__}: {e}"
print(json.dumps(out))
"""


def test_ranges_are_checked_before_they_are_expanded():
    r = run_child(SCRIPT)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["frf_huge"] == "ValueError: lines: range '1:1000000000' is too long", out
    assert out["frf_long"] == "ValueError: line 128 is at or beyond Nyquist: lines must be below P/2 = 128", out
    assert out["frf_step"] == "ValueError: line 130 is at or beyond Nyquist: lines must be below P/2 = 128", out
    assert out["detect"].startswith("ValueError: detection line 128 must lie strictly between DC and Nyquist"), out
    assert out["design"].startswith("ValueError: line 128 is at or beyond Nyquist"), out
    assert out["design_huge"] == "ValueError: lines: range '1:4000000000' is too long", out
