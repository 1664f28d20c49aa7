// msid bench fit --only modal FRF: the order scan of a structure's FRF (`msid fit --method ml
// --domain ct --order auto`) timed as a whole process, the CPU time of its best run, beside the modal
// peer's stabilisation run on the same FRF (sdypy-EMA's LSCF over its polynomial orders 2..60, its modes
// those stable over orders 30-60; a Python process: tools/peers/msid_peers/lscf_peer.py) and, with
// --baseline, another msid executable's same scan (a previous build), all in one run on one machine.
// Prints the chosen order and its modes beside the peer's stable modes.
#include "bench_util.hpp"
#include "msid_bench.hpp"

#include "msid_host_util.hpp"
#include "msid_json_file.hpp"

#include <climits>
#include <cmath>
#include <cstdlib>

namespace msidbench {

using msidfmt::Json;
using msidutil::fmt;

namespace {

// The scan's arguments for an executable and an output path.
std::vector<std::string> scan_args(const std::string &frf, const std::string &out)
{
    return {"msid", "fit", "--method", "ml", "--domain", "ct", "--order", "auto", frf, "-o", out};
}

// "fn/zeta%" of every pair of a model file's modes, and its chosen order and rule.
std::string modes_line(const std::string &model)
{
    const Json d = msidfmt::read_json_file(model);
    std::string s = fmt("order %d (%s):", d["order_selection"]["chosen"].get<int>(),
                        d["order_selection"]["rule"].get<std::string>().c_str());
    for (const Json &m : d["modes"]["modes"])
        if (!m["real_pole"].get<bool>())
            s += fmt(" %.3f/%.2f%s", m["fn"].get<double>(), 100 * m["zeta"].get<double>(),
                     m.value("at_bound", false) ? "(bound)" : "");
    return s;
}

void fit_modal(Writer &w, const ModalBenchRequest &rq)
{
    if (rq.frf.empty()) throw msidutil::UsageError("give the FRF file: msid bench fit --only modal FRF.json");
    if (rq.runs < 1) throw msidutil::UsageError("--runs must be at least 1");
    char self[PATH_MAX];
    if (!realpath(rq.msid_exe.c_str(), self)) throw msidutil::Error("cannot resolve " + rq.msid_exe);
    w.print("msid bench fit --only modal  (msid %s)\nmachine: %s\nFRF: %s\n", MSID_VERSION, machine().c_str(),
            rq.frf.c_str());
    w.print("times: the CPU time (user + system) of the best of %u run(s) after one warm-up, per process\n\n", rq.runs);
    const std::string dir = temp_dir("msid-bench-modal");
    ModalBenchResult res;
    const Times t = time_process(self, scan_args(rq.frf, dir + "/msid.json"), 0.0, true, (int)rq.runs, true);
    w.print("  msid fit --order auto        %8.2f s CPU  (%.2f s wall)   %s\n", t.cpu, t.wall,
            modes_line(dir + "/msid.json").c_str());
    if (!rq.baseline.empty()) {
        const Times b = time_process(rq.baseline, scan_args(rq.frf, dir + "/base.json"), 0.0, true, (int)rq.runs, true);
        w.print("  baseline (%s)\n                               %8.2f s CPU  (%.2f s wall)   %s\n", rq.baseline.c_str(),
                b.cpu, b.wall, modes_line(dir + "/base.json").c_str());
        w.print("  msid / baseline              %8.2fx faster\n", b.cpu / t.cpu);
    }
    if (rq.peer) {
        const std::string script = peers_dir() + "/msid_peers/lscf_peer.py";
        try {
            // sdypy-EMA computes every polynomial order up to the highest: the stabilisation run over 2..60,
            // its modes those that recur over orders 30-60 (the orders where this FRF's modes have settled)
            const Times p = time_process("python3", {"python3", script, rq.frf, "--orders", "30:60", "-o", dir + "/lscf.json"},
                                         0.0, true, (int)rq.runs);
            const Json pj = msidfmt::read_json_file(dir + "/lscf.json");
            std::string s;
            for (const Json &m : pj["modes"]) s += fmt(" %.3f/%.2f", m[0].get<double>(), 100 * m[1].get<double>());
            w.print("  LSCF (sdypy-EMA), orders 2-60 %7.2f s CPU  (%.2f s wall)   stable over >= 80%% of orders 30-60:%s\n",
                    p.cpu, p.wall, s.c_str());
        } catch (const msidutil::Error &e) {
            w.print("  LSCF peer unavailable: %s\n", e.what());
        }
    }
    w.print("\n");
    remove_dir(w, dir, "msid bench: note: could not remove ");
}

}  // namespace

ModalBenchResult bench_fit_modal(const ModalBenchRequest &rq, const Sink &sink)
{
    return with_report<ModalBenchResult>(fit_modal, rq, sink);
}

}  // namespace msidbench
