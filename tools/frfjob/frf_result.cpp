// The periodic FRF job's typed result: its document tree (for the callers that edit documents) and
// the one msid-frf/1 text writer that streams the file from the arrays.
#include "msid_frf_result.hpp"
#include "frf_text.hpp"
#include "msid_json_file.hpp"
#include "msid_host_util.hpp"

#include <exception>
#include <system_error>
#include <thread>

namespace msidjob {

using cd = FrfResult::cd;

// The members before the lines: header, counts, the noise covariance, the experiments.
static Json head_of(const FrfResult &r)
{
    const size_t ny = r.header.ny;
    Json doc = msidfrf::header(r.header);
    doc["periods_used"] = r.periods_used;
    doc["periods_rejected"] = r.periods_rejected;
    doc["dft_path"] = r.dft_path;
    doc["vec_convention"] = msidfrf::VEC_CONVENTION;
    doc["noise_cov"] = msidfrf::cmat(r.noise_cov.data(), ny, ny);
    Json exps = Json::array();
    for (const auto &x : r.experiments) exps.push_back(msidfrf::experiment(x));
    doc["experiments"] = std::move(exps);
    return doc;
}

static Json detection_of(const FrfResult &r)
{
    const size_t ny = r.header.ny, m = r.header.m;
    Json dl = Json::array();
    for (size_t d = 0; d < r.detect_bins.size(); ++d)
        dl.push_back(msidfrf::detection_line(
            r.detect_bins[d], r.header.period, r.header.fs, msidfrf::from_row_major(&r.detect_mean[d * m * ny], m, ny),
            std::vector<double>(&r.detect_var[d * ny], &r.detect_var[d * ny] + ny),
            std::vector<double>(&r.detect_p[d * ny], &r.detect_p[d * ny] + ny)));
    return dl;
}

// Line l's arrays as the text writer takes them.
static msidfrf::LineArrays line_arrays(const FrfResult &r, size_t l)
{
    const size_t ny = r.header.ny, nu = r.header.nu, g = ny * nu;
    msidfrf::LineArrays a;
    a.ny = ny;
    a.nu = nu;
    a.G = &r.G[l * g];
    a.cov = &r.cov[l * g * g];
    a.dof = r.dof[l];
    a.cov_ki = &r.cov_ki[l * g * g];
    a.dof_ki = r.dof_ki[l];
    a.noise = &r.noise[l * ny * ny];
    a.snr = &r.snr[l * ny];
    a.cond = r.cond[l];
    a.input_snr = r.input_snr[l];
    return a;
}

Json detection_summary(const FrfResult &r)
{
    Json doc = Json::object();
    doc["n_experiments"] = r.header.m;
    doc["n_outputs"] = r.header.ny;
    Json exps = Json::array();
    for (const auto &x : r.experiments) exps.push_back({{"periods_used", x.periods_used}});
    doc["experiments"] = std::move(exps);
    doc["detection_lines"] = detection_of(r);
    return doc;
}

Json frf_meta(const FrfResult &r)
{
    Json doc = head_of(r);
    if (!r.detect_bins.empty()) doc["detection_lines"] = detection_of(r);
    for (auto it = r.tail.begin(); it != r.tail.end(); ++it) doc[it.key()] = it.value();
    return doc;
}

Json frf_document(const FrfResult &r)
{
    const size_t ny = r.header.ny, nu = r.header.nu, g = ny * nu, L = r.n_lines();
    Json doc = head_of(r);
    Json lines = Json::array();
    lines.get_ref<Json::array_t &>().reserve(L);
    for (size_t l = 0; l < L; ++l) {
        msidfrf::LineStats s;
        s.G = msidfrf::from_row_major(&r.G[l * g], ny, nu);
        s.cov = msidfrf::from_row_major(&r.cov[l * g * g], g, g);
        s.dof = r.dof[l];
        s.cov_ki = msidfrf::from_row_major(&r.cov_ki[l * g * g], g, g);
        s.dof_ki = r.dof_ki[l];
        s.noise = msidfrf::from_row_major(&r.noise[l * ny * ny], ny, ny);
        s.snr.assign(&r.snr[l * ny], &r.snr[l * ny] + ny);
        s.cond = r.cond[l];
        s.input_snr = r.input_snr[l];
        lines.push_back(msidfrf::line(msidfrf::position(r.pos[l]), s));
    }
    doc["lines"] = std::move(lines);
    if (!r.detect_bins.empty()) doc["detection_lines"] = detection_of(r);
    for (auto it = r.tail.begin(); it != r.tail.end(); ++it) doc[it.key()] = it.value();
    return doc;
}

// The lines [l0, l1) as msidfrf::line_element() writes them at level 1 (a member of the document).
static void lines_text(const FrfResult &r, size_t l0, size_t l1, std::string &out)
{
    for (size_t l = l0; l < l1; ++l) {
        msidfrf::line_element(r.pos[l], line_arrays(r, l), l, 1, 1, out);
        if (l == l0) out.reserve(out.size() * (l1 - l0) / 8 * 9 + 4096);   // lines are alike in size
    }
}

// The text of an object's members as dump() writes them at level 1, without the braces: what lies
// between "{\n" and "\n}" ("" for an empty object).
static std::string members_text(const Json &o)
{
    if (o.empty()) return "";
    std::string s;
    msidfrf::dump(o, 1, s);
    return s.substr(2, s.size() - 4);
}

void write_frf_text(const FrfResult &r, std::string &out)
{
    const Json head = head_of(r);
    // a tail member that replaces a member before it keeps that member's place: the tree's layout
    for (auto it = r.tail.begin(); it != r.tail.end(); ++it)
        if (head.contains(it.key()) || it.key() == "lines" || it.key() == "detection_lines") {
            msidfrf::dump(frf_document(r), 1, out, true);
            out += '\n';
            return;
        }
    const size_t L = r.n_lines();
    out += "{\n";
    out += members_text(head);
    out += ",\n \"lines\": ";
    if (!L) out += "[]";
    else {
        out += "[\n";
        // many lines: two halves on two threads, appended in order (the same bytes)
        const size_t half = L >= 64 && std::thread::hardware_concurrency() >= 2 ? L / 2 : L;
        std::string second;
        std::exception_ptr err;
        std::thread th;
        if (half < L) {
            try {
                th = std::thread([&] {
                    try {
                        lines_text(r, half, L, second);
                    } catch (...) {
                        err = std::current_exception();
                    }
                });
            } catch (const std::system_error &) {
            }
        }
        try {
            lines_text(r, 0, half, out);
        } catch (...) {
            if (th.joinable()) th.join();
            throw;
        }
        if (th.joinable()) th.join();
        else if (half < L) lines_text(r, half, L, second);
        if (err) std::rethrow_exception(err);
        out += second;
        out += "\n ]";
    }
    if (!r.detect_bins.empty()) {
        Json d = Json::object();
        d["detection_lines"] = detection_of(r);
        out += ",\n";
        out += members_text(d);
    }
    if (!r.tail.empty()) {
        out += ",\n";
        out += members_text(r.tail);
    }
    out += "\n}\n";
}

void write_frf_file(const std::string &path, const FrfResult &r, bool durable)
{
    std::string s;
    try {
        write_frf_text(r, s);
    } catch (const msidfrf::NonFinite &) {   // the tree's writer names the place
        msidfmt::write_json_file(path, frf_document(r), durable);
        throw msidfmt::Error("'" + path + "' not written: the result is not finite");   // not reached
    }
    msidutil::write_file_atomic(path, s, durable);
}

}  // namespace msidjob
