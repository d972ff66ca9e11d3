#pragma once
/// \file rk_steppers.hpp
/// Two embedded explicit Runge–Kutta pairs with their own continuous extensions, written for
/// fixed-size Eigen states (the baselines of rk_baseline.hpp):
///
///  * Dopri5: Dormand & Prince (1980), "A family of embedded Runge–Kutta formulae", J. Comput.
///    Appl. Math. 6, 19–26: order 5 with a 4th-order error estimate, 7 stages, first same as last
///    (6 evaluations per step), and the 4th-order dense output of Hairer, Nørsett & Wanner,
///    "Solving Ordinary Differential Equations I" (2nd ed., Springer 1993), §II.6 (Dormand &
///    Prince's continuous extension as in the book's DOPRI5: the coefficients d below).
///  * Dop853: Prince & Dormand (1981), "High order embedded Runge–Kutta formulae", J. Comput.
///    Appl. Math. 7, 67–75, in the 8(5,3) form of Hairer, Nørsett & Wanner, §II.10 (DOP853):
///    order 8, 12 stages plus the first-same-as-last one (12 evaluations per step), the error
///    estimate combining the 5th- and 3rd-order embedded solutions, and the 7th-order dense
///    output from three more stages (14–16), evaluated only for steps whose interior is asked
///    for. Coefficients: the published values as printed in that table (30 digits), checked
///    against the copy of the table distributed with SciPy (scipy/integrate/_ivp/
///    dop853_coefficients.py) and by the convergence test of this file's steps and interpolants
///    (tools/bench/rk_order_check.cpp: slopes 5, 4+1, 8, 7+1).
///
/// Error control (both, as Hairer's codes): sc_i = atol + rtol·max(|y0_i|, |y1_i|),
/// err = RMS(err_i / sc_i), a step is accepted when err ≤ 1; the next step
/// h·min(fac_max, max(fac_min, 0.9·err^(−1/q))) with q = 5 (Dopri5: fac ∈ [0.2, 10]) or 8
/// (Dop853: fac ∈ [1/3, 6]); fac_max = 1 right after a rejection.
///
/// Usage: Dopri5<State, Rhs> s(rhs, atol, rtol); s.init(t, z, h); while (...) { s.step(t_end);
///   s.state_at(t, out); }   — rhs(t, z, dz) is the right-hand side.
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>

namespace vibro::bench {

namespace rk_detail {
/// RMS of err_i / (atol + rtol·max(|y0_i|, |y1_i|)).
template <class State>
double error_norm(const State& err, const State& y0, const State& y1, double atol, double rtol) {
  const auto sc = (atol + rtol * y0.cwiseAbs().cwiseMax(y1.cwiseAbs()).array());
  return std::sqrt((err.array() / sc).square().sum() / static_cast<double>(err.size()));
}
}  // namespace rk_detail

template <class State, class Rhs>
class Dopri5 {
 public:
  static constexpr int order = 5;
  Dopri5(Rhs& rhs, double atol, double rtol) : rhs_(rhs), atol_(atol), rtol_(rtol) {}

