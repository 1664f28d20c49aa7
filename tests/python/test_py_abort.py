"""No abort at the interpreter's exit while msid.measure runs in another thread.
Each case is a child interpreter (bounded in time: a hang detector) that measures msid-devsim over
Modbus TCP on 127.0.0.1 in a thread and then exits: Ctrl-C in the main thread while it joins the
measuring thread, and a daemon thread still inside msid.measure at exit. Before the fix both ended in
SIGABRT ("terminate called without an active exception": the GIL taken back in a destructor by a
thread that the exiting interpreter ends) and left the device mid-run, so that the next measurement
failed for seconds ("the device did not confirm the configuration"). Now the exit stops the run, the
device is told to stop, and the next measurement runs at once."""
import json
import signal

import pytest

from child import DESIGN, run_child, sim_module

SCRIPT = """
import json, os, signal, sys, threading
import msid
uri, how = sys.argv[1], sys.argv[2]
d = msid.design(**json.loads(sys.argv[3]))
started = threading.Event()

def progress(s):
    if s["periods_total"] >= 2:
        started.set()

def run():
    try:
        msid.measure(uri, d, periods=4000, rate=2000, progress=progress)
    except BaseException as e:   # the stop at exit ends the run (KeyboardInterrupt)
        print("measure ended:", type(e).__name__, flush=True)

t = threading.Thread(target=run, daemon=(how == "daemon"))
t.start()
if not started.wait(60):
    print("the measurement did not start", flush=True)
    os._exit(3)
print("measuring", flush=True)
if how == "join":
    # Ctrl-C while the main thread waits for the measuring thread: KeyboardInterrupt ends the main
    # thread, and CPython 3.11 lets the shutdown proceed with the thread still measuring
    threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
    t.join()
sys.exit(0)
"""


@pytest.mark.parametrize("how", ["join", "daemon"])
def test_exit_while_measuring_in_a_thread(tmp_path, how):
    mblib = sim_module()
    import msid
    d = msid.design(**DESIGN)
    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        uri = f"modbus-tcp://127.0.0.1:{sim.port}"
        r = run_child(SCRIPT, uri, how, json.dumps(DESIGN))
        assert "measuring" in r.stdout, (r.stdout, r.stderr)
        assert r.returncode != -signal.SIGABRT and "terminate called" not in r.stderr, (r.returncode, r.stderr)
        # a clean end: exit status 0, or the KeyboardInterrupt of Ctrl-C (the interpreter re-raises SIGINT)
        assert r.returncode in (0, 1, -signal.SIGINT, 130), (r.returncode, r.stderr)
        # the device was told to stop: the next measurement runs (before: "did not confirm the configuration")
        f = msid.measure(uri, d, periods=3, skip_periods=1, timeout=5)
        assert f.meta["complete"] is True
