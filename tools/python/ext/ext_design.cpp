// msid._msid.Design: excitation designs (msidfmt::build_design, the msid-design/1 file) and their
// samples from the core's generator, as `msid excite` makes them.
#include "ext.hpp"
#include "ext_call.hpp"

#include "msid_host_util.hpp"
#include "msid_json_file.hpp"

namespace msidpy {

using msidfmt::DesignParams;
using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;
using msidutil::UsageError;

// `msid excite`'s parameters (compute.py has put the lists in order) into a built design.
static PyDesign make(uint32_t period, const std::vector<uint32_t> &lines, const std::vector<double> &omega,
                     double sample_time, const std::vector<double> &amplitudes, const std::string &phases,
                     uint64_t seed, uint32_t inputs, uint32_t experiments, const std::string &pattern, uint32_t periods)
{
    DesignParams p;
    p.period = period;
    if (lines.empty() == omega.empty()) throw UsageError("give either lines (bins) or omega with sample_time");
    if (!lines.empty() && sample_time > 0) throw UsageError("sample_time goes with omega, not lines");
    if (!omega.empty() && !(sample_time > 0)) throw UsageError("omega needs sample_time (s)");
    p.bins = lines;
    p.omega = omega;
    p.sample_time = omega.empty() ? 0.0 : sample_time;
    const size_t L = lines.size() + omega.size();
    p.n_inputs = inputs;
    p.n_experiments = experiments ? experiments : inputs;
    p.amplitudes = amplitudes;
    if (p.amplitudes.size() == 1) p.amplitudes.assign(L, p.amplitudes[0]);
    p.amp_per_input = p.amplitudes.size() == (size_t)p.n_inputs * L && p.n_inputs > 1;
    p.phase_mode = choose<msid_phase_mode>("phases", phases,
                                           {{"random", MSID_PHASE_RANDOM}, {"schroeder", MSID_PHASE_SCHROEDER}});
    p.seed = seed;
    p.pattern = choose<msid_pattern>("pattern", pattern, {{"dft", MSID_PATTERN_DFT}, {"hadamard", MSID_PATTERN_HADAMARD}});
    if (periods == 0) throw UsageError("periods must be at least 1");
    p.periods = periods;
    // build_design plans FFTW (the crest factors): the planner lock
    return PyDesign{without_gil({true, true, "msid.design"}, [&] { return msidfmt::build_design(p); })};
}

// `periods` periods of experiment e's inputs: (periods * P) x nu, row-major.
static py::array_t<double> samples(const PyDesign &D, uint32_t e, uint32_t periods)
{
    const msid_design &d = D.d->d;
    if (e >= d.n_experiments) throw UsageError(fmt("experiment %u: the design has %u (counted from 0)", e, d.n_experiments));
    if (periods == 0) throw UsageError("periods must be at least 1");
    const size_t n = (size_t)periods * d.period, nu = d.n_inputs;
    py::array_t<double> out({n, nu});
    double *u = out.mutable_data();
    without_gil({false, true, "Design.samples"}, [&] {
        msid_gen_cfg gc{&d, &D.d->tw, e, 1};
        Mem gm(msid_gen_mem_size(&gc));
        msid_gen g;
        check(msid_gen_init(&g, &gc, gm.p, gm.n), "generator");
        // a period at a time, a checkpoint after each
        const size_t P = d.period;
        for (size_t k = 0; k < n; k += P) {
            msid_gen_block(&g, u + k * nu, std::min(P, n - k), nu);
            msidutil::checkpoint(msidutil::Step::rows, std::min(P, n - k), "Design.samples");
        }
    });
    return out;
}

void register_design(py::module_ &m)
{
    py::class_<PyDesign>(m, "Design", "A built excitation design (use msid.design / msid.read_design).")
        .def_property_readonly("doc", [](const PyDesign &D) { return json_to_py(msidfmt::design_to_json(*D.d)); })
        .def_property_readonly("period", [](const PyDesign &D) { return D.d->d.period; })
        .def_property_readonly("n_inputs", [](const PyDesign &D) { return D.d->d.n_inputs; })
        .def_property_readonly("n_experiments", [](const PyDesign &D) { return D.d->d.n_experiments; })
        .def_property_readonly("bins", [](const PyDesign &D) {
            return std::vector<uint32_t>(D.d->d.bins, D.d->d.bins + D.d->d.n_lines);
        })
        .def_property_readonly("cond_max", [](const PyDesign &D) { return D.d->d.cond_max; })
        .def("crest_factor", [](const PyDesign &D, uint32_t e, uint32_t i) {
            return msid_design_crest_factor(&D.d->d, e, i);
        })
        .def("samples", &samples, py::arg("experiment"), py::arg("periods"))
        .def("save", [](const PyDesign &D, const std::string &path) {
            msidfmt::write_json_file(path, msidfmt::design_to_json(*D.d));
        });
    m.def("design", &make, py::arg("period"), py::arg("lines"), py::arg("omega"), py::arg("sample_time"),
          py::arg("amplitudes"), py::arg("phases"), py::arg("seed"), py::arg("inputs"), py::arg("experiments"),
          py::arg("pattern"), py::arg("periods"));
    m.def("read_design",
          [](const std::string &path) {
              return PyDesign{without_gil({true, true, "msid.read_design"}, [&] { return msidfmt::read_design_file(path); })};
          },
          py::arg("path"));
}

}  // namespace msidpy
