#include "lpm.hpp"
#include "msid_cancel.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <thread>

namespace msidest {

long lpm_dof(unsigned W, unsigned R, unsigned nu, unsigned m, bool transient)
{
    return (long)m * (2L * W + 1) - (long)(R + 1) * (nu + (transient ? m : 0));
}

unsigned lpm_default_window(unsigned R, unsigned nu, unsigned ny, unsigned m)
{
    unsigned W = 1;
    while (lpm_dof(W, R, nu, m) < (long)ny + 4) ++W;
    return W;
}

namespace {

// The fixed part of the local design for one window position: the window covers
// bins k+o .. k+o+2W, rho_t = (o+t)/W. wts = rho_t^a (a <= 2R) turns a window of
// data into its polynomial moments; the transient polynomials span {rho^s, s <= R},
// with orthonormal basis Q = P Rinv (P_ta = rho_t^a, QR of P), so projections onto
// them are fixed combinations of moments: sum_t Q_tc x_t = sum_a Rinv[a][c] (moment a of x).
struct WindowOp {
    std::vector<double> wts;    // n x (2R+1): wts[t * (2R+1) + a] = rho_t^a
    std::vector<double> rinv;   // (R+1) x (R+1), Rinv[a][c] at a*(R+1)+c (empty without transient)
};

WindowOp window_op(int o, unsigned W, unsigned R, bool transient)
{
    const unsigned n = 2 * W + 1, na = 2 * R + 1;
    WindowOp op;
    op.wts.resize((size_t)na * n);
    for (unsigned t = 0; t < n; ++t) {
        const double rho = (double)(o + (int)t) / (double)W;
        double p = 1;
        for (unsigned a = 0; a < na; ++a, p *= rho) op.wts[(size_t)t * na + a] = p;
    }
    if (transient) {
        Eigen::MatrixXd P(n, R + 1);
        for (unsigned t = 0; t < n; ++t)
            for (unsigned a = 0; a <= R; ++a) P(t, a) = op.wts[(size_t)t * na + a];
        Eigen::HouseholderQR<Eigen::MatrixXd> qr(P);
        const Eigen::MatrixXd Rm = qr.matrixQR().topRows(R + 1).triangularView<Eigen::Upper>();
        const Eigen::MatrixXd Ri = Rm.inverse();
        op.rinv.resize((size_t)(R + 1) * (R + 1));
        for (unsigned a = 0; a <= R; ++a)
            for (unsigned c = 0; c <= R; ++c) op.rinv[a * (R + 1) + c] = Ri(a, c);
    }
    return op;
}

// Moments sum_t rho_t^a x[t], a < na, of a complex sequence; wT[t * stride + a] = rho_t^a.
// t outer, a inner: 2 na independent accumulator chains instead of two long reductions.
inline void moments(const cd *x, const double *wT, unsigned stride, unsigned n, unsigned na, cd *out)
{
    double sr[17], si[17];
    for (unsigned a = 0; a < na; ++a) sr[a] = si[a] = 0.0;
    for (unsigned t = 0; t < n; ++t) {
        const double xr = x[t].real(), xi = x[t].imag();
        const double *w = wT + (size_t)t * stride;
        for (unsigned a = 0; a < na; ++a) {
            sr[a] += w[a] * xr;
            si[a] += w[a] * xi;
        }
    }
    for (unsigned a = 0; a < na; ++a) out[a] = cd(sr[a], si[a]);
}

// The first index >= i (or bins.size()) whose bin is a multiple of 16.
inline size_t align16(const std::vector<size_t> &bins, size_t i)
{
    if (i >= bins.size()) return bins.size();
    return std::min(bins.size(), i + (16 - bins[i] % 16) % 16);
}

// The sizes of one bin's local problem: the window of n = 2W+1 bins, ng = nu (R+1) regressors of the
// plant part (the inputs times the polynomial of order R), nT transient polynomials (0 without the
// transient), na = 2R+1 moments of a product sequence, nseq product sequences per experiment.
struct LocalDims {
    unsigned nu, ny, m, R, W, n, ng, g, na, nr, nT, npu, npy;
    size_t nseq;
};

LocalDims local_dims(const Spectra &S, const LpmConfig &cfg, unsigned W)
{
    LocalDims d;
    d.nu = S.nu, d.ny = S.ny, d.m = S.m, d.R = cfg.order, d.W = W;
    d.n = 2 * W + 1, d.ng = d.nu * (d.R + 1), d.g = d.ny * d.nu, d.na = 2 * d.R + 1, d.nr = d.R + 1;
    d.nT = cfg.transient ? d.R + 1 : 0;
    d.npu = d.nu * (d.nu + 1) / 2, d.npy = d.ny * (d.ny + 1) / 2;
    // per experiment: U_j conj U_j' (j <= j'), U_j, Y_i conj U_j, Y_i, Y_i conj Y_i' (i <= i')
    d.nseq = d.npu + d.nu + (size_t)d.ny * d.nu + d.ny + d.npy;
    return d;
}

// The products of the spectra over bins [lo, lo + span) into seq, per experiment in the order of
// LocalDims::nseq: every entry of the local normal equations is a moment of one of them, so they are
// formed once per block instead of once per window position.
void spectra_products(const Spectra &S, const LocalDims &d, size_t lo, size_t span, std::vector<cd> &seq)
{
    const unsigned nu = d.nu, ny = d.ny;
    seq.resize((size_t)d.m * d.nseq * span);
    for (unsigned e = 0; e < d.m; ++e) {
        cd *base = &seq[(size_t)e * d.nseq * span];
        size_t q = 0;
        for (unsigned j = 0; j < nu; ++j)
            for (unsigned j2 = j; j2 < nu; ++j2, ++q)
                for (size_t k = 0; k < span; ++k) base[q * span + k] = S.U(e, j)[lo + k] * std::conj(S.U(e, j2)[lo + k]);
        for (unsigned j = 0; j < nu; ++j, ++q)
            for (size_t k = 0; k < span; ++k) base[q * span + k] = S.U(e, j)[lo + k];
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned j = 0; j < nu; ++j, ++q)
                for (size_t k = 0; k < span; ++k) base[q * span + k] = S.Y(e, i)[lo + k] * std::conj(S.U(e, j)[lo + k]);
        for (unsigned i = 0; i < ny; ++i, ++q)
            for (size_t k = 0; k < span; ++k) base[q * span + k] = S.Y(e, i)[lo + k];
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned i2 = i; i2 < ny; ++i2, ++q)
                for (size_t k = 0; k < span; ++k) base[q * span + k] = S.Y(e, i)[lo + k] * std::conj(S.Y(e, i2)[lo + k]);
    }
}

