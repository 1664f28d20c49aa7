// msid._msid.measure where the acquisition is not built (no daq/: not Linux): one message.
#include "ext.hpp"

namespace msidpy {

void register_measure(py::module_ &m)
{
    m.def("measure", [](py::args, py::kwargs) -> py::object {
        throw msidutil::UsageError("msid.measure needs the acquisition library (tools/acquire), built on Linux only");
    });
}

}  // namespace msidpy
