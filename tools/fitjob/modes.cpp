// `msid modes MODEL` as a library call: natural frequencies, damping ratios and residues of every
// pole pair with standard deviations (modal_io.hpp: the delta method from the parameter covariance);
// a model of --method multi goes to modes_multi.cpp.
#include "fit_job_detail.hpp"

#include "modal_io.hpp"

namespace msidfitjob {


ModesOutcome modes_of(const Json &j, const std::string &path)
{
    try {
        if (!j.is_object() || j.value("format", "") != "msid-model/1")
            throw FitError("'" + path + "': not an msid-model/1 file");
        if (j.value("method", "") == "multi") return modes_of_multi(j, path);
        const ModalReport r = modal_report(j);
        ModesOutcome out;
        out.text = modal_text(r);
        Json o = modal_json(r);
        o["format"] = "msid-modes/1";
        o["model"] = path;
        out.report = std::move(o);
        return out;
    } catch (const Json::exception &e) {
        throw FitError("'" + path + "': malformed model file (" + e.what() + ")");
    }
}

}  // namespace msidfitjob