// How many moments each product sequence needs (stride na): the inputs' products up to 2R (plant
// times plant), the inputs and outputs alone only with the transient, the cross products up to R,
// the outputs' products only their sum.
std::vector<unsigned> moment_counts(const LocalDims &d)
{
    std::vector<unsigned> naq;
    for (unsigned p = 0; p < d.npu; ++p) naq.push_back(d.na);
    for (unsigned j = 0; j < d.nu; ++j) naq.push_back(d.nT ? d.na : 0);
    for (unsigned p = 0; p < d.ny * d.nu; ++p) naq.push_back(d.nr);
    for (unsigned i = 0; i < d.ny; ++i) naq.push_back(d.nT ? d.nr : 0);
    for (unsigned p = 0; p < d.npy; ++p) naq.push_back(1);
    return naq;
}

// Sliding the interior window by one bin: S_a(k+1) = sum_b C(a,b) (-1/W)^(a-b) D_b with
// D_b = S_b(k) - (-1)^b p(k-W) + ((W+1)/W)^b p(k+W+1); bino holds C(a,b) (-1/W)^(a-b), vout the
// signs of the bin that left, vin the weights of the bin that entered. The moments are recomputed
// directly at bins k % 16 == 0, which bounds the rounding the slide accumulates.
struct SlideCoefs {
    std::vector<double> bino, vout, vin;
};

