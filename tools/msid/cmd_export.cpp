// `msid export`: an msid-frf/1 file as CSV (spreadsheets) or MATLAB .mat in the shape of idfrd, a model
// as ss/idss's matrices (docs/python.md#msid-export): options -> tools/frfexport -> one line.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"
#include "msid_frf_export.hpp"

#include <cstdio>
#include <string>

namespace msidcli {

static const char *EXPORT_HELP =
    "usage: msid export frf.json (--csv out.csv | --mat out.mat) [--known-input]\n"
    "       msid export model.json --mat out.mat\n"
    "Frequencies, G and standard deviations of an msid-frf/1 file for spreadsheets and MATLAB.\n"
    "  --csv   one row per line: bin, freq (cycles/sample), freq_hz (when the rate is known), omega\n"
    "          (rad/s; rad/sample without a sample time), then per output i / input j the columns\n"
    "          G_yi_uj_re, G_yi_uj_im, G_yi_uj_sd (sd = sqrt of the complex variance E|Ghat - G|^2), and dof\n"
    "  --mat   MATLAB v5: ResponseData (ny x nu x L complex), Frequency (L x 1, rad/s or rad/sample),\n"
    "          Ts (sample time; 0 for a continuous-time file, 1 when unknown), CovarianceData\n"
    "          (ny x nu x L x 2 x 2: covariance of [Re Im], circular noise: v/2 on the diagonal; DC lines\n"
    "          v and 0), SD (ny x nu x L), dof (L x 1), Bin, FrequencyHz (when known), FrequencyUnit,\n"
    "          InputName, OutputName, InputUnit, OutputUnit (cell arrays of char; u1.., y1.. and empty units\n"
    "          when the file names none):\n"
    "          idfrd(ResponseData, Frequency, Ts, 'CovarianceData', CovarianceData, 'FrequencyUnit', FrequencyUnit);\n"
    "          and for exact 95% regions with few periods (showConfidence assumes a Gaussian, too narrow at\n"
    "          low dof): CovarianceData95 = CovarianceData .* ConfidenceScale95 (per line, from the dof:\n"
    "          F(2, 2 dof), DC lines F(1, dof)) drawn with showConfidence(h, SD95), SD95 = sqrt(-2 log 0.05)\n"
    "  --known-input   standard deviations from cov_known_input instead of cov\n"
    "An msid-model/1 file (--mat only): A, B, C, D, Ts (0: continuous time; 1 when unknown), InputName,\n"
    "OutputName, InputUnit, OutputUnit (cell arrays of char), Domain, Method, Order: ss(A, B, C, D, Ts, 'InputName', InputName,\n"
    "'OutputName', OutputName) or idss(A, B, C, D, zeros(size(A, 1), size(C, 1)), zeros(size(A, 1), 1), Ts).\n";

int cmd_export(int argc, char **argv)
{
    Args a(argc, argv, 2, EXPORT_HELP, {"csv", "mat"}, {"known-input"});
    if (a.positional().size() != 1) throw UsageError("give one FRF file (msid export frf.json --csv out.csv | --mat out.mat)");
    if (a.has("csv") == a.has("mat")) throw UsageError("give exactly one of --csv out.csv and --mat out.mat");
    const std::string in = a.positional()[0];
    if (msidexport::is_model_file(in)) {
        if (a.has("csv")) throw UsageError("a model file exports to --mat only (A, B, C, D, Ts and names)");
        if (a.has("known-input")) throw UsageError("--known-input is for an FRF file, not a model");
        msidexport::export_model_mat(in, a.get("mat"));
        std::printf("wrote %s: A, B, C, D, Ts, InputName, OutputName, InputUnit, OutputUnit (ss, idss)\n", a.get("mat").c_str());
        return 0;
    }
    if (a.has("csv")) {
        const auto s = msidexport::export_frf_csv(in, a.get("csv"), a.has("known-input"));
        std::printf("wrote %s: %zu lines, %ux%u\n", a.get("csv").c_str(), s.lines, s.ny, s.nu);
        return 0;
    }
    const auto s = msidexport::export_frf_mat(in, a.get("mat"), a.has("known-input"));
    std::printf("wrote %s: %zu lines, %ux%u (idfrd: ResponseData, Frequency, Ts, CovarianceData)\n", a.get("mat").c_str(),
                s.lines, s.ny, s.nu);
    return 0;
}

}  // namespace msidcli
