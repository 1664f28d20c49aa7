// msid.import_frf: FRFs measured by other tools (Touchstone, UFF 58, CSV, idfrd .mat) through the
// command line's readers (tools/frfimport), as msid-frf/1 text that msid.FRF and msid.fit take.
#include "ext.hpp"

#include "frf_import.hpp"

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
    std::string text;
    {
        py::gil_scoped_release nogil;
        text = msidfrfimport::load_document(path, format).dump();
    }
    return text;
}

void register_import(py::module_ &m)
{
    m.def("frf_format", &frf_format, py::arg("path"), py::arg("format"),
          "The format of an FRF file: msid, touchstone, uff, csv or mat (use msid.import_frf).");
    m.def("import_frf", &import_frf, py::arg("path"), py::arg("format"),
          "An FRF file of any format as msid-frf/1 JSON text (use msid.import_frf).");
}

}  // namespace msidpy