SlideCoefs slide_coefs(const LocalDims &d)
{
    const unsigned na = d.na, W = d.W;
    SlideCoefs sc;
    sc.bino.assign((size_t)na * na, 0.0);
    sc.vout.resize(na);
    sc.vin.resize(na);
    for (unsigned a = 0; a < na; ++a) {
        double c = 1;   // C(a, b) (-1/W)^(a-b), b = a down to 0
        for (unsigned b = a + 1; b-- > 0;) {
            sc.bino[(size_t)a * na + b] = c;
            c *= -(double)b / (double)(a - b + 1) / (double)W;
        }
        sc.vout[a] = a % 2 ? -1.0 : 1.0;
        sc.vin[a] = std::pow((W + 1.0) / W, (double)a);
    }
    return sc;
}

// One bin's buffers, reused from bin to bin: the moments, the transient projections cc and dd, the
// normal equations A (lower triangle), B, YY, the Cholesky factor Lc with its inverse diagonal, the
// solutions Z = Lc^-1 B and X = A^-1 B, and the inverse Li of the factor's trailing block with M.
struct BinScratch {
    std::vector<cd> mom, dl, cc, dd, A, Lc, B, Z, X, YY, Li, M;
    std::vector<double> invd;
    explicit BinScratch(const LocalDims &d)
        : mom((size_t)d.m * d.nseq * d.na), dl(d.na), cc((size_t)d.ng * d.nr), dd((size_t)d.ny * d.nr),
          A((size_t)d.ng * d.ng), Lc((size_t)d.ng * d.ng), B((size_t)d.ng * d.ny), Z((size_t)d.ng * d.ny),
          X((size_t)d.ng * d.ny), YY((size_t)d.ny * d.ny), Li((size_t)d.nu * d.nu), M((size_t)d.nu * d.nu),
          invd(d.ng)
    {
    }
};

// The moments of every product sequence over the window starting at bin w0 (x points at its first
// bin): slid from the previous bin's when `slide` (the interior window moved by one), else directly.
void window_moments(const std::vector<cd> &seq, const LocalDims &d, const std::vector<unsigned> &naq,
                    const SlideCoefs &sc, size_t span, size_t offset, const double *wts, bool slide, BinScratch &b)
{
    const unsigned na = d.na, n = d.n;
    for (unsigned e = 0; e < d.m; ++e)
        for (size_t q = 0; q < d.nseq; ++q) {
            const cd *x = &seq[((size_t)e * d.nseq + q) * span + offset];
            cd *Sm = &b.mom[((size_t)e * d.nseq + q) * na];
            const unsigned nq = naq[q];
            if (!slide) {
                moments(x, wts, na, n, nq, Sm);
                continue;
            }
            const cd pout = x[-1], pin = x[n - 1];   // p(k-1-W) left, p(k+W) entered
            for (unsigned k = 0; k < nq; ++k) b.dl[k] = Sm[k] - sc.vout[k] * pout + sc.vin[k] * pin;
            for (unsigned a = 0; a < nq; ++a) {
                cd v = 0;
                for (unsigned k = 0; k <= a; ++k) v += sc.bino[(size_t)a * na + k] * b.dl[k];
                Sm[a] = v;
            }
        }
}

