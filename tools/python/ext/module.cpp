// msid._msid: the module, and the one place where msid's errors become Python exceptions.
#include "ext.hpp"

#include <new>

#include "frf_file.hpp"

namespace msidpy {

// msidutil::Error's kind decides the exception: a file or device that cannot be used is an
// OSError, anything else msid refuses (bad samples, records or options) a ValueError. The text
// is msid's message, the one the command line prints.
static void translate(std::exception_ptr p)
{
    try {
        if (p) std::rethrow_exception(p);
    } catch (const msidutil::Error &e) {
        PyErr_SetString(e.kind == msidutil::ErrorKind::io ? PyExc_OSError : PyExc_ValueError, e.what());
    } catch (const msidfrf::Error &e) {
        // the FRF and model documents and the fits (msidfit::FitError): the data cannot give a result
        PyErr_SetString(PyExc_ValueError, e.what());
    }
}

}  // namespace msidpy

PYBIND11_MODULE(_msid, m)
{
    m.doc() = "msid's host libraries in process (use the msid package: msid.frf, msid.Measurement, msid.design, msid.fit)";
    pybind11::register_exception_translator(&msidpy::translate);
    msidpy::register_design(m);
    msidpy::register_frf(m);
    msidpy::register_measurement(m);
    msidpy::register_fit(m);
    msidpy::register_measure(m);
    msidpy::register_import(m);
}
