#!/usr/bin/env python3
"""Boot Debian's kernel under qemu (TCG) with real SocketCAN and run one job in it.

The host kernel here has no AF_CAN, so the CAN tests run inside a small VM:
  - kernel: the linux-image-*-amd64 package that linux-image-amd64 depends on,
    fetched with `apt-get download` and unpacked with `dpkg -x` by
    scripts/deps.sh into $MSID_VCAN_DIR (default /var/cache/msid-vcan/k);
  - initramfs: busybox-static plus the CAN, virtio and 9p modules and sch_tbf
    (token-bucket qdisc: the ENOBUFS test), built here in a temporary
    directory on every run (a few MB, well under a second);
  - the host root is shared read-only over 9p (`-virtfs ... readonly=on`) and
    chrooted into, so the guest runs the host's own build and python (also from
    a checkout under /tmp); a second 9p share (read-write) is the results
    directory; TMPDIR and HOME are a tmpfs at /dev/shm;
  - vcan0 (CAN FD capable, MTU 72) and vcan1 (classic only, MTU 16) are
    created with `ip link add dev vcanN type vcan`.
The job is a shell command run in the chroot with the results directory as
working directory; its exit status is this script's exit status. Any failure
to build or boot the VM is an error (exit 3), never a skip.

usage: vm.py [--results DIR] [--timeout S] [--mem MB] -- command args...
"""
import argparse
import glob
import gzip
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

MODULES = ["can", "can-raw", "can-bcm", "can-dev", "vcan", "virtio_ring", "virtio", "virtio_pci_modern_dev",
           "virtio_pci_legacy_dev", "virtio_pci", "netfs", "fscache", "9pnet", "9pnet_virtio", "9p",
           "sch_tbf"]   # can-bcm: the CANopen SYNC producer (in_vm/test_canopen.py); sch_tbf: a rate-limited vcan0 makes sends fail with ENOBUFS (in_vm/test_enobufs.py)
KDIR = os.environ.get("MSID_VCAN_DIR", "/var/cache/msid-vcan/k")
QEMU = "qemu-system-x86_64"
BUSYBOX = "/bin/busybox"

INIT = r"""#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc; mount -t sysfs sys /sys; mount -t devtmpfs dev /dev
for m in {modules}; do insmod /lib/modules/$m.ko || echo "VM-ERROR: insmod $m failed"; done
ip link set lo up
ip link add dev vcan0 type vcan && ip link set vcan0 mtu 72 && ip link set vcan0 up || echo "VM-ERROR: vcan0"
ip link add dev vcan1 type vcan && ip link set vcan1 mtu 16 && ip link set vcan1 up || echo "VM-ERROR: vcan1"
mkdir -p /host
mount -t 9p -o trans=virtio,version=9p2000.L,ro host /host || echo "VM-ERROR: mount host"
mount -t proc proc /host/proc; mount -t sysfs sys /host/sys; mount -t devtmpfs dev /host/dev
mkdir -p /host/dev/shm && mount -t tmpfs -o size=1g,mode=1777 tmpfs /host/dev/shm
mkdir -p /host{results} 2>/dev/null
mount -t 9p -o trans=virtio,version=9p2000.L,rw,cache=none results /host{results} || echo "VM-ERROR: mount results"
echo VM-READY
chroot /host /bin/sh -c 'cd {results} && HOME=/dev/shm TMPDIR=/dev/shm PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin sh ./job.sh > job.log 2>&1; echo $? > job.rc'
sync
poweroff -f
"""


def die(msg):
    print(f"vm.py: error: {msg}", file=sys.stderr)
    sys.exit(3)


def kernel_files():
    vml = sorted(glob.glob(os.path.join(KDIR, "boot", "vmlinuz-*")))
    if not vml:
        die(f"no kernel under {KDIR}/boot: run scripts/deps.sh (it downloads Debian's linux-image package)")
    ver = os.path.basename(vml[-1])[len("vmlinuz-"):]
    mdir = os.path.join(KDIR, "lib", "modules", ver)
    mods = []
    for m in MODULES:
        hits = [p for p in glob.glob(os.path.join(mdir, "kernel", "**", "*.ko*"), recursive=True)
                if os.path.basename(p).split(".ko")[0].replace("_", "-") == m.replace("_", "-")]
        if not hits:
            die(f"module {m} not found under {mdir}")
        mods.append(hits[0])
    return vml[-1], mods


