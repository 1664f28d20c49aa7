// exploratory MC: ML cost calibration and parameter covariance (not a test)
#include "fit_sim.hpp"
#include "lmfd_fit.hpp"
#include "subspace.hpp"
#include <cstdio>
using namespace msidfit;
int main(int argc, char **argv) {
    const int R = argc > 1 ? atoi(argv[1]) : 200;
    SSModel pl; pl.domain = Domain::DT;
    pl.A = MatR(2,2); pl.A << 1.2, -0.7, 1.0, 0.0; pl.B = MatR(2,1); pl.B << 1, 0; pl.C = MatR(1,2); pl.C << 0.5, 0.3; pl.D = MatR(1,1); pl.D << 0.1;
    static const uint32_t bins[] = {1,2,3,4,5,6,8,10,12,14,17,20,24,28,33,40,48,56,64,80};
    fitsim::Bench b; b.design.period = 256; b.design.n_lines = 20; b.design.bins = bins; b.design.n_inputs = 1; b.design.n_experiments = 1; b.design.seed = 3;
    b.ny = 1; b.K = atoi(argc > 2 ? argv[2] : "20"); b.sigma_y = 0.5; b.clean = fitsim::dt_plant(pl);
    fitsim::Runner run(b);
    msid_rng rng; msid_rng_seed(&rng, 42);
    LmfdSpec s; s.nD = 2; s.nN = 2;
    std::vector<VecR> th; double Vs = 0; MatR covsum; int n = 0;
    for (int r = 0; r < R; ++r) {
        FrfData f = run.run(rng);
        auto w = weigh(f, Domain::DT, Weight::Cov);
        auto st = lmfd_sk(w, Domain::DT, 0, s, 30);
        MlOptions o;
        auto res = lmfd_ml(w, Domain::DT, 0, s, st, o, false);
        th.push_back(res.theta); Vs += res.cost;
        if (!n) covsum = res.cov; else covsum += res.cov; ++n;
        if (r == 0) { printf("theta:"); for (int i=0;i<res.theta.size();++i) printf(" %s=%.4f", res.names[i].c_str(), res.theta(i)); printf("\ncost %.2f expected %.2f dof %.0f factor %.3f iters %d\n", res.cost, res.cost_expected, res.dof, res.cov_factor, res.iterations); }
    }
    VecR mean = VecR::Zero(th[0].size()); for (auto &t : th) mean += t; mean /= n;
    MatR emp = MatR::Zero(mean.size(), mean.size()); for (auto &t : th) emp += (t-mean)*(t-mean).transpose(); emp /= (n-1);
    covsum /= n;
    printf("mean cost %.2f\n", Vs / n);
    for (int i = 0; i < mean.size(); ++i) printf("param %d mean %.5f emp var %.3e rep var %.3e ratio %.3f\n", i, mean(i), emp(i,i), covsum(i,i), emp(i,i)/covsum(i,i));
}