  /// Starts at (t, z) with a first trial step h (evaluates f there).
  void init(double t, const State& z, double h) {
    t0_ = t1_ = t;
    z0_ = z1_ = z;
    for (auto& k : k_) k.resizeLike(z);
    y_.resizeLike(z);
    err_.resizeLike(z);
    for (auto& r : dense_) r = State::Zero(z.size());  // filled before use; zeroed for the compiler's sake
    rhs_(t, z, k_[6]);
    h_ = h;
    dense_ready_ = false;
  }
  /// One accepted step from t1() to at most t_limit. False if the step size underflows.
  bool step(double t_limit) {
    t0_ = t1_;
    z0_ = z1_;
    k_[0] = k_[6];  // first same as last
    bool rejected_before = false;
    for (int tries = 0; tries < 1000; ++tries) {
      const bool cut = t_limit - t0_ < h_;
      const double h = cut ? t_limit - t0_ : h_;
      if (!(h > 0.0) || t0_ + h == t0_) return false;
      y_ = z0_ + (h * a21) * k_[0];
      rhs_(t0_ + c2 * h, y_, k_[1]);
      y_ = z0_ + h * (a31 * k_[0] + a32 * k_[1]);
      rhs_(t0_ + c3 * h, y_, k_[2]);
      y_ = z0_ + h * (a41 * k_[0] + a42 * k_[1] + a43 * k_[2]);
      rhs_(t0_ + c4 * h, y_, k_[3]);
      y_ = z0_ + h * (a51 * k_[0] + a52 * k_[1] + a53 * k_[2] + a54 * k_[3]);
      rhs_(t0_ + c5 * h, y_, k_[4]);
      y_ = z0_ + h * (a61 * k_[0] + a62 * k_[1] + a63 * k_[2] + a64 * k_[3] + a65 * k_[4]);
      const double t_new = cut ? t_limit : t0_ + h;
      rhs_(t_new, y_, k_[5]);
      z1_ = z0_ + h * (a71 * k_[0] + a73 * k_[2] + a74 * k_[3] + a75 * k_[4] + a76 * k_[5]);
      rhs_(t_new, z1_, k_[6]);
      err_ = h * (e1 * k_[0] + e3 * k_[2] + e4 * k_[3] + e5 * k_[4] + e6 * k_[5] + e7 * k_[6]);
      const double err = rk_detail::error_norm(err_, z0_, z1_, atol_, rtol_);
      if (!std::isfinite(err)) {
        h_ = 0.1 * h;
        ++rejected;
        rejected_before = true;
        continue;
      }
      const double fac = 0.9 * std::pow(std::max(err, 1e-10), -1.0 / order);
      if (err <= 1.0) {
        const double grow = std::min(rejected_before ? 1.0 : 10.0, std::max(0.2, fac));
        // A step cut short by t_limit keeps the controller's proposal if that was larger.
        h_ = cut ? std::max(h_, h * grow) : h * grow;
        t1_ = t_new;
        hstep_ = h;
        dense_ready_ = false;
        return true;
      }
      h_ = h * std::max(0.2, fac);
      ++rejected;
      rejected_before = true;
    }
    return false;
  }
  double t0() const { return t0_; }
  double t1() const { return t1_; }
  double dt() const { return h_; }
  const State& z1() const { return z1_; }
  /// The state at t in [t0, t1] from the continuous extension (4th order).
  void state_at(double t, State& out) {
    if (t == t1_) {
      out = z1_;
      return;
    }
    if (!dense_ready_) {
      const double h = hstep_;
      dense_[0] = z1_ - z0_;
      dense_[1] = h * k_[0] - dense_[0];
      dense_[2] = dense_[0] - h * k_[6] - dense_[1];
      dense_[3] = h * (d1 * k_[0] + d3 * k_[2] + d4 * k_[3] + d5 * k_[4] + d6 * k_[5] + d7 * k_[6]);
      dense_ready_ = true;
    }
    const double th = (t - t0_) / hstep_, th1 = 1.0 - th;
    out = z0_ + th * (dense_[0] + th1 * (dense_[1] + th * (dense_[2] + th1 * dense_[3])));
  }
  long rejected = 0;

 private:
  // Dormand & Prince (1980), Table 2 (the 5th-order weights are the last row of a).
  static constexpr double c2 = 1.0 / 5, c3 = 3.0 / 10, c4 = 4.0 / 5, c5 = 8.0 / 9;
  static constexpr double a21 = 1.0 / 5;
  static constexpr double a31 = 3.0 / 40, a32 = 9.0 / 40;
  static constexpr double a41 = 44.0 / 45, a42 = -56.0 / 15, a43 = 32.0 / 9;
  static constexpr double a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561, a54 = -212.0 / 729;
  static constexpr double a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247, a64 = 49.0 / 176,
                          a65 = -5103.0 / 18656;
  static constexpr double a71 = 35.0 / 384, a73 = 500.0 / 1113, a74 = 125.0 / 192, a75 = -2187.0 / 6784,
                          a76 = 11.0 / 84;
  // 5th minus 4th order weights.
  static constexpr double e1 = 71.0 / 57600, e3 = -71.0 / 16695, e4 = 71.0 / 1920, e5 = -17253.0 / 339200,
                          e6 = 22.0 / 525, e7 = -1.0 / 40;
  // Dense output (Hairer, Nørsett & Wanner, DOPRI5's continuous extension).
  static constexpr double d1 = -12715105075.0 / 11282082432.0, d3 = 87487479700.0 / 32700410799.0,
                          d4 = -10690763975.0 / 1880347072.0, d5 = 701980252875.0 / 199316789632.0,
                          d6 = -1453857185.0 / 822651844.0, d7 = 69997945.0 / 29380423.0;

