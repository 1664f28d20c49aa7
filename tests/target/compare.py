#!/usr/bin/env python3
"""Compare the output of one program run on the host and on an emulated target.

usage: compare.py [--max-ulp GROUP=N ...] -- HOST_CMD... --target TARGET_CMD...

Both commands must exit 0. Lines starting with '#' describe the platform and
are skipped. 'libm NAME x y ...' lines: numbers within 1e-12 relative.
'v GROUP hex hex ...' lines: IEEE-754 doubles as hex bit patterns; equal, or
at most N ulps apart where --max-ulp GROUP=N is given (the count of values
that differ is printed). Every other line must be identical.
"""
import struct
import subprocess
import sys


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        sys.exit(f"compare: {' '.join(cmd)} exited with {p.returncode}\n{p.stdout[-2000:]}{p.stderr[-2000:]}")
    return [l for l in p.stdout.splitlines() if not l.startswith('#')]


def as_int(h):
    """Bits of a double as a signed, monotonic integer (for ulp distance)."""
    i = int(h, 16)
    return i if i < (1 << 63) else (1 << 63) - i


def main(argv):
    max_ulp = {}
    while argv and argv[0] == '--max-ulp':
        g, n = argv[1].split('=')
        max_ulp[g] = int(n)
        argv = argv[2:]
    if not argv or argv[0] != '--' or '--target' not in argv:
        sys.exit(__doc__)
    k = argv.index('--target')
    host, target = run(argv[1:k]), run(argv[k + 1:])
    if len(host) != len(target):
        sys.exit(f"compare: {len(host)} lines on the host, {len(target)} on the target")
    if not host:
        sys.exit("compare: no output")
    differ, worst, bad = {}, {}, 0
    for n, (a, b) in enumerate(zip(host, target), 1):
        if a == b:
            continue
        fa, fb = a.split(), b.split()
        if fa[:2] != fb[:2] or len(fa) != len(fb):
            print(f"line {n}: host '{a}' target '{b}'")
            bad += 1
        elif fa[0] == 'libm':
            for x, y in zip(fa[2:], fb[2:]):
                x, y = float(x), float(y)
                if abs(x - y) > 1e-12 * max(abs(x), abs(y)):
                    print(f"line {n}: {fa[1]}: {x!r} vs {y!r} beyond 1e-12 relative")
                    bad += 1
        elif fa[0] == 'v':
            g = fa[1]
            for x, y in zip(fa[2:], fb[2:]):
                d = abs(as_int(x) - as_int(y))
                if d:
                    differ[g] = differ.get(g, 0) + 1
                    worst[g] = max(worst.get(g, 0), d)
                if d > max_ulp.get(g, 0):
                    print(f"line {n}: {g}: {x} vs {y}: {d} ulp (allowed {max_ulp.get(g, 0)})")
                    bad += 1
        else:
            print(f"line {n}: host '{a}' target '{b}'")
            bad += 1
    for g in sorted(set(max_ulp) | set(differ)):
        print(f"{g}: {differ.get(g, 0)} value(s) differ from the host, worst {worst.get(g, 0)} ulp "
              f"(allowed {max_ulp.get(g, 0)})")
    print(f"compared {len(host)} lines: {'OK' if bad == 0 else f'{bad} mismatch(es)'}")
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
