"""What a tick loop costs, and the end of the report, for the tick benches (tests/modbus/bench_ticks.py, tests/vcan/in_vm/bench_ticks_can.py):
the CPU seconds of a child process, and the user-space instructions it ran under callgrind, which no load changes."""
import json
import resource
import subprocess
from pathlib import Path


def child_cpu(cmd, timeout=1800):
    """Run cmd; its result (stdout, stderr, exit status) and the CPU seconds it used (getrusage of the waited child)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def callgrind_ir(cmd, tmp, tag, timeout=3600):
    """Instructions the process ran in user space (valgrind --tool=callgrind), from its summary line."""
    out = Path(tmp) / f"cg-{tag}.out"
    r = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *[str(c) for c in cmd]],
                       capture_output=True, text=True, timeout=timeout)
    for line in r.stderr.splitlines():
        if "Collected :" in line:
            return int(line.split(":")[-1].strip().replace(",", ""))
    raise RuntimeError(f"callgrind gave no count for {tag}: {r.stderr[-500:]}")


def finish(rows, json_path=None):
    """The end of a tick bench's report: how each loop was scheduled, and every figure to `json_path` if given."""
    for name, r in rows.items():
        if "scheduling" in r:
            print(f"  {name}: {r['scheduling']}")
    if json_path:
        Path(json_path).write_text(json.dumps(rows, indent=1))
