#include "frf_job_detail.hpp"
#include "frf_doc.hpp"
#include "frf_file.hpp"
#include "frf_text.hpp"
#include "msid_frf_job.hpp"

#include <cmath>

namespace msidjob {

// The first number in `j` that is NaN or infinite (JSON would write it as null), by its path; "" if none.
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

}  // namespace msidjob
