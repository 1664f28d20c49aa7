#include "msid_reference.hpp"

#include "records_detail.hpp"

#include <algorithm>

namespace msidrec {

std::vector<std::string> parse_reference(const std::string &spec)
{
    std::vector<std::pair<unsigned, std::string>> it;
    size_t a = 0;
    for (;;) {
        const size_t b = spec.find(',', a);
        std::string item = spec.substr(a, b == std::string::npos ? std::string::npos : b - a);
        while (!item.empty() && (item.front() == ' ' || item.front() == '\t')) item.erase(item.begin());
        while (!item.empty() && (item.back() == ' ' || item.back() == '\t')) item.pop_back();
        const size_t eq = item.find('=');
        std::string dst = item.substr(0, eq), src = eq == std::string::npos ? dst : item.substr(eq + 1);
        unsigned k = 0;
        size_t used = 0;
        if (dst.size() >= 2 && (dst[0] == 'r' || dst[0] == 'R') && dst[1] != '0') {
            try {
                k = (unsigned)std::stoul(dst.substr(1), &used);
            } catch (const std::exception &) {
                k = 0;
            }
        }
        if (k == 0 || k > 64 || used + 1 != dst.size() || src.empty())
            throw UsageError(MSID_OPT("reference") ": '" + item + "' is not r<k>=<column name> or r<k> (k = 1..64)");
        for (const auto &e : it) {
            if (e.first == k) throw UsageError(fmt(MSID_OPT("reference") ": r%u is given twice", k));
            if (e.second == src) throw UsageError(MSID_OPT("reference") ": column '" + src + "' is given twice");
        }
        it.emplace_back(k, src);
        if (b == std::string::npos) break;
        a = b + 1;
    }
    std::vector<std::string> out(it.size());
    for (const auto &e : it) {
        if (e.first > it.size())
            throw UsageError(fmt(MSID_OPT("reference") ": r%u without r1..r%u: references are numbered from r1 without gaps",
                                 e.first, e.first - 1));
        out[e.first - 1] = e.second;
    }
    return out;
}

std::vector<double> rows_with_reference(const Record &rec, const std::vector<std::string> &ref)
{
    const unsigned nu = rec.nu, ny = rec.ny, nr = (unsigned)ref.size();
    if (nr != nu)
        throw Error(fmt("'%s': %u reference column(s) for %u input(s): the noisy-input LPM needs one reference per "
                        "input (" MSID_OPT("reference") " r1=COL%s)", rec.path.c_str(), nr, nu, nu > 1 ? fmt(",...,r%u=COL", nu).c_str() : ""));
    // the reference columns as "inputs", the record's first output along (a reader needs one)
    ColumnMap m;
    for (unsigned k = 0; k < nr; ++k) m.map.emplace_back(fmt("u%u", k + 1), ref[k]);
    m.map.emplace_back("y1", rec.columns.at(nu));
    Record rr;
    try {
        rr = read_experiment(rec.path, m);
    } catch (const msidutil::Error &e) {   // name the reference, not the reader's stand-in "u<k>"
        std::string w = e.what();
        const size_t p = w.find("(for u");
        if (p != std::string::npos) w[p + 5] = 'r';
        throw Error(w);
    }
    if (rr.n_rows != rec.n_rows)
        throw Error(fmt("'%s': the reference columns have %zu rows, the inputs and outputs %zu", rec.path.c_str(),
                        rr.n_rows, rec.n_rows));
    const size_t C = (size_t)nr + ny + nu, cin = (size_t)nu + ny;
    std::vector<double> rows(rec.n_rows * C);
    const double *d = rec.data(), *r = rr.data();
    for (size_t t = 0; t < rec.n_rows; ++t) {
        double *o = &rows[t * C];
        for (unsigned k = 0; k < nr; ++k) o[k] = r[t * (nr + 1) + k];
        for (unsigned i = 0; i < ny; ++i) o[nr + i] = d[t * cin + nu + i];
        for (unsigned j = 0; j < nu; ++j) o[nr + ny + j] = d[t * cin + j];
    }
    return rows;
}

std::vector<std::string> own_reference_columns(const Record &rec)
{
    std::vector<std::string> out;
    for (uint32_t k = 1; k <= rec.nu; ++k) {
        const std::string lo = fmt("r%u", k), up = fmt("R%u", k);
        const auto it = std::find_if(rec.file_columns.begin(), rec.file_columns.end(),
                                     [&](const std::string &n) { return n == lo || n == up; });
        if (it == rec.file_columns.end()) return {};
        out.push_back(*it);
    }
    return out;
}

}  // namespace msidrec