// The local normal equations from the moments, summed over the experiments, with the transient
// block eliminated by the Schur complement (the projections cc, dd onto the orthonormal transient
// basis): A = K_G K_G^H - cc cc^H (lower triangle), B = K_G Y^H - cc dd^H, YY = Y Y^H - dd dd^H.
void normal_equations(const LocalDims &d, const WindowOp &op, BinScratch &b)
{
    const unsigned nu = d.nu, ny = d.ny, R = d.R, ng = d.ng, na = d.na, nr = d.nr, nT = d.nT, npu = d.npu;
    std::fill(b.A.begin(), b.A.end(), cd(0));
    std::fill(b.B.begin(), b.B.end(), cd(0));
    std::fill(b.YY.begin(), b.YY.end(), cd(0));
    for (unsigned e = 0; e < d.m; ++e) {
        const cd *base = &b.mom[(size_t)e * d.nseq * na];
        const cd *mpu = base, *mu = base + (size_t)npu * na, *mq = mu + (size_t)nu * na;
        const cd *mt = mq + (size_t)ny * nu * na, *my = mt + (size_t)ny * na;
        // projections on the transient basis: cc[(s,j), c] = sum_a Rinv[a][c] mu_j(s + a), dd[i, c]
        for (unsigned s = 0; s <= R; ++s)
            for (unsigned j = 0; j < nu; ++j)
                for (unsigned c = 0; c < nT; ++c) {
                    cd v = 0;
                    for (unsigned a = 0; a <= R; ++a) v += op.rinv[a * nr + c] * mu[(size_t)j * na + s + a];
                    b.cc[(size_t)((R - s) * nu + j) * nr + c] = v;
                }
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned c = 0; c < nT; ++c) {
                cd v = 0;
                for (unsigned a = 0; a <= R; ++a) v += op.rinv[a * nr + c] * mt[(size_t)i * na + a];
                b.dd[(size_t)i * nr + c] = v;
            }
        for (unsigned s = 0; s <= R; ++s)
            for (unsigned j = 0; j < nu; ++j) {
                const unsigned ra = (R - s) * nu + j;
                for (unsigned s2 = 0; s2 <= R; ++s2)
                    for (unsigned j2 = 0; j2 < nu; ++j2) {
                        const unsigned rb = (R - s2) * nu + j2;
                        if (rb > ra) continue;
                        const unsigned jl = std::min(j, j2), jh = std::max(j, j2);
                        const unsigned p = jl * nu - jl * (jl - 1) / 2 + (jh - jl);
                        cd v = mpu[(size_t)p * na + s + s2];
                        if (j > j2) v = std::conj(v);
                        for (unsigned c = 0; c < nT; ++c)
                            v -= b.cc[(size_t)ra * nr + c] * std::conj(b.cc[(size_t)rb * nr + c]);
                        b.A[(size_t)ra * ng + rb] += v;
                    }
                for (unsigned i = 0; i < ny; ++i) {
                    cd v = std::conj(mq[(size_t)(i * nu + j) * na + s]);
                    for (unsigned c = 0; c < nT; ++c) v -= b.cc[(size_t)ra * nr + c] * std::conj(b.dd[(size_t)i * nr + c]);
                    b.B[(size_t)ra * ny + i] += v;
                }
            }
        for (unsigned i = 0, p = 0; i < ny; ++i)
            for (unsigned i2 = i; i2 < ny; ++i2, ++p) {
                cd v = my[(size_t)p * na];
                for (unsigned c = 0; c < nT; ++c) v -= b.dd[(size_t)i * nr + c] * std::conj(b.dd[(size_t)i2 * nr + c]);
                b.YY[(size_t)i * ny + i2] += v;
            }
    }
    for (unsigned i = 0; i < ny; ++i)
        for (unsigned i2 = 0; i2 < i; ++i2) b.YY[(size_t)i * ny + i2] = std::conj(b.YY[(size_t)i2 * ny + i]);
}

// Cholesky A = Lc Lc^H with the inverse diagonal in invd; false where A is (nearly) singular: a pivot
// below 1e-12 of its diagonal (this regressor lies in the span of the others), or an input with
// (almost) no power in this window against its level in the record (pfloor), so that the bin is
// named instead of solved from noise.
bool local_cholesky(const LocalDims &d, const std::vector<double> &pfloor, BinScratch &b)
{
    const unsigned ng = d.ng;
    for (unsigned j = 0; j < ng; ++j) {
        double dj = b.A[(size_t)j * ng + j].real();
        const double d0 = dj;
        for (unsigned c = 0; c < j; ++c) dj -= std::norm(b.Lc[(size_t)j * ng + c]);
        if (!(dj > 1e-12 * d0) || !(d0 > pfloor[j % d.nu])) return false;
        const double ljj = std::sqrt(dj), inv = 1.0 / ljj;
        b.Lc[(size_t)j * ng + j] = ljj;
        b.invd[j] = inv;
        for (unsigned i = j + 1; i < ng; ++i) {
            cd v = b.A[(size_t)i * ng + j];
            for (unsigned c = 0; c < j; ++c) v -= b.Lc[(size_t)i * ng + c] * std::conj(b.Lc[(size_t)j * ng + c]);
            b.Lc[(size_t)i * ng + j] = v * inv;
        }
    }
    return true;
}

