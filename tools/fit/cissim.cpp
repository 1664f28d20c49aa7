// Discrete-cISSIM system identification: ISP regression (Alg. 1 and 3), A, C, n
// (Alg. 4), B, D (Alg. 5). You, Huang, Zhang 2023; see cissim.hpp.
#include "cissim.hpp"
#include "real_dft.hpp"
#include "small_lu.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <memory>

namespace msidfit {

bool cissim_isp_auto_direct(size_t q, uint32_t period)
{
    return (double)q < 4.0 * std::log2((double)std::max<uint32_t>(period, 2));
}

// Sum of the K whole periods after `skip`: T x C (C = nu + ny), row-major like the record, and the
// output noise covariance per sample from the spread over the periods (K >= 2):
//   Sigma_v = (sum_k y_k y_k^T - (1/K) sum_n s_n s_n^T) / ((K - 1) T).
// One streaming pass: per period s += r and, for the diagonal, q += r .* r on T C contiguous doubles
// (vectorised, the accumulators stay in L2); cross products of different outputs (ny >= 2) in a second
// pass with scalar accumulators. This pass is the O(N) part of Alg. 1 / 3 and dominates the time.
static std::vector<double> period_sum(const double *rows, size_t n_rows, uint32_t C, uint32_t T, uint32_t skip,
                                      uint64_t &K, uint32_t nu, MatR &noise)
{
    const uint64_t total = n_rows / T;
    if (total <= skip)
        throw FitError("the record holds " + std::to_string(total) + " whole period(s) of " + std::to_string(T) +
                       " samples; skipping " + std::to_string(skip) + " leaves none");
    K = total - skip;
    const size_t TC = (size_t)T * C;
    std::vector<double> s(TC, 0.0), q(TC, 0.0);
    double *__restrict sp = s.data();
    double *__restrict qp = q.data();
    for (uint64_t p = skip; p < total; ++p) {
        const double *__restrict r = rows + (size_t)p * TC;
        for (size_t i = 0; i < TC; ++i) {
            const double v = r[i];
            sp[i] += v;
            qp[i] += v * v;
        }
    }
    noise.resize(0, 0);
    if (K < 2) return s;
    const uint32_t ny = C - nu;
    MatR syy = MatR::Zero(ny, ny);
    for (uint32_t a = 0; a < ny; ++a) {
        double d = 0;
        for (size_t k = 0; k < T; ++k) d += qp[k * C + nu + a] - sp[k * C + nu + a] * sp[k * C + nu + a] / (double)K;
        syy(a, a) = d;
        for (uint32_t b = 0; b < a; ++b) {
            double c = 0;
            const double *r = rows + (size_t)skip * TC;
            for (size_t k = 0; k < (size_t)K * T; ++k) c += r[k * C + nu + a] * r[k * C + nu + b];
            for (size_t k = 0; k < T; ++k) c -= sp[k * C + nu + a] * sp[k * C + nu + b] / (double)K;
            syy(a, b) = syy(b, a) = c;
        }
    }
    noise = syy / (double)((K - 1) * T);
    return s;
}

// Per-line sample covariance of the mean phasor over the periods (IspResult::line_cov): the phasors of
// each period at the bins (direct products or one FFT per channel and period, as the ISP), then
// S_l = sum_p (P_p - P)(P_p - P)^H / (K - 1) and S_l / K.
static void line_covariances(IspResult &r, const double *rows, uint32_t C, uint32_t skip, bool direct,
                             const std::vector<uint32_t> *cov_bins)
{
    const uint32_t T = r.period;
    const uint64_t K = r.periods;
    const size_t q = r.bins.size();
    if (K < 2) return;
    MatC mean(C, q);
    mean.topRows(r.U.rows()) = r.U;
    mean.bottomRows(r.Y.rows()) = r.Y;
    // the lines that get a covariance (all, or those of cov_bins), as indices into r.bins
    std::vector<size_t> want;
    for (size_t l = 0; l < q; ++l)
        if (!cov_bins || std::find(cov_bins->begin(), cov_bins->end(), r.bins[l]) != cov_bins->end()) want.push_back(l);
    r.line_cov.assign(q, MatC());
    // the upper triangles of sum_p (P_p - P)(P_p - P)^H, C x C row-major per wanted line
    std::vector<cd> acc(want.size() * C * C, cd(0));
    const double scale = 2.0 / T;
    MatC P(C, q);
    std::unique_ptr<RealDft> fft;
    std::vector<double> x(T), c, sn;
    std::vector<cd> X(T / 2 + 1);
    VecC d(C);
    if (!direct) fft = std::make_unique<RealDft>(T);
    if (direct) {
        c.resize(T), sn.resize(T);
        for (uint32_t n = 0; n < T; ++n) c[n] = std::cos(2.0 * M_PI * n / T), sn[n] = std::sin(2.0 * M_PI * n / T);
    }
    for (uint64_t p = skip; p < skip + K; ++p) {
        const double *pr = rows + (size_t)p * T * C;
        for (uint32_t j = 0; j < C; ++j) {
            if (direct) {
                for (size_t l = 0; l < q; ++l) {
                    double re = 0, im = 0;
                    uint64_t idx = 0;
                    for (uint32_t n = 0; n < T; ++n) {
                        re += pr[(size_t)n * C + j] * c[idx];
                        im -= pr[(size_t)n * C + j] * sn[idx];
                        idx += r.bins[l];
                        if (idx >= T) idx -= T;
                    }
                    P(j, (Eigen::Index)l) = cd(re, im) * scale;
                }
            } else {
                for (uint32_t n = 0; n < T; ++n) x[n] = pr[(size_t)n * C + j];
                fft->forward(x.data(), X.data());
                for (size_t l = 0; l < q; ++l) P(j, (Eigen::Index)l) = X[r.bins[l]] * scale;
            }
        }
        for (size_t w = 0; w < want.size(); ++w) {
            const Eigen::Index l = (Eigen::Index)want[w];
            for (uint32_t i = 0; i < C; ++i) d(i) = P(i, l) - mean(i, l);
            cd *a = &acc[w * C * C];
            for (uint32_t i = 0; i < C; ++i)
                for (uint32_t j = i; j < C; ++j) a[i * C + j] += d(i) * std::conj(d(j));
        }
    }
    const double f = 1.0 / ((double)(K - 1) * (double)K);
    for (size_t w = 0; w < want.size(); ++w) {
        MatC S(C, C);
        const cd *a = &acc[w * C * C];
        for (uint32_t i = 0; i < C; ++i)
            for (uint32_t j = i; j < C; ++j) {
                S(i, j) = a[i * C + j] * f;
                S(j, i) = std::conj(S(i, j));
            }
        r.line_cov[want[w]] = S;
    }
}

IspResult cissim_isp(const double *rows, size_t n_rows, uint32_t nu, uint32_t ny, uint32_t T,
                     const std::vector<uint32_t> &bins, uint32_t skip, IspMethod method, bool line_cov,
                     const std::vector<uint32_t> *cov_bins)
{
    if (T < 2) throw FitError("the period must be at least 2 samples");
    for (uint32_t b : bins)
        if (2 * (uint64_t)b >= T)
            throw FitError("line " + std::to_string(b) + " is not below half the period (" + std::to_string(T) +
                           " / 2): the ISP regression uses bins 0 .. ceil(T/2) - 1 (Corollary 1)");
    const uint32_t C = nu + ny;
    IspResult r;
    r.period = T;
    r.bins = bins;
    std::vector<double> s = period_sum(rows, n_rows, C, T, skip, r.periods, nu, r.noise);
    const size_t q = bins.size();
    const double scale = 2.0 / ((double)r.periods * T);   // Alg. 1 step 3: (K T / 2)^-1
    MatC P(C, q);
    const bool direct = method == IspMethod::Direct || (method == IspMethod::Auto && cissim_isp_auto_direct(q, T));
    r.used_fft = !direct;
    if (direct) {
        // Alg. 1 on the period sum: one pass over T samples per line (cos/sin table of length T)
        std::vector<double> c(T), sn(T);
        for (uint32_t n = 0; n < T; ++n) {
            const double th = 2.0 * M_PI * (double)n / T;
            c[n] = std::cos(th);
            sn[n] = std::sin(th);
        }
        std::vector<double> re(C), im(C);
        for (size_t l = 0; l < q; ++l) {
            std::fill(re.begin(), re.end(), 0.0);
            std::fill(im.begin(), im.end(), 0.0);
            uint64_t idx = 0;
            for (uint32_t n = 0; n < T; ++n) {
                const double *x = &s[(size_t)n * C];
                const double cc = c[idx], ss = sn[idx];
                for (uint32_t j = 0; j < C; ++j) { re[j] += x[j] * cc; im[j] -= x[j] * ss; }
                idx += bins[l];
                if (idx >= T) idx -= T;
            }
            for (uint32_t j = 0; j < C; ++j) P(j, l) = cd(re[j], im[j]) * scale;
        }
    } else {
        // Alg. 3: one FFT of length T of the period sum per channel
        RealDft fft(T);
        std::vector<double> x(T);
        std::vector<cd> X(T / 2 + 1);
        for (uint32_t j = 0; j < C; ++j) {
            for (uint32_t n = 0; n < T; ++n) x[n] = s[(size_t)n * C + j];
            fft.forward(x.data(), X.data());
            for (size_t l = 0; l < q; ++l) P(j, l) = X[bins[l]] * scale;
        }
    }
    r.U = P.topRows(nu);
    r.Y = P.bottomRows(ny);
    if (line_cov) line_covariances(r, rows, C, skip, direct, cov_bins);
    return r;
}

MatR cissim_isp_real(const IspResult &r)
{
    const Eigen::Index ny = r.Y.rows(), nu = r.U.rows();
    Eigen::Index s = 0;
    for (uint32_t b : r.bins) s += b == 0 ? 1 : 2;
    MatR R(s, ny + nu);
    Eigen::Index row = 0;
    for (size_t l = 0; l < r.bins.size(); ++l) {
        for (Eigen::Index j = 0; j < ny + nu; ++j) {
            const cd p = j < nu ? r.U(j, (Eigen::Index)l) : r.Y(j - nu, (Eigen::Index)l);
            if (r.bins[l] == 0) {
                R(row, j) = p.real() / std::sqrt(2.0);
            } else {
                R(row, j) = -p.imag();      // a_r (sine)
                R(row + 1, j) = p.real();   // b_r (cosine)
            }
        }
        row += r.bins[l] == 0 ? 1 : 2;
    }
    return R;
}

// Real columns of the phasor block X (rows x q) at the bins, multiplied by z^j (the
// paper's X (S^i)^j, in phasor form: a rotation by j theta), appended to the columns of
// dst starting at `col`. DC: one column P_0 / sqrt 2; other lines: Re and Im.
static Eigen::Index put_cols(MatR &dst, Eigen::Index r0, const MatC &X, const std::vector<uint32_t> &bins,
                             uint32_t T, int j, Eigen::Index col)
{
    for (size_t l = 0; l < bins.size(); ++l) {
        const cd z = std::polar(1.0, 2.0 * M_PI * (double)bins[l] * j / T);
        for (Eigen::Index i = 0; i < X.rows(); ++i) {
            const cd v = X(i, (Eigen::Index)l) * z;
            if (bins[l] == 0) {
                dst(r0 + i, col) = v.real() / std::sqrt(2.0);
            } else {
                dst(r0 + i, col) = v.real();
                dst(r0 + i, col + 1) = v.imag();
            }
        }
        col += bins[l] == 0 ? 1 : 2;
    }
    return col;
}

static Eigen::Index real_cols(const IspResult &r)
{
    Eigen::Index s = 0;
    for (uint32_t b : r.bins) s += b == 0 ? 1 : 2;
    return s;
}

void cissim_BD(SSModel &m, const std::vector<IspResult> &isp, bool estimate_D)
{
    const Eigen::Index n = m.A.rows(), ny = m.C.rows(), nu = isp[0].U.rows();
    const Eigen::Index nb = n * nu, nd = estimate_D ? ny * nu : 0;
    Eigen::Index rows = 0;
    for (const auto &r : isp) rows += real_cols(r) * ny;
    MatR Phi = MatR::Zero(rows, nb + nd);
    VecR rhs(rows);
    Eigen::Index row = 0;
    const MatC Ct = m.C.cast<cd>().transpose();
    SmallLu lu(n);
    MatC Kt;
    for (const auto &r : isp) {
        for (size_t l = 0; l < r.bins.size(); ++l) {
            const cd z = std::polar(1.0, 2.0 * M_PI * (double)r.bins[l] / r.period);
            // K = C (z I - A)^-1 (eq. 30), by a transposed solve
            lu.compute(m.A, z);
            lu.solve_t(Ct, Kt);
            const auto K = Kt.transpose();
            const VecC u = r.U.col((Eigen::Index)l);
            const bool dc = r.bins[l] == 0;
            const double w = dc ? 1.0 / std::sqrt(2.0) : 1.0;
            for (Eigen::Index i = 0; i < ny; ++i) {
                // row i of (u^T kron K) vec(B) + (u^T kron I) vec(D) (Alg. 5 step 3)
                VecC a = VecC::Zero(nb + nd);
                for (Eigen::Index b = 0; b < nu; ++b) {
                    for (Eigen::Index k = 0; k < n; ++k) a(k + n * b) = K(i, k) * u(b);
                    if (estimate_D) a(nb + i + ny * b) = u(b);
                }
                const cd y = r.Y(i, (Eigen::Index)l);
                Phi.row(row) = w * a.real().transpose();
                rhs(row++) = w * y.real();
                if (!dc) {
                    Phi.row(row) = a.imag().transpose();
                    rhs(row++) = y.imag();
                }
            }
        }
    }
    Phi.conservativeResize(row, Eigen::NoChange);
    rhs.conservativeResize(row);
    Eigen::ColPivHouseholderQR<MatR> qr(Phi);
    qr.setThreshold(1e-12);
    if (qr.rank() < Phi.cols())
        throw FitError("B and D are not identifiable from these lines (Alg. 5 regression has rank " +
                       std::to_string(qr.rank()) + " of " + std::to_string(Phi.cols()) +
                       "): every input needs excited lines (several experiments for several inputs at one line)");
    const VecR th = qr.solve(rhs);
    m.B = Eigen::Map<const MatR>(th.data(), n, nu);
    m.D = estimate_D ? MatR(Eigen::Map<const MatR>(th.data() + nb, ny, nu)) : MatR::Zero(ny, nu);
}

CissimResult cissim_fit(const std::vector<IspResult> &isp, const CissimOptions &o)
{
    if (isp.empty()) throw FitError("cissim needs at least one experiment");
    const Eigen::Index ny = isp[0].Y.rows(), nu = isp[0].U.rows();
    const uint32_t T = isp[0].period;
    for (const auto &r : isp)
        if (r.period != T || r.bins != isp[0].bins || r.Y.rows() != ny || r.U.rows() != nu)
            throw FitError("cissim: the experiments must share the period, the lines and the channels");
    CissimResult res;
    res.lines = isp[0].bins.size();
    res.order_estimated = o.order <= 0;
    const int nmax = o.order > 0 ? o.order : o.max_order;
    int nbar = o.block_rows;
    if (nbar <= 0) nbar = o.order > 0 ? std::max(2 * o.order, o.order + 1) : o.max_order + 1;
    if (ny * (nbar - 1) < nmax)
        throw FitError("order " + std::to_string(nmax) + " needs at least " + std::to_string((nmax + ny - 1) / ny + 1) +
                       " block rows with " + std::to_string(ny) + " output(s) (Alg. 4 step 8); got " +
                       std::to_string(nbar));
    res.block_rows = nbar;
    Eigen::Index s = 0;
    for (const auto &r : isp) s += real_cols(r);
    res.real_columns = (size_t)s;
    // eq. (31): q >= m (n + nbar) lines for persistent excitation (real columns count per line 2)
    const Eigen::Index need = (Eigen::Index)nu * (nmax + nbar);
    Eigen::Index q_all = 0;
    for (const auto &r : isp) q_all += (Eigen::Index)r.bins.size();
    const Eigen::Index ncol = (Eigen::Index)nbar * (nu + ny);
    if (q_all < need || s < ncol)
        throw FitError("the lines do not identify order " + std::to_string(nmax) + ": " + std::to_string(q_all) +
                       " line(s) over the experiments, the persistent-excitation condition (31) needs q >= nu (n + nbar) = " +
                       std::to_string(need) + " (nbar = " + std::to_string(nbar) +
                       " block rows); use more lines (--lines, or the full set without --reduced) or a lower --order");
    // Alg. 4 steps 1-3: [U; Y]^T with the block rows U S^j, Y S^j, then QR
    MatR UY(ncol, s);
    for (int j = 0; j < nbar; ++j) {
        Eigen::Index cu = 0, cy = 0;
        for (const auto &r : isp) {
            cu = put_cols(UY, (Eigen::Index)j * nu, r.U, r.bins, T, j, cu);
            cy = put_cols(UY, (Eigen::Index)nbar * nu + (Eigen::Index)j * ny, r.Y, r.bins, T, j, cy);
        }
    }
    Eigen::HouseholderQR<MatR> qr(UY.transpose());
    const MatR R = qr.matrixQR().topRows(ncol).triangularView<Eigen::Upper>();
    const Eigen::Index nU = (Eigen::Index)nbar * nu, nY = (Eigen::Index)nbar * ny;
    double r11max = 0;
    for (Eigen::Index i = 0; i < nU; ++i) r11max = std::max(r11max, std::abs(R(i, i)));
    for (Eigen::Index i = 0; i < nU; ++i)
        if (!(std::abs(R(i, i)) > 1e-10 * r11max) || !(r11max > 0))
            throw FitError("the input does not excite the chosen lines enough: the block Hankel matrix of the input "
                           "phasors has rank below nu nbar = " + std::to_string(nU) +
                           " (You et al. eq. 31); check that the input is excited at --lines");
    // step 4: SVD of R22^T, whitened by the noise covariance of the block rows (weighted)
    MatR R22t = R.bottomRightCorner(nY, nY).transpose();
    MatR Lw;
    if (o.weighted) {
        MatR Sv = MatR::Zero(ny, ny);
        double kw = 0;
        for (const auto &r : isp)
            if (r.noise.size()) { Sv += r.noise; kw += 1; }
        Sv = kw > 0 ? MatR(Sv / kw) : MatR(MatR::Identity(ny, ny));
        Sv.diagonal().array() += 1e-12 * std::max(Sv.diagonal().maxCoeff(), 1e-300);
        MatR Cn = MatR::Zero(nY, nY);
        std::vector<double> cosd((size_t)nbar);
        for (const auto &r : isp)
            for (uint32_t b : r.bins) {
                // E|P_r|^2 = 4 Sigma_v / (K T) per phasor: whitened noise singular values ~ 1
                const double th = 2.0 * M_PI * (double)b / T, c = (b == 0 ? 0.5 : 1.0) * 4.0 / ((double)r.periods * T);
                for (int d = 0; d < nbar; ++d) cosd[(size_t)d] = c * std::cos(d * th);   // Toeplitz in j - k
                for (int j = 0; j < nbar; ++j)
                    for (int k = 0; k < nbar; ++k)
                        Cn.block((Eigen::Index)j * ny, (Eigen::Index)k * ny, ny, ny) += cosd[(size_t)std::abs(j - k)] * Sv;
            }
        Eigen::LLT<MatR> llt(Cn);
        if (llt.info() == Eigen::Success) {
            Lw = llt.matrixL();
            R22t = llt.matrixL().solve(R22t);
        }
    }
    Eigen::JacobiSVD<MatR> svd(R22t, Eigen::ComputeThinU);
    const VecR sv = svd.singularValues();
    res.sv.assign(sv.data(), sv.data() + sv.size());
    int n = o.order;
    if (n <= 0 && Lw.size()) {
        // whitened: the noise singular values are ~1 (Marchenko-Pastur edge 1 + sqrt(nY / s)); the order
        // is the count above 1 + 4 sqrt(nY / (s - nU)) when some singular value is below (a noise floor)
        const double tau = 1.0 + 4.0 * std::sqrt((double)nY / std::max<double>(1.0, (double)(s - nU)));
        int above = 0;
        for (Eigen::Index k = 0; k < sv.size(); ++k) above += sv(k) > tau;
        if (above < (int)sv.size() && above >= 1) n = std::min(above, o.max_order);
    }
    if (n <= 0) {
        // Remark 3: the rank of R22 by its largest singular-value gap among 1..max_order
        double best = -1;
        for (int k = 1; k <= std::min<int>(o.max_order, (int)sv.size() - 1); ++k) {
            const double g = sv(k) > 0 ? sv(k - 1) / sv(k) : 1e300;
            if (g > best) { best = g; n = k; }
        }
        if (n <= 0) throw FitError("cannot estimate the order: give --order");
    }
    if (n > (int)(ny * (nbar - 1)) || n >= (int)sv.size() + 1)
        throw FitError("order " + std::to_string(n) + " is too high for " + std::to_string(nbar) + " block rows");
    res.order = n;
    // steps 6-8
    MatR O = svd.matrixU().leftCols(n) * sv.head(n).cwiseSqrt().asDiagonal();
    if (Lw.size()) O = Lw * O;
    SSModel &m = res.model;
    m.domain = Domain::DT;
    m.C = O.topRows(ny);
    const MatR Oup = O.topRows(ny * (nbar - 1)), Odn = O.bottomRows(ny * (nbar - 1));
    m.A = Oup.completeOrthogonalDecomposition().solve(Odn);
    if (o.stable && !ss_stable(m)) {
        m.B = MatR::Zero(n, nu);
        m.D = MatR::Zero(ny, nu);
        res.reflected = ss_reflect_unstable(m);
    }
    cissim_BD(m, isp, o.estimate_D);
    return res;
}

}  // namespace msidfit
