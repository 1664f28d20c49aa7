"""No deadlock when msid is called from a measurement's progress callable, or from
another thread while msid.measure runs. Each case is a child interpreter bounded in time (a hang
detector): before the fix msid.frf, Measurement.push/.frf(), freeing a Measurement and a nested
msid.measure inside the callable waited for ever for the FFTW planner lock that the measurement holds
(SIGINT ignored), and a Measurement freed in the main thread while a thread measured waited for it with
the GIL held, which the measuring thread needs. Now the lock is the thread's own (reentrant): those
calls run in the callable, a nested measurement is refused with a clear RuntimeError, and a
destructor never waits."""
import json

from child import DESIGN, run_child, sim_module

IN_CALLBACK = """
import json, sys
import numpy as np
import msid
uri = sys.argv[1]
d = msid.design(**json.loads(sys.argv[2]))
small = msid.design(period=64, lines="1:5", amplitudes=0.5, seed=3, periods=4)
u = small.samples(0, 4)
rec = np.column_stack([u[:, 0], 0.5 * u[:, 0]])
done = {}

def progress(s):
    if done or s["periods_total"] < 2:
        return
    f = msid.frf(rec, design=small)
    done["frf_lines"] = int(f.n_lines)
    m = msid.Measurement(design=small)
    m.push(rec, experiment=0)
    done["measurement_lines"] = int(m.frf().n_lines)
    m2 = msid.Measurement(design=small)
    m2.push(rec[:100], experiment=0)
    del m2                       # freed while the measurement holds the planner lock
    done["freed"] = True
    try:
        msid.measure(uri, d, periods=3)
        done["nested"] = "ran"
    except RuntimeError as e:
        done["nested"] = str(e)

f = msid.measure(uri, d, periods=4, skip_periods=1, progress=progress)
done["complete"] = f.meta["complete"]
print(json.dumps(done))
"""

FREE_BESIDE = """
import json, sys, threading
import msid
uri = sys.argv[1]
d = msid.design(**json.loads(sys.argv[2]))
small = msid.design(period=64, lines="1:5", amplitudes=0.5, seed=3, periods=4)
started = threading.Event()
out = {}

def run():
    out["f"] = msid.measure(uri, d, periods=60, rate=2000, progress=lambda s: started.set())

ms = []
for k in range(3):   # each with its job (FFTW plans) made before the measurement starts
    m = msid.Measurement(design=small)
    m.push(small.samples(0, 1).repeat(2, axis=1), experiment=0)
    ms.append(m)
t = threading.Thread(target=run)
t.start()
assert started.wait(60)
del m
ms.clear()   # freed with the GIL held while the measuring thread holds the planner lock
t.join()
print(json.dumps({"complete": out["f"].meta["complete"]}))
"""


def test_msid_calls_inside_the_progress_callable(tmp_path):
    mblib = sim_module()
    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        r = run_child(IN_CALLBACK, f"modbus-tcp://127.0.0.1:{sim.port}", json.dumps(DESIGN))
    assert r.returncode == 0, r.stderr
    done = json.loads(r.stdout.strip().splitlines()[-1])
    assert done["frf_lines"] == 5 and done["measurement_lines"] == 5 and done["freed"] is True
    assert "msid.measure cannot run inside the progress callable of another msid.measure" in done["nested"]
    assert done["complete"] is True


def test_measurement_freed_beside_a_measuring_thread(tmp_path):
    mblib = sim_module()
    with mblib.Sim(tmp_path, "--seed", 5) as sim:
        r = run_child(FREE_BESIDE, f"modbus-tcp://127.0.0.1:{sim.port}", json.dumps(DESIGN))
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {"complete": True}