// Z = Lc^-1 B, and X = Lc^-H Z = A^-1 B = Theta^H for the G(k) unknowns only: they are last, so the
// back substitution for them depends on them alone (the polynomial's higher terms are not needed).
void local_solve(const LocalDims &d, BinScratch &b)
{
    const unsigned ng = d.ng, ny = d.ny;
    for (unsigned i = 0; i < ny; ++i) {
        for (unsigned a = 0; a < ng; ++a) {
            cd v = b.B[(size_t)a * ny + i];
            for (unsigned c = 0; c < a; ++c) v -= b.Lc[(size_t)a * ng + c] * b.Z[(size_t)c * ny + i];
            b.Z[(size_t)a * ny + i] = v * b.invd[a];
        }
        for (unsigned a = ng; a-- > d.R * d.nu;) {
            cd v = b.Z[(size_t)a * ny + i];
            for (unsigned c = a + 1; c < ng; ++c) v -= std::conj(b.Lc[(size_t)c * ng + a]) * b.X[(size_t)c * ny + i];
            b.X[(size_t)a * ny + i] = v * b.invd[a];
        }
    }
}

// The line's results into res at index bi: the noise covariance C_v = (YY - Z^H Z) / q, G(k) from X,
// and Cov vec(G) = M^T kron C_v with M = (L22 L22^H)^-1 the G(k) block of A^-1 (L22 the factor's
// trailing nu x nu block, inverted into Li).
void write_line(LpmResult &res, size_t bi, const LocalDims &d, double inv_q, BinScratch &b)
{
    const unsigned nu = d.nu, ny = d.ny, ng = d.ng, g = d.g;
    cd *G = &res.G[bi * g], *C = &res.cov[bi * g * g], *N = &res.noise[bi * ny * ny];
    for (unsigned i = 0; i < ny; ++i)
        for (unsigned i2 = 0; i2 < ny; ++i2) {
            cd v = b.YY[(size_t)i * ny + i2];
            for (unsigned a = 0; a < ng; ++a) v -= std::conj(b.Z[(size_t)a * ny + i]) * b.Z[(size_t)a * ny + i2];
            N[(size_t)i * ny + i2] = v * inv_q;
        }
    const unsigned o = d.R * nu;
    std::fill(b.Li.begin(), b.Li.end(), cd(0));
    for (unsigned j = 0; j < nu; ++j) {
        b.Li[(size_t)j * nu + j] = b.invd[o + j];
        for (unsigned i = j + 1; i < nu; ++i) {
            cd v = 0;
            for (unsigned c = j; c < i; ++c) v -= b.Lc[(size_t)(o + i) * ng + o + c] * b.Li[(size_t)c * nu + j];
            b.Li[(size_t)i * nu + j] = v * b.invd[o + i];
        }
    }
    for (unsigned a = 0; a < nu; ++a)
        for (unsigned c2 = 0; c2 < nu; ++c2) {
            cd v = 0;
            for (unsigned c = 0; c < nu; ++c) v += std::conj(b.Li[(size_t)c * nu + a]) * b.Li[(size_t)c * nu + c2];
            b.M[(size_t)a * nu + c2] = v;
        }
    for (unsigned i = 0; i < ny; ++i)
        for (unsigned j = 0; j < nu; ++j) G[i * nu + j] = std::conj(b.X[(size_t)(o + j) * ny + i]);
    // Cov[(i + ny j), (i2 + ny j2)] = C_v(i, i2) M(j2, j): M^T kron C_v in the column-stacked vec
    for (unsigned j = 0; j < nu; ++j)
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned j2 = 0; j2 < nu; ++j2)
                for (unsigned i2 = 0; i2 < ny; ++i2)
                    C[(size_t)(i + ny * j) * g + i2 + ny * j2] = N[(size_t)i * ny + i2] * b.M[(size_t)j2 * nu + j];
}