  Rhs& rhs_;
  double atol_, rtol_;
  double t0_ = 0.0, t1_ = 0.0, h_ = 0.0, hstep_ = 0.0;
  State z0_, z1_, y_, err_;
  std::array<State, 7> k_;
  std::array<State, 4> dense_;
  bool dense_ready_ = false;
};

namespace dop853 {
// Prince & Dormand (1981) 8(5,3) in the form of Hairer, Nørsett & Wanner §II.10: nodes c, the
// stage matrix a (row 12 holds the 8th-order weights b; rows 13–15 the dense output's extra
// stages), the 3rd-order weights bhh (at stages 1, 9, 12; b − bhh is the 3rd-order error), the
// 5th-order error weights e5, and the dense output's coefficients d (its 4th to 7th terms).
  constexpr double c[16] = {0.0, 0.526001519587677318785587544488e-01, 0.789002279381515978178381316732e-01, 0.118350341907227396726757197510, 0.281649658092772603273242802490, 0.333333333333333333333333333333, 0.25, 0.307692307692307692307692307692, 0.651282051282051282051282051282, 0.6, 0.857142857142857142857142857142, 1.0, 1.0, 0.1, 0.2, 0.777777777777777777777777777778};
  constexpr double a[16][16] = {
      {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {5.26001519587677318785587544488e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {2.95875854768068491816892993775e-2, 0.0, 8.87627564304205475450678981324e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {2.41365134159266685502369798665e-1, 0.0, -8.84549479328286085344864962717e-1, 9.24834003261792003115737966543e-1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {3.7037037037037037037037037037e-2, 0.0, 0.0, 1.70828608729473871279604482173e-1, 1.25467687566822425016691814123e-1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {3.7109375e-2, 0.0, 0.0, 1.70252211019544039314978060272e-1, 6.02165389804559606850219397283e-2, -1.7578125e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {3.70920001185047927108779319836e-2, 0.0, 0.0, 1.70383925712239993810214054705e-1, 1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2, 8.27378916381402288758473766002e-3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {6.24110958716075717114429577812e-1, 0.0, 0.0, -3.36089262944694129406857109825, -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1, 2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {4.77662536438264365890433908527e-1, 0.0, 0.0, -2.48811461997166764192642586468, -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1, 1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1, -2.03312017085086261358222928593e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {-9.3714243008598732571704021658e-1, 0.0, 0.0, 5.18637242884406370830023853209, 1.09143734899672957818500254654, -8.14978701074692612513997267357, -1.85200656599969598641566180701e1, 2.27394870993505042818970056734e1, 2.49360555267965238987089396762, -3.0467644718982195003823669022, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
      {2.27331014751653820792359768449, 0.0, 0.0, -1.05344954667372501984066689879e1, -2.00087205822486249909675718444, -1.79589318631187989172765950534e1, 2.79488845294199600508499808837e1, -2.85899827713502369474065508674, -8.87285693353062954433549289258, 1.23605671757943030647266201528e1, 6.43392746015763530355970484046e-1, 0.0, 0.0, 0.0, 0.0, 0.0},
      {5.42937341165687622380535766363e-2, 0.0, 0.0, 0.0, 0.0, 4.45031289275240888144113950566, 1.89151789931450038304281599044, -5.8012039600105847814672114227, 3.1116436695781989440891606237e-1, -1.52160949662516078556178806805e-1, 2.01365400804030348374776537501e-1, 4.47106157277725905176885569043e-2, 0.0, 0.0, 0.0, 0.0},
      {5.61675022830479523392909219681e-2, 0.0, 0.0, 0.0, 0.0, 0.0, 2.53500210216624811088794765333e-1, -2.46239037470802489917441475441e-1, -1.24191423263816360469010140626e-1, 1.5329179827876569731206322685e-1, 8.20105229563468988491666602057e-3, 7.56789766054569976138603589584e-3, -8.298e-3, 0.0, 0.0, 0.0},
      {3.18346481635021405060768473261e-2, 0.0, 0.0, 0.0, 0.0, 2.83009096723667755288322961402e-2, 5.35419883074385676223797384372e-2, -5.49237485713909884646569340306e-2, 0.0, 0.0, -1.08347328697249322858509316994e-4, 3.82571090835658412954920192323e-4, -3.40465008687404560802977114492e-4, 1.41312443674632500278074618366e-1, 0.0, 0.0},
      {-4.28896301583791923408573538692e-1, 0.0, 0.0, 0.0, 0.0, -4.69762141536116384314449447206, 7.68342119606259904184240953878, 4.06898981839711007970213554331, 3.56727187455281109270669543021e-1, 0.0, 0.0, 0.0, -1.39902416515901462129418009734e-3, 2.9475147891527723389556272149, -9.15095847217987001081870187138, 0.0},
  };
  // bhh (third-order weights) at stages 0, 8, 11
  constexpr double bhh[3] = {0.244094488188976377952755905512, 0.733846688281611857341361741547, 0.220588235294117647058823529412e-1};
  constexpr double e5[12] = {0.1312004499419488073250102996e-1, 0.0, 0.0, 0.0, 0.0, -0.1225156446376204440720569753e+1, -0.4957589496572501915214079952, 0.1664377182454986536961530415e+1, -0.3503288487499736816886487290, 0.3341791187130174790297318841, 0.8192320648511571246570742613e-1, -0.2235530786388629525884427845e-1};
  constexpr double d[4][16] = {
      {-0.84289382761090128651353491142e+1, 0.0, 0.0, 0.0, 0.0, 0.56671495351937776962531783590, -0.30689499459498916912797304727e+1, 0.23846676565120698287728149680e+1, 0.21170345824450282767155149946e+1, -0.87139158377797299206789907490, 0.22404374302607882758541771650e+1, 0.63157877876946881815570249290, -0.88990336451333310820698117400e-1, 0.18148505520854727256656404962e+2, -0.91946323924783554000451984436e+1, -0.44360363875948939664310572000e+1},
      {0.10427508642579134603413151009e+2, 0.0, 0.0, 0.0, 0.0, 0.24228349177525818288430175319e+3, 0.16520045171727028198505394887e+3, -0.37454675472269020279518312152e+3, -0.22113666853125306036270938578e+2, 0.77334326684722638389603898808e+1, -0.30674084731089398182061213626e+2, -0.93321305264302278729567221706e+1, 0.15697238121770843886131091075e+2, -0.31139403219565177677282850411e+2, -0.93529243588444783865713862664e+1, 0.35816841486394083752465898540e+2},
      {0.19985053242002433820987653617e+2, 0.0, 0.0, 0.0, 0.0, -0.38703730874935176555105901742e+3, -0.18917813819516756882830838328e+3, 0.52780815920542364900561016686e+3, -0.11573902539959630126141871134e+2, 0.68812326946963000169666922661e+1, -0.10006050966910838403183860980e+1, 0.77771377980534432092869265740, -0.27782057523535084065932004339e+1, -0.60196695231264120758267380846e+2, 0.84320405506677161018159903784e+2, 0.11992291136182789328035130030e+2},
      {-0.25693933462703749003312586129e+2, 0.0, 0.0, 0.0, 0.0, -0.15418974869023643374053993627e+3, -0.23152937917604549567536039109e+3, 0.35763911791061412378285349910e+3, 0.93405324183624310003907691704e+2, -0.37458323136451633156875139351e+2, 0.10409964950896230045147246184e+3, 0.29840293426660503123344363579e+2, -0.43533456590011143754432175058e+2, 0.96324553959188282948394950600e+2, -0.39177261675615439165231486172e+2, -0.14972683625798562581422125276e+3},
  };
}  // namespace dop853

template <class State, class Rhs>
class Dop853 {
 public:
  static constexpr int order = 8;
  Dop853(Rhs& rhs, double atol, double rtol) : rhs_(rhs), atol_(atol), rtol_(rtol) {}

  void init(double t, const State& z, double h) {
    t0_ = t1_ = t;
    z0_ = z1_ = z;
    for (auto& k : k_) k.resizeLike(z);
    y_.resizeLike(z);
    err3_.resizeLike(z);
    err5_.resizeLike(z);
    for (auto& r : dense_) r = State::Zero(z.size());
    rhs_(t, z, k_[12]);
    h_ = h;
    dense_ready_ = false;
  }
  bool step(double t_limit) {
    using namespace dop853;
    t0_ = t1_;
    z0_ = z1_;
    k_[0] = k_[12];  // first same as last
    bool rejected_before = false;
    for (int tries = 0; tries < 1000; ++tries) {
      const bool cut = t_limit - t0_ < h_;
      const double h = cut ? t_limit - t0_ : h_;
      if (!(h > 0.0) || t0_ + h == t0_) return false;
      for (int i = 1; i < 12; ++i) {
        y_ = z0_;
        for (int j = 0; j < i; ++j)
          if (a[i][j] != 0.0) y_ += (h * a[i][j]) * k_[static_cast<std::size_t>(j)];
        rhs_(t0_ + c[i] * h, y_, k_[static_cast<std::size_t>(i)]);
      }
      z1_ = z0_;
      err3_.setZero();
      err5_.setZero();
      for (int j = 0; j < 12; ++j) {
        const auto& kj = k_[static_cast<std::size_t>(j)];
        if (a[12][j] != 0.0) z1_ += (h * a[12][j]) * kj;
        if (e5[j] != 0.0) err5_ += e5[j] * kj;
      }
      err3_ = (a[12][0] - bhh[0]) * k_[0] + (a[12][8] - bhh[1]) * k_[8] + (a[12][11] - bhh[2]) * k_[11];
      for (int j : {5, 6, 7, 9, 10}) err3_ += a[12][j] * k_[static_cast<std::size_t>(j)];
      const double t_new = cut ? t_limit : t0_ + h;
      // Hairer's combined estimate: |h| Σ(e5/sc)² / √(n (Σ(e5/sc)² + 0.01 Σ(e3/sc)²)).
      const auto sc = (atol_ + rtol_ * z0_.cwiseAbs().cwiseMax(z1_.cwiseAbs()).array());
      const double s5 = (err5_.array() / sc).square().sum(), s3 = (err3_.array() / sc).square().sum();
      double den = s5 + 0.01 * s3;
      if (den <= 0.0) den = 1.0;
      const double err = std::abs(h) * s5 / std::sqrt(den * static_cast<double>(z0_.size()));
      if (!std::isfinite(err)) {
        h_ = 0.1 * h;
        ++rejected;
        rejected_before = true;
        continue;
      }
      const double fac = 0.9 * std::pow(std::max(err, 1e-16), -1.0 / order);
      if (err <= 1.0) {
        rhs_(t_new, z1_, k_[12]);
        const double grow = std::min(rejected_before ? 1.0 : 6.0, std::max(1.0 / 3.0, fac));
        h_ = cut ? std::max(h_, h * grow) : h * grow;
        t1_ = t_new;
        hstep_ = h;
        dense_ready_ = false;
        return true;
      }
      h_ = h * std::max(1.0 / 3.0, fac);
      ++rejected;
      rejected_before = true;
    }
    return false;
  }
  double t0() const { return t0_; }
  double t1() const { return t1_; }
  double dt() const { return h_; }
  const State& z1() const { return z1_; }
  /// The state at t in [t0, t1] from the 7th-order continuous extension.
  void state_at(double t, State& out) {
    using namespace dop853;
    if (t == t1_) {
      out = z1_;
      return;
    }
    const double h = hstep_;
    if (!dense_ready_) {
      for (int i = 13; i < 16; ++i) {
        y_ = z0_;
        for (int j = 0; j < i; ++j)
          if (a[i][j] != 0.0) y_ += (h * a[i][j]) * k_[static_cast<std::size_t>(j)];
        rhs_(t0_ + c[i] * h, y_, k_[static_cast<std::size_t>(i)]);
      }
      dense_[0] = z1_ - z0_;
      dense_[1] = h * k_[0] - dense_[0];
      dense_[2] = 2.0 * dense_[0] - h * (k_[12] + k_[0]);
      for (int r = 0; r < 4; ++r) {
        auto& out_r = dense_[static_cast<std::size_t>(r + 3)];
        out_r.setZero();
        for (int j = 0; j < 16; ++j)
          if (d[r][j] != 0.0) out_r += (h * d[r][j]) * k_[static_cast<std::size_t>(j)];
      }
      dense_ready_ = true;
    }
    const double s = (t - t0_) / h, s1 = 1.0 - s;
    out = z0_ + s * (dense_[0] + s1 * (dense_[1] + s * (dense_[2] + s1 * (dense_[3] + s * (dense_[4] + s1 *
                    (dense_[5] + s * dense_[6]))))));
  }
  long rejected = 0;

 private:
  Rhs& rhs_;
  double atol_, rtol_;
  double t0_ = 0.0, t1_ = 0.0, h_ = 0.0, hstep_ = 0.0;
  State z0_, z1_, y_, err3_, err5_;
  std::array<State, 16> k_;
  std::array<State, 7> dense_;
  bool dense_ready_ = false;
};

}  // namespace vibro::bench
