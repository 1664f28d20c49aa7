#include "frf_job_detail.hpp"
#include "frf_doc.hpp"
#include "frf_file.hpp"
#include "frf_text.hpp"
#include "msid_frf_job.hpp"

#include <cmath>
#include <sys/resource.h>
#include <unistd.h>

namespace msidjob {

Json cplx_json(const std::complex<double> *a, size_t rows, size_t cols) { return msidfrf::cmat(a, rows, cols); }

Json est_line_json(Json pos, unsigned ny, unsigned nu, const std::complex<double> *G,
                   const std::complex<double> *cov, double dof, const std::complex<double> *noise,
                   const std::vector<double> &snr_db)
{
    const size_t g = (size_t)ny * nu;
    msidfrf::LineStats s;
    s.G = msidfrf::from_row_major(G, ny, nu);
    s.cov = msidfrf::from_row_major(cov, g, g);
    s.dof = dof;   // cov_known_input: the same matrix and dof
    s.noise = msidfrf::from_row_major(noise, ny, ny);
    s.snr = snr_db;
    return msidfrf::line(std::move(pos), s);
}

double est_document_bytes(size_t lines, unsigned ny, unsigned nu)
{
    const double g = (double)ny * nu, reals = 2.0 * (g + 2.0 * g * g + (double)ny * ny);
    return 1.2 * (double)lines * (2048.0 + 130.0 * reals);
}

double usable_memory_bytes()
{
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    double m = pages > 0 && page > 0 ? (double)pages * (double)page : HUGE_VAL;
    struct rlimit rl;
    if (getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) m = std::min(m, (double)rl.rlim_cur);
    return m;
}

void check_document_memory(size_t lines, unsigned ny, unsigned nu, const std::string &what, const std::string &cure)
{
    const double need = est_document_bytes(lines, ny, nu), have = usable_memory_bytes();
    if (need <= 0.5 * have) return;
    throw Error(fmt("%s gives %zu lines (%u x %u), about %.2g GB of FRF document in memory, more than half of the "
                    "%.2g GB this process may use: %s",
                    what.c_str(), lines, ny, nu, need / 1e9, have / 1e9, cure.c_str()));
}

}  // namespace msidjob