def build_initramfs(work, mods, results):
    root = os.path.join(work, "root")
    for d in ("bin", "proc", "sys", "dev", "lib/modules", "host"):
        os.makedirs(os.path.join(root, d), exist_ok=True)
    if not os.path.exists(BUSYBOX):
        die("busybox-static is not installed (scripts/deps.sh installs it)")
    shutil.copy(BUSYBOX, os.path.join(root, "bin", "busybox"))
    names = []
    for p in mods:
        base = os.path.basename(p)
        name = base.split(".ko")[0]
        dst = os.path.join(root, "lib", "modules", name + ".ko")
        if base.endswith(".ko.xz"):
            subprocess.run(["xz", "-dc", p], stdout=open(dst, "wb"), check=True)
        elif base.endswith(".ko.zst"):
            subprocess.run(["zstd", "-dcq", p], stdout=open(dst, "wb"), check=True)
        else:
            shutil.copy(p, dst)
        names.append(name)
    init = os.path.join(root, "init")
    with open(init, "w") as f:
        f.write(INIT.format(modules=" ".join(names), results=results))
    os.chmod(init, 0o755)
    img = os.path.join(work, "initrd.gz")
    files = subprocess.run(["find", "."], cwd=root, capture_output=True, text=True, check=True).stdout
    cpio = subprocess.run(["busybox", "cpio", "-o", "-H", "newc"], cwd=root, input=files.encode(),
                          capture_output=True, check=True).stdout
    with gzip.open(img, "wb", compresslevel=1) as f:
        f.write(cpio)
    return img


def run_in_vm(command, results, timeout=900, mem=2048, smp=2, quiet=False):
    """Run `command` (a shell string) in the VM; returns its exit status."""
    if not shutil.which(QEMU):
        die(f"{QEMU} not found: install Debian's qemu-system-x86 (scripts/deps.sh does)")
    results = os.path.abspath(results)
    os.makedirs(results, exist_ok=True)
    for f in ("job.rc", "job.log"):
        if os.path.exists(os.path.join(results, f)):
            os.unlink(os.path.join(results, f))
    with open(os.path.join(results, "job.sh"), "w") as f:
        f.write("set -u\n")
        # the guest runs the host's interpreter and sees the test environment
        f.write(f"export PATH={shlex.quote(os.path.dirname(sys.executable) + ':' + os.environ.get('PATH', '/usr/bin:/bin'))}\n")
        for k, v in sorted(os.environ.items()):
            if k.startswith("MSID_") or k in ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE"):
                f.write(f"export {k}={shlex.quote(v)}\n")
        f.write(command + "\n")
    vmlinuz, mods = kernel_files()
    with tempfile.TemporaryDirectory(prefix="msid-vm-") as work:
        initrd = build_initramfs(work, mods, results)
        cmd = [QEMU, "-accel", "tcg", "-cpu", "max", "-m", str(mem), "-smp", str(smp), "-nographic", "-no-reboot",
               "-kernel", vmlinuz, "-initrd", initrd,
               "-append", "console=ttyS0 panic=-1 quiet loglevel=3",
               "-virtfs", "local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap",
               "-virtfs", f"local,path={results},mount_tag=results,security_model=none",
               "-nic", "none"]
        t0 = time.monotonic()
        console = os.path.join(results, "console.log")
        with open(console, "wb") as con:
            try:
                p = subprocess.run(cmd, stdin=subprocess.DEVNULL, stdout=con, stderr=subprocess.STDOUT,
                                   timeout=timeout)
            except subprocess.TimeoutExpired:
                die(f"the VM did not finish within {timeout} s (console: {console})")
        dt = time.monotonic() - t0
    text = open(console, "rb").read().decode("utf-8", "replace")
    errs = [l for l in text.splitlines() if "VM-ERROR" in l]
    if errs:
        die("VM setup failed: " + "; ".join(errs) + f" (console: {console})")
    rcf = os.path.join(results, "job.rc")
    if p.returncode != 0 or not os.path.exists(rcf):
        die(f"the VM failed (qemu exit {p.returncode}, no job status); console: {console}\n" + text[-3000:])
    rc = int(open(rcf).read().strip() or "1")
    if not quiet:
        sys.stdout.write(open(os.path.join(results, "job.log"), errors="replace").read())
        print(f"vm.py: VM ran {dt:.1f} s, job exit status {rc}")
    return rc


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", default=None, help="writable results directory (default: a new temporary one)")
    ap.add_argument("--timeout", type=float, default=900)
    ap.add_argument("--mem", type=int, default=2048)
    ap.add_argument("command", nargs=argparse.REMAINDER)
    a = ap.parse_args()
    cmd = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not cmd:
        ap.error("give a command after --")
    results = a.results or tempfile.mkdtemp(prefix="msid-vcan-")
    sys.exit(run_in_vm(" ".join(shlex.quote(c) for c in cmd), results, a.timeout, a.mem))


if __name__ == "__main__":
    main()