struct Worker {
    const Spectra &S;
    const LpmConfig &cfg;
    const std::vector<WindowOp> &ops;
    LpmResult &res;
    size_t Kmax;
    std::vector<double> pfloor;  // per input: 1e-12 x (window rows) x its mean |U|^2 over the record
    size_t bad_bin = 0;          // first singular bin in this worker's range (0: none)
    // the caller's cancellation token (msid_cancel.hpp), asked after each block of bins; true once it
    // asked this worker to stop (a worker thread never throws: lpm() throws for it after the joins)
    msidutil::Cancel *cancel = nullptr;
    bool stopped = false;

    // Normal equations of the local LS from products of the spectra (Part I: Theta =
    // Y K^H (K K^H)^-1 with K = [r^s U; r^s]): every entry of K K^H, Y K^H, Y Y^H is a
    // polynomial moment of U_j conj U_j', U_j, Y_i conj U_j, Y_i or Y_i conj Y_i' over the
    // window. The transient block is eliminated by the Schur complement with the fixed
    // orthonormal basis Q (equivalently: projecting onto the complement of the polynomials).
    std::vector<cd> seq;         // products of the spectra over one block of bins (reused)

    // Blocks of about 2048 bins keep the spectra products in cache. Blocks (and the thread
    // ranges, see lpm()) start at the band start or at a bin that is a multiple of 16, where
    // the moments are recomputed anyway: results do not depend on the threads or blocks.
    void run(size_t i0, size_t i1)
    {
        for (size_t b0 = i0; b0 < i1 && !bad_bin;) {
            const size_t b1 = std::min(i1, align16(res.bins, b0 + 2048));
            run_block(b0, b1);
            if (cancel && cancel->proceed_or_stop(msidutil::Step::lines, b1 - b0)) {
                stopped = true;
                return;
            }
            b0 = b1;
        }
    }

    // The lines of bins [i0, i1): the products of the spectra over the windows they touch, then per
    // bin its window's moments, normal equations, factor, solution and results. A singular bin sets
    // bad_bin and ends the block (lpm() names it).
    void run_block(size_t i0, size_t i1)
    {
        if (i0 >= i1) return;
        const LocalDims d = local_dims(S, cfg, res.W);
        const unsigned W = d.W;
        // products over the bins this worker's windows touch: [lo, hi)
        const size_t lo = std::min(std::max(res.bins[i0], (size_t)W + 1) - W, Kmax - 2 * W);
        const size_t hi = std::min(std::max(res.bins[i1 - 1], (size_t)W + 1) - W, Kmax - 2 * W) + d.n;
        const size_t span = hi - lo;
        spectra_products(S, d, lo, span, seq);
        const std::vector<unsigned> naq = moment_counts(d);
        const SlideCoefs sc = slide_coefs(d);
        BinScratch b(d);
        const double inv_q = 1.0 / (double)res.q;
        size_t prev_k = 0;
        for (size_t bi = i0; bi < i1; ++bi) {
            const size_t k = res.bins[bi];
            const size_t w0 = std::min(std::max(k, (size_t)W + 1) - W, Kmax - 2 * W);
            const WindowOp &op = ops[(size_t)(w0 + 2 * W - k)];
            const bool interior = w0 + W == k;
            const bool slide = interior && prev_k + 1 == k && k % 16 != 0;
            prev_k = interior ? k : 0;
            window_moments(seq, d, naq, sc, span, w0 - lo, op.wts.data(), slide, b);
            normal_equations(d, op, b);
            if (!local_cholesky(d, pfloor, b)) {
                bad_bin = k;
                return;
            }
            local_solve(d, b);
            write_line(res, bi, d, inv_q, b);
        }
    }
};

}  // namespace

