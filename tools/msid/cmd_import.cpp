// `msid import`: an FRF measured by another tool (Touchstone, UFF 58, CSV, idfrd .mat) as an
// msid-frf/1 file; the readers are tools/frfimport (docs/frf-format.md, "FRFs from other tools").
#include "cli_util.hpp"
#include "commands.hpp"
#include "frf_import.hpp"
#include "msid_json_file.hpp"

#include <cmath>
#include <cstdio>

namespace msidcli {

static const char *IMPORT_HELP =
    "usage: msid import FILE [--format touchstone|uff|csv|mat] -o frf.json\n"
    "An FRF measured by another tool as an msid-frf/1 file (msid fit, validate and plot also read FILE\n"
    "directly). The format from the extension (.sNp, .uff/.unv, .csv, .mat) and content, or --format:\n"
    "  touchstone  Touchstone 1.x of network analysers: S, Y, Z, H or G parameters of an N-port (N inputs,\n"
    "              N outputs), RI, MA or DB, Hz..GHz; noise parameters of a 2-port are left out\n"
    "  uff         UFF/UNV dataset 58 (ASCII) of modal test suites: function type 4 (FRF), complex ordinate,\n"
    "              even or uneven abscissa; references are the inputs, responses the outputs, named node+dir\n"
    "  csv         freq_hz or omega, then G_OUT_IN_re, G_OUT_IN_im and optionally G_OUT_IN_sd or G_OUT_IN_coh\n"
    "              (with '# averages: n'); '# units: name=unit, ...'; '# domain: dt' and '# sample_time: T'\n"
    "  mat         an idfrd-shaped MATLAB v5 .mat: ResponseData (ny x nu x L), Frequency, Ts (0: continuous\n"
    "              time), FrequencyUnit, optional CovarianceData and dof, InputName .. OutputUnit (as msid\n"
    "              export --mat writes them)\n"
    "A continuous-time FRF without a sample time (an analogue instrument's) stays one: msid fit makes a\n"
    "continuous-time model of it. Without standard deviations or coherence the file has no covariance:\n"
    "msid fit then fits unweighted and gives no p-value. Nothing is written when the file is refused.\n";

int cmd_import(int argc, char **argv)
{
    Args a(argc, argv, 2, IMPORT_HELP, {"format", "output"}, {});
    if (a.positional().size() != 1) throw UsageError("give one FRF file to import (msid import FILE -o frf.json)");
    const std::string out = a.get("output");
    if (out.empty()) throw UsageError("give the output file with -o frf.json");
    const std::string in = a.positional()[0];
    const msidfrfimport::Format fm = msidfrfimport::format_of(in, a.get("format"));
    if (fm == msidfrfimport::Format::Msid) throw UsageError("'" + in + "' is an msid-frf/1 file already");
    const msidfrfimport::Imported im = msidfrfimport::read_imported(in, fm);
    const msidfmt::Json doc = msidfrfimport::to_document(im);
    msidfrf::parse_frf(doc, out);   // the checks every reader of the file makes, before it is written
    msidfmt::write_json_file(out, doc, false);
    const auto &lines = doc["lines"];
    const double f0 = im.ct ? lines.front()["omega"].get<double>() / (2 * M_PI) : lines.front()["freq"].get<double>();
    const double f1 = im.ct ? lines.back()["omega"].get<double>() / (2 * M_PI) : lines.back()["freq"].get<double>();
    std::printf("wrote %s: %s, %u output(s) x %u input(s), %zu lines, %.6g..%.6g %s, %s, %s\n", out.c_str(),
                im.format.c_str(), im.ny, im.nu, lines.size(), f0, f1,
                im.ct ? "Hz" : im.sample_time > 0 ? "cycles/sample" : "cycles/sample (no sample time)",
                im.ct ? "continuous time" : "discrete time",
                im.cov.empty() ? "no covariance (msid fit fits it unweighted, no p-value)" : "with covariance");
    return 0;
}

}  // namespace msidcli
