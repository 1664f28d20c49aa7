#!/usr/bin/env python3
"""Flash and RAM per object from a GNU ld map file (-Wl,-Map), for `msid bench target`.

usage: map_sizes.py FILE.map
Sums the input sections (.text*, .rodata*, .ARM.* -> flash; .data* -> flash and
RAM; .bss* -> RAM) that the linker kept, per member of libmsid.a, and groups the
rest (C library and libgcc, startup, the program itself).
"""
import collections
import re
import sys

SEC = re.compile(r'^ (\.(?:text|rodata|data|bss|ARM)[^\s]*)\s*\n?\s+0x[0-9a-f]+\s+0x([0-9a-f]+)\s+(\S+)', re.M)


def main(path):
    txt = open(path).read()
    # only what was kept: the part of the map after "Linker script and memory map"
    k = txt.find('Linker script and memory map')
    txt = txt[k:] if k >= 0 else txt
    flash, ram = collections.Counter(), collections.Counter()
    for m in SEC.finditer(txt):
        sec, size, src = m.group(1), int(m.group(2), 16), m.group(3)
        if 'libmsid.a(' in src:
            who = re.search(r'\((.*?)(?:\.c)?\.obj\)', src).group(1)
        elif re.search(r'lib(c|m|g|gcc|rdimon|nosys)(_nano)?\.a', src):
            who = '(C library, libgcc)'
        elif 'startup_mps2' in src:
            who = '(startup)'
        else:
            who = '(program)'
        if sec.startswith('.bss'):
            ram[who] += size
        elif sec.startswith('.data'):
            ram[who] += size
            flash[who] += size
        else:
            flash[who] += size
    print(f"  {'object':22s} {'flash':>7s} {'RAM':>7s}")
    for who in sorted(set(flash) | set(ram)):
        print(f"  {who:22s} {flash[who]:7d} {ram[who]:7d}")
    lib = sum(v for w, v in flash.items() if w.startswith('msid_'))
    print(f"  {'libmsid total':22s} {lib:7d} {sum(v for w, v in ram.items() if w.startswith('msid_')):7d}")


if __name__ == '__main__':
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
