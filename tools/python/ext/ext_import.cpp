// msid.import_frf: FRFs measured by other tools (Touchstone, UFF 58, CSV, idfrd .mat) through the
// command line's readers (tools/frfimport), as msid-frf/1 text that msid.FRF and msid.fit take; and
// msid.export, the other way (tools/frfexport).
#include "ext.hpp"
#include "ext_call.hpp"

#include "frf_import.hpp"
#include "msid_frf_export.hpp"

namespace msidpy {

static const char *const FORMAT_NAMES[] = {"msid", "touchstone", "uff", "csv", "mat"};

// The format msid gives `path` (format: "" to recognise it by its extension and content).
static std::string frf_format(const std::string &path, const std::string &format)
{
    return FORMAT_NAMES[(int)msidfrfimport::format_of(path, format)];
}

// The msid-frf/1 document of an FRF file of any format, as JSON text.
static std::string import_frf(const std::string &path, const std::string &format)
{
    return without_gil({false, true, "msid.import_frf"}, [&] { return msidfrfimport::load_document(path, format).dump(); });
}

// `msid export SRC --csv|--mat OUT`: "csv", "mat" or "model" (what was written) and the FRF's size.
static py::tuple export_file(const std::string &src, const std::string &out, bool csv, bool known_input)
{
    std::string what;
    msidexport::ExportSummary s;
    without_gil({false, true, "msid.export"}, [&] {
        if (msidexport::is_model_file(src)) {
            if (csv) throw msidutil::UsageError("a model file exports to --mat only (A, B, C, D, Ts and names)");
            if (known_input) throw msidutil::UsageError("--known-input is for an FRF file, not a model");
            msidexport::export_model_mat(src, out);
            what = "model";
        } else {
            s = csv ? msidexport::export_frf_csv(src, out, known_input) : msidexport::export_frf_mat(src, out, known_input);
            what = csv ? "csv" : "mat";
        }
    });
    return py::make_tuple(what, s.lines, s.ny, s.nu);
}

void register_import(py::module_ &m)
{
    m.def("export_file", &export_file, py::arg("src"), py::arg("out"), py::arg("csv"), py::arg("known_input"),
          "An FRF or model file for other tools, as msid export (use msid.export).");
    m.def("frf_format", &frf_format, py::arg("path"), py::arg("format"),
          "The format of an FRF file: msid, touchstone, uff, csv or mat (use msid.import_frf).");
    m.def("import_frf", &import_frf, py::arg("path"), py::arg("format"),
          "An FRF file of any format as msid-frf/1 JSON text (use msid.import_frf).");
}

}  // namespace msidpy
