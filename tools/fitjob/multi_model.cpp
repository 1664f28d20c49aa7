// The model document of `msid fit --method multi` read back (its poles, numerator, noise model and
// noise variance): what `msid modes` and `msid validate --experiment` of such a model take.
#include "fit_job_detail.hpp"

namespace msidfitjob {

MultiModelDoc multi_model_doc(const Json &j, const std::string &path)
{
    if (!j.is_object() || j.value("format", "") != "msid-model/1")
        throw Error("'" + path + "': not an msid-model/1 file");
    if (j.value("method", "") != "multi" || !j.contains("multi") || !j["multi"].is_object())
        throw Error("'" + path + "': validation on records needs a model written by msid fit --method multi (this one is '" +
                    j.value("method", std::string("?")) + "'; validate FRF models against an FRF file)");
    try {
        MultiModelDoc m;
        const Json &mj = j["multi"];
        const auto al = mj.at("alpha").get<std::vector<double>>();
        m.alpha = Eigen::Map<const VecR>(al.data(), (Eigen::Index)al.size());
        m.nu = j.at("n_inputs").get<int>();
        m.ny = j.at("n_outputs").get<int>();
        m.s2 = mj.at("noise_variance").get<double>();
        m.dof = mj.at("dof").get<double>();
        m.h = j.contains("sample_time") && j["sample_time"].is_number() ? j["sample_time"].get<double>() : 0.0;
        if (mj.contains("noise") && mj["noise"].contains("ar")) {
            const auto c = mj["noise"]["ar"].get<std::vector<double>>();
            m.noise = Eigen::Map<const VecR>(c.data(), (Eigen::Index)c.size());
        }
        const int n = (int)m.alpha.size();
        if (n < 1 || !m.alpha.allFinite() || m.ny < 1 || m.nu < 0 || !(m.s2 > 0))
            throw Error("'" + path + "': the multi section has no usable poles, channels or noise variance");
        if (m.nu > 0) {
            m.d0 = j.at("settings").value("feedthrough", std::string("no")) == "yes" ? 0 : 1;
            const Json &N = j.at("lmfd").at("N");
            if ((int)N.size() != n + 1) throw Error("'" + path + "': lmfd.N must hold n + 1 matrices");
            for (int d = m.d0; d <= n; ++d) {
                MatR B(m.ny, m.nu);
                for (int r = 0; r < m.ny; ++r)
                    for (int k = 0; k < m.nu; ++k) B(r, k) = N.at((size_t)d).at((size_t)r).at((size_t)k).get<double>();
                m.beta.push_back(B);
            }
        }
        if (j.contains("source") && j["source"].is_array())
            for (const auto &s : j["source"]) m.sources.push_back(s.get<std::string>());
        return m;
    } catch (const Json::exception &e) {
        throw Error("'" + path + "': malformed multi model (" + e.what() + ")");
    }
}

}  // namespace msidfitjob