LpmResult lpm(const Spectra &s, const LpmConfig &c)
{
    const unsigned nu = s.nu, ny = s.ny, m = s.m, R = c.order;
    if (nu == 0 || ny == 0 || m == 0) throw EstError("no inputs, outputs or experiments");
    if (R > 8) throw EstError("order R must be 0..8");
    const unsigned W = c.window ? c.window : lpm_default_window(R, nu, ny, m);
    const long q = lpm_dof(W, R, nu, m, c.transient);
    if (q <= 0) {
        unsigned wmin = 1;
        while (lpm_dof(wmin, R, nu, m, c.transient) <= 0) ++wmin;
        char b[400];
        std::snprintf(b, sizeof b,
                      "window W = %u is too small for order R = %u: %u experiment(s) x (2W+1) = %u bins leave "
                      "q = %ld <= 0 noise degrees of freedom after the (R+1)(nu+m) = %u parameters; use --window %u "
                      "or more (or a lower --order)",
                      W, R, m, m * (2 * W + 1), q, (R + 1) * (nu + (c.transient ? m : 0)), wmin);
        throw EstError(b);
    }
    const size_t Kmax = s.N >= 3 ? (s.N - 1) / 2 : 0;   // last bin below Nyquist
    if (2 * (size_t)W + 1 > Kmax) {
        char b[300];
        std::snprintf(b, sizeof b,
                      "record too short for the window: %zu samples give %zu bins between DC and Nyquist, the "
                      "window needs 2W+1 = %u (W = %u); record at least %zu samples or use a smaller --window",
                      s.N, Kmax, 2 * W + 1, W, (size_t)(2 * W + 1) * 2 + 2);
        throw EstError(b);
    }
    const size_t k_lo = c.k_lo, k_hi = c.k_hi ? c.k_hi : Kmax;
    if (k_lo < 1 || k_hi > Kmax || k_lo > k_hi) {
        char b[200];
        std::snprintf(b, sizeof b, "band bins %zu..%zu outside the usable bins 1..%zu (DC and Nyquist excluded)", k_lo,
                      k_hi, Kmax);
        throw EstError(b);
    }
    LpmResult res;
    res.N = s.N;
    res.nu = nu;
    res.ny = ny;
    res.m = m;
    res.R = R;
    res.W = W;
    res.q = (unsigned)q;
    const size_t nb = k_hi - k_lo + 1, g = (size_t)ny * nu;
    res.bins.resize(nb);
    for (size_t i = 0; i < nb; ++i) res.bins[i] = k_lo + i;
    res.G.resize(nb * g);
    res.cov.resize(nb * g * g);
    res.noise.resize(nb * ny * ny);
    std::vector<WindowOp> ops;
    for (int o = -2 * (int)W; o <= 0; ++o) ops.push_back(window_op(o, W, R, c.transient));

    const unsigned T = std::max(1u, std::min<unsigned>(c.threads, (unsigned)((nb + 1023) / 1024)));
    std::vector<double> pfloor(nu, 0.0);
    for (unsigned j = 0; j < nu; ++j) {
        double p = 0;
        for (unsigned e = 0; e < m; ++e)
            for (size_t k = 1; k <= Kmax; ++k) p += std::norm(s.U(e, j)[k]);
        pfloor[j] = 1e-12 * (2.0 * W + 1) * p / (double)Kmax;
    }
    std::vector<Worker> wk(T, Worker{s, c, ops, res, Kmax, pfloor, 0, msidutil::current_cancel(), false, {}});
    std::vector<std::thread> th;
    auto split = [&](unsigned t) { return t == 0 ? 0 : t == T ? nb : align16(res.bins, nb * t / T); };
    for (unsigned t = 1; t < T; ++t) th.emplace_back([&, t] { wk[t].run(split(t), split(t + 1)); });
    wk[0].run(0, split(1));
    for (auto &x : th) x.join();
    for (const auto &w : wk)
        if (w.stopped) throw msidutil::Cancelled{"the LPM"};
    for (const auto &w : wk)
        if (w.bad_bin) {
            char b[400];
            std::snprintf(b, sizeof b,
                          "the local input matrix is singular at bin %zu (%.6g cycles/sample): the inputs do not "
                          "excite the %u bins around it%s; restrict --band to where every input has power",
                          w.bad_bin, (double)w.bad_bin / s.N, 2 * W + 1,
                          nu > 1 ? " independently (inputs correlated or one missing)" : "");
            throw EstError(b);
        }
    return res;
}

}  // namespace msidest
