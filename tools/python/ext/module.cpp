// msid._msid: the module, and the one place where msid's errors become Python exceptions.
#include "ext.hpp"
#include "ext_call.hpp"

#include <cctype>
#include <new>

#include "frf_file.hpp"
#include "msid_cancel.hpp"

namespace msidpy {

// msid's message in Python's words. The options a library names neutrally (MSID_OPT) are keywords
// (msidutil::render_options). A message that still names a flag (one a library built from another
// message's what(), or a note's text) has it read as its keyword: an option of the command line outside
// quotes ('--skip-periods') is the keyword (skip_periods), as msid.frf, msid.fit and msid.measure take
// it. Quoted text (file names, column names, values) and a command line quoted in prose ("msid fit
// --method multi", up to the end of its clause) are left as they are.
static std::string python_words(const std::string &m)
{
    std::string out;
    out.reserve(m.size());
    bool quoted = false, command = false;
    for (size_t i = 0; i < m.size(); ++i) {
        const char c = m[i];
        if (!quoted && m.compare(i, 5, "msid ") == 0 && (i == 0 || !std::isalnum((unsigned char)m[i - 1])) &&
            i + 5 < m.size() && m[i + 5] >= 'a' && m[i + 5] <= 'z')
            command = true;
        else if (command && (c == ';' || c == ',' || c == '(' || c == ')' ||
                             ((c == '.' || c == ':') && (i + 1 == m.size() || m[i + 1] == ' '))))
            command = false;
        // a quote opens after a non-word character and closes before one (an apostrophe does neither)
        if (c == '\'' && !quoted && (i == 0 || !std::isalnum((unsigned char)m[i - 1]))) quoted = true;
        else if (c == '\'' && quoted && (i + 1 == m.size() || !std::isalnum((unsigned char)m[i + 1]))) quoted = false;
        const bool flag = !quoted && !command && c == '-' && i + 2 < m.size() && m[i + 1] == '-' && m[i + 2] >= 'a' &&
                          m[i + 2] <= 'z' && (i == 0 || !(std::isalnum((unsigned char)m[i - 1]) || m[i - 1] == '-'));
        if (!flag) {
            out += c;
            continue;
        }
        for (i += 2; i < m.size() && (std::isalnum((unsigned char)m[i]) || m[i] == '-'); ++i)
            out += m[i] == '-' ? '_' : m[i];
        --i;
    }
    return out;
}

// An exception of `type` with msid's message: the text as Python text even where it is not UTF-8 (a
// Latin-1 column name quoted from a file), its undecodable bytes escaped.
static void raise(PyObject *type, const std::string &m)
{
    const std::string w = python_words(m);
    PyObject *s = PyUnicode_DecodeUTF8(w.data(), (Py_ssize_t)w.size(), "backslashreplace");
    if (!s) {
        PyErr_Clear();
        s = PyUnicode_FromString("(a message that is not text)");
    }
    PyErr_SetObject(type, s);
    Py_XDECREF(s);
}

// msidutil::Error's kind decides the exception: a file or device that cannot be used is an
// OSError, anything else msid refuses (bad samples, records or options) a ValueError. The text
// is msid's message, the one the command line prints, in Python's words.
static void translate(std::exception_ptr p)
{
    try {
        if (p) std::rethrow_exception(p);
    } catch (const msidutil::Cancelled &e) {   // normally Call::run raised the signal handler's exception
        raise(PyExc_KeyboardInterrupt, std::string("interrupted: ") + e.what());
    } catch (const msidutil::Error &e) {
        raise(e.kind == msidutil::ErrorKind::io ? PyExc_OSError : PyExc_ValueError,
              msidutil::render_options(e.text(), msidutil::OptionWords::keyword));
    } catch (const msidfrf::IoError &e) {
        raise(PyExc_OSError, e.what());
    } catch (const msidfrf::Error &e) {
        // the FRF and model documents and the fits (msidfit::FitError): the data cannot give a result
        raise(PyExc_ValueError, e.what());
    } catch (const std::bad_alloc &) {
        raise(PyExc_MemoryError, "msid: out of memory for this request (its sizes: the records, lines, order)");
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
    m.def("_progress", &msidpy::progress_counts,
          "Units of work done by every call so far, per step (rows, lines, orders, iterations, solves, document): how far an "
          "interrupted call got (the interrupt tests).");
    m.def("_interrupt_at", &msidpy::interrupt_at, pybind11::arg("step"), pybind11::arg("at"),
          "SIGINT once `at` more units of `step` are done, raised by the checkpoint that counts them: the interrupt "
          "tests place the signal by work done (step \"\": disarmed).");
    m.def("_sigints", &msidpy::sigints_seen,
          "SIGINTs counted while a call ran on the main thread (the interrupt tests: once the count moved, every checkpoint "
          "of the call stops).");
    m.def("_python_words", &msidpy::python_words,
          "A message of the command line as the extension raises it (options as keywords): for the tests.");
    m.def(
        "_render_options",
        [](const std::string &text, bool keywords) {
            return msidutil::render_options(text, keywords ? msidutil::OptionWords::keyword : msidutil::OptionWords::flag);
        },
        pybind11::arg("message"), pybind11::arg("keywords"),
        "A library's message with its neutral option names (0x1f name 0x1f) as keywords or as flags: for the tests.");
    m.def("_shutdown", &msidpy::shutdown_calls, "Stop every running call and wait for them (registered with atexit).");
    // At the interpreter's exit, before it ends the threads still running: a call in a daemon thread
    // stops at its next checkpoint, a measurement tells its device to stop.
    pybind11::module_::import("atexit").attr("register")(m.attr("_shutdown"));
}
