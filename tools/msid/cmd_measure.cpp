// msid measure: the main command. One device URI, one output directory: configure the device,
// run every experiment with live progress, write OUTDIR/frf.json (and design.json), optionally
// fit OUTDIR/model.json, and plot (bode.png, bode.svg, report.html) through the Python package.
// Ctrl-C keeps every complete period. docs/measure.md.
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"
#include "measure_outputs.hpp"

#include <csignal>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <sys/stat.h>
#include <unistd.h>

namespace msidcli {

static const char *MEASURE_HELP =
    "usage: msid measure --device URI (--design design.json | --period P --lines L [design options])\n"
    "                    [--map DEVICE.toml --rate HZ [--no-realtime]]\n"
    "                    [--periods K] [--skip-periods K] [--rate HZ] [--fs HZ]\n"
    "                    [--fit subspace|ml [--order n|auto]] [--no-plots] [--quiet] -o OUTDIR\n"
    "\n"
    "Configure the device, run every experiment, and write OUTDIR/frf.json (msid-frf/1 with its\n"
    "covariance, \"complete\" and an `acquisition` block), OUTDIR/design.json, with --fit\n"
    "OUTDIR/model.json (msid fit), and the Bode plots OUTDIR/bode.png, bode.svg and report.html\n"
    "(Python package msid: tools/python). Progress goes to stderr: one rewritten line on a terminal,\n"
    "one line per event otherwise. Ctrl-C stops cleanly: the FRF of the complete periods is written\n"
    "marked \"complete\": false, --fit is skipped with one line saying how to fit it later, the plots\n"
    "say INCOMPLETE (exit status 130). Every file is written atomically.\n"
    "\n"
    "  --device URI      modbus-tcp://HOST[:PORT][?unit=N]               (port 502 by default)\n"
    "                    modbus-rtu:///dev/ttyX?baud=N[&parity=N|E|O&unit=N&data-bits=8&stop-bits=1]\n"
    "                    can://IFACE[?fd=1&base=0x200]                   (SocketCAN, msid-can/1)\n"
    "  --map FILE        the device is described by FILE (msid-device/1, docs/devices.md): a PLC, drive or\n"
    "                    I/O module with its own register map. msid generates the excitation, writes the\n"
    "                    drive channels and reads the measure channels once per tick at --rate HZ (required,\n"
    "                    any real rate), checks every value against the limits first, and writes the safe\n"
    "                    values on every way out. Check the device first: msid device check --map FILE\n"
    "  --no-realtime     with --map: do not ask for SCHED_FIFO and locked memory\n"
    "  --design FILE     msid-design/1 (msid excite), or design options:\n"
    "  --period P --lines L1,a:b,...  [--amplitudes A] [--seed S] [--phases random|schroeder]\n"
    "                    [--inputs NU (default: the device's)] [--experiments M]\n"
    "  --periods K       periods per experiment (default: the design's, else 8)\n"
    "  --skip-periods K  leading periods left out (transient); --transient flag|drop|off, --alpha A,\n"
    "                    --detect-lines B,..: as in msid frf\n"
    "  --rate HZ         device sample rate (0: as fast as the link carries, default); sets fs\n"
    "  --fs HZ           sample rate for the frequency axis of an unpaced device (--rate 0)\n"
    "  --scale S         value of one int16 step (default 0.001)\n"
    "  --timeout S       give up when no new sample arrives this long (default 10)\n"
    "  --fit M           subspace or ml: fit OUTDIR/model.json (msid fit --method M)\n"
    "  --order n|auto    model order (default auto: stabilisation diagram, docs/fitting.md)\n"
    "  --no-plots        skip the plots and report\n"
    "  --quiet           no progress\n";

static const std::vector<std::string> MEASURE_KEYS = {
    "device", "design", "period", "lines", "amplitudes", "seed", "phases", "inputs", "experiments", "periods",
    "skip-periods", "transient", "alpha", "detect-lines", "rate", "fs", "scale", "timeout", "fit", "order", "output",
    "map"};

const std::vector<std::string> &measure_keys() { return MEASURE_KEYS; }

// The design: from a file, or from options with the device's inputs unless --inputs is given.
static std::unique_ptr<Design> design_from_options(const Args &a, uint32_t device_inputs)
{
    DesignParams p;
    p.period = parse_u32(a.require("period"), "--period");
    p.bins = parse_uint_list(a.require("lines"), "--lines");
    p.n_inputs = a.u32("inputs", device_inputs);
    p.n_experiments = a.u32("experiments", p.n_inputs);
    if (a.has("amplitudes")) {
        p.amplitudes = parse_double_list(a.get("amplitudes"), "--amplitudes");
        if (p.amplitudes.size() == 1) p.amplitudes.assign(p.bins.size(), p.amplitudes[0]);
    }
    const std::string ph = a.get("phases", "random");
    if (ph == "random") p.phase_mode = MSID_PHASE_RANDOM;
    else if (ph == "schroeder") p.phase_mode = MSID_PHASE_SCHROEDER;
    else throw UsageError("--phases must be random or schroeder (got '" + ph + "')");
    p.seed = a.u64("seed", 1);
    p.periods = a.u32("periods", 8);
    return build_design(p);
}

static void check_outdir(const std::string &dir)
{
    struct stat st;
    if (::stat(dir.c_str(), &st) == 0 && !S_ISDIR(st.st_mode))
        throw UsageError("-o '" + dir + "' exists and is not a directory");
}

MeasureRun run_measure(const MeasureOptions &opt, Progress &pg)
{
    const Args &a = *opt.args;
    MeasureRun run;
    const std::string &outdir = opt.outdir;
    std::unique_ptr<Design> file_design;
    if (a.has("design")) file_design = read_design_file(a.get("design"));
    auto plan = [&](uint32_t nu, MeasurePlan &P) {
        P.D = file_design ? std::move(file_design) : design_from_options(a, nu);
        if (opt.dev.kind == DeviceUri::CAN) P.sf.fd = opt.dev.fd ? 1 : 0;
        parse_measure_options(a, *P.D, P.sf, P.rq);
        if (a.has("fs")) {
            if (P.sf.rate) throw UsageError("--fs is for an unpaced device; --rate already sets the sample rate");
            P.rq.fs = parse_double(a.get("fs"), "--fs");
            if (!(P.rq.fs > 0)) throw UsageError("--fs must be positive");
        }
        if (a.has("timeout")) {
            P.timeout = parse_double(a.get("timeout"), "--timeout");
            if (!(P.timeout > 0)) throw UsageError("--timeout must be positive");
        }
    };
    if (!opt.map.empty()) {
        const msid_devdesc desc = msidacq::load_description(opt.map);
        msidacq::MappedOptions mo;
        mo.rate_hz = opt.rate_hz;
        mo.realtime = opt.realtime;
        mo.desc_path = opt.map;
        if (a.has("timeout")) mo.timeout = parse_double(a.get("timeout"), "--timeout");
        auto mplan = [&](uint32_t nu, MeasurePlan &P) {
            P.D = file_design ? std::move(file_design) : design_from_options(a, nu);
            parse_periods_and_estimate(a, *P.D, P.sf, P.rq);
        };
        StopOnSignal guard;   // Ctrl-C ends the acquisition; the safe values are written, complete periods kept
        run.m = msidacq::measure_mapped(opt.dev, desc, mo, mplan, pg);
    } else {
        StopOnSignal guard;   // Ctrl-C ends the acquisition, the FRF of the complete periods is kept
        run.m = measure_device(opt.dev, plan, pg);
    }
    if (::mkdir(outdir.c_str(), 0755) != 0 && errno != EEXIST)
        throw Error("cannot create directory '" + outdir + "': " + std::strerror(errno));
    clear_previous_outputs(outdir);
    write_json_file(outdir + "/design.json", design_to_json(*run.m.D));
    msidjob::write_outcome(outdir + "/frf.json", run.m.o);
    if (!run.m.reference.is_null()) write_json_file(outdir + "/reference.json", run.m.reference);
    run.frf = outdir + "/frf.json";
    for (const auto &n : run.m.o.notes) std::fprintf(stderr, "msid measure: note: %s\n", n.c_str());
    if (!opt.fit.empty() && !run.m.complete) {
        // a stop asks msid to end: no fit (seconds to minutes, and on the few periods of a cut-short
        // experiment often no fit at all); the FRF is kept and says how to fit it later
        run.fit_skipped = fmt("the run was stopped, so no fit was made; to fit the kept FRF: msid fit --method %s "
                              "--order %s %s -o %s/model.json",
                              opt.fit.c_str(), opt.order.c_str(), run.frf.c_str(), outdir.c_str());
    } else if (!opt.fit.empty()) {
        run.model = outdir + "/model.json";
        run.fit_error = fit_model(run.frf, run.model, opt.fit, opt.order, opt.quiet_fit);
        if (!run.fit_error.empty()) run.model.clear();
    }
    if (opt.plots) run.plot_note = make_plots(outdir, run.frf, run.model, opt.command_line);
    return run;
}

MeasureOptions parse_measure_command(const Args &a)
{
    MeasureOptions o;
    o.args = &a;
    o.outdir = a.require("output");
    o.dev = parse_device_uri(a.require("device"));
    if (a.has("design") && (a.has("period") || a.has("lines")))
        throw UsageError("give either --design FILE or --period/--lines, not both");
    if (!a.has("design") && !(a.has("period") && a.has("lines")))
        throw UsageError("give --design FILE, or --period P and --lines L to design the excitation");
    if (a.has("design")) {
        for (const char *k : {"amplitudes", "seed", "phases", "inputs", "experiments"})
            if (a.has(k)) throw UsageError(std::string("--") + k + " is a design option: it does not go with --design");
        read_design_file(a.get("design"));   // a bad file fails before the device is touched
    } else if (a.has("inputs")) {
        design_from_options(a, 1);            // bad design options fail before the device is touched
    }
    if (a.has("order") && !a.has("fit")) throw UsageError("--order goes with --fit");
    if (a.has("fit")) {
        o.fit = a.get("fit");
        if (o.fit != "subspace" && o.fit != "ml") throw UsageError("--fit must be subspace or ml (got '" + o.fit + "')");
        o.order = a.get("order", "auto");
        if (o.order != "auto") {
            const uint32_t n = parse_u32(o.order, "--order");
            if (n < 1 || n > 200) throw UsageError("--order must be 1..200 or auto");
        }
    }
    o.plots = !a.has("no-plots");
    if (a.has("map")) {
        o.map = a.get("map");
        if (!a.has("rate")) throw UsageError("--map needs --rate HZ: the host ticks at that rate");
        o.rate_hz = parse_double(a.get("rate"), "--rate");
        if (!(o.rate_hz > 0 && o.rate_hz <= 100000)) throw UsageError("--rate must be in (0, 100000] Hz");
        for (const char *k : {"scale", "fs"})
            if (a.has(k)) throw UsageError(std::string("--") + k + " does not go with --map (the description scales "
                                                                    "each channel; --rate is the sample rate)");
        o.realtime = !a.has("no-realtime");
        msidacq::load_description(o.map);   // a bad description fails before the device is touched
    } else if (a.has("no-realtime")) {
        throw UsageError("--no-realtime goes with --map");
    }
    check_outdir(o.outdir);
    return o;
}

int cmd_measure_uri(int argc, char **argv)
{
    Args a(argc, argv, 2, MEASURE_HELP, measure_keys(), {"no-plots", "quiet", "no-realtime"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    MeasureOptions opt = parse_measure_command(a);
    opt.command_line = shell_line(argc, argv);
    Progress pg(stderr, is_terminal(stderr), a.has("quiet"));
    MeasureRun run = run_measure(opt, pg);
    std::printf("wrote %s: %s\n", run.frf.c_str(), run.m.summary.c_str());
    if (!run.model.empty()) std::printf("wrote %s\n", run.model.c_str());
    if (!run.plot_note.empty()) std::printf("%s\n", run.plot_note.c_str());
    if (!run.fit_error.empty()) {
        std::fprintf(stderr, "msid measure: error: the fit failed (the FRF is kept): %s\n", run.fit_error.c_str());
        return 1;
    }
    if (!run.fit_skipped.empty()) std::fprintf(stderr, "msid measure: fit skipped: %s\n", run.fit_skipped.c_str());
    if (!run.m.complete) {
        std::fprintf(stderr, "msid measure: interrupted: %s is the FRF of the complete periods (\"complete\": false)\n",
                     run.frf.c_str());
        return 128 + (run.m.stop_reason ? run.m.stop_reason : SIGINT);
    }
    return 0;
}

}  // namespace msidcli
