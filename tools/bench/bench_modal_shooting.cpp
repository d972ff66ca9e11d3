// Newton–Krylov shooting on the modal engine (analysis/shooting.hpp, modal_tangent.hpp) for long
// chains: a uniform chain (m = k = 1, a wall at the left, C = αM + βK) driven at its first mass,
// with an upper stop on mass 0 and a lower stop on mass 4. For each N: the modes' set-up, the
// guess (a run of `--periods` forcing periods from rest), then shooting to the period-1 orbit with
// GMRES steps and the leading Floquet multipliers by Arnoldi; reported with the work
// (iterations, J·v products, seconds per product) and an independent check: the orbit's residual
// after one more plain run of the engine, and the multipliers' prediction of how fast a perturbed
// start returns to it (or, unstable, leaves it), measured by running.
//
//   build/<dir>/tools/bench/bench_modal_shooting [--n 100,1000,4000] [--periods 6]
#include "vibro/modal_tangent.hpp"
#include "vibro/shooting.hpp"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

vibro::BandedChain chain_of(int n) {
  std::vector<double> masses(static_cast<std::size_t>(n), 1.0), springs(static_cast<std::size_t>(n - 1), 1.0);
  const double beta = 0.02;
  std::vector<double> dampers(springs.size(), beta);
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(n, 0.5);
  f.cosine(0) = 0.6;
  vibro::BandedChain c = vibro::BandedChain::from_links(masses, springs, dampers, 1.0, beta, 0.0, 0.0, f);
  c.rayleigh_mass = 0.05;
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Newton–Krylov shooting on the modal engine"};
  std::string sizes = "100,1000,4000";
  double periods = 6.0;
  app.add_option("--n", sizes, "chain lengths, comma-separated");
  app.add_option("--periods", periods, "periods of the guess's run from rest");
  CLI11_PARSE(app, argc, argv);

  fmt::print("| N | set-up s | guess s | shoot s | Newton its | GMRES products | Arnoldi products | residual | "
             "|μ1| | converged | Arnoldi residual | stable | rerun residual | |μ1| / measured per period |\n");
  fmt::print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::stringstream list(sizes);
  for (std::string item; std::getline(list, item, ',');) {
    const int n = std::stoi(item);
    const std::vector<vibro::Stop> stops{vibro::Stop::upper(0, 0.5, 0.8), vibro::Stop::lower(4, -0.12, 0.7)};
    const double T = 2.0 * std::numbers::pi / 0.5;
    auto t = std::chrono::steady_clock::now();
    vibro::ModalEngine engine(chain_of(n), stops, {});
    const double setup = seconds_since(t);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
    t = std::chrono::steady_clock::now();
    const vibro::RunSummary g = engine.run(0.0, zero, zero, periods * T);
    const double guess = seconds_since(t);
    t = std::chrono::steady_clock::now();
    const vibro::ShootingResult r = vibro::shoot(engine, {}, periods * T, g.x, g.v);
    const double shot = seconds_since(t);
    if (!r.converged()) {
      fmt::print("| {} | {:.2f} | {:.2f} | {:.2f} | not converged: {} |\n", n, setup, guess, shot, r.message);
      continue;
    }
    // Independent checks by plain runs: the orbit closes; a perturbation of the orbit decays at
    // the rate |μ1| predicts (over m periods, by |μ1|^m up to the eigenvector's projection).
    const vibro::RunSummary once = engine.run(r.t0, r.x, r.v, r.t0 + T);
    const double rerun = std::max((once.x - r.x).cwiseAbs().maxCoeff() / r.length_scale,
                                  (once.v - r.v).cwiseAbs().maxCoeff() / r.velocity_scale);
    // Measured: (d_m / d_1)^(1/(m−1)), d_j the distance from the orbit after j periods (a complex
    // leading pair makes d_j oscillate; over m = 40 periods that moves the root by a few %).
    // For an unstable orbit m is cut so that the perturbation stays linear (grows ≤ 1e3-fold).
    const double mu = r.multipliers.spectral_radius;
    const int m = mu > 1.0 ? std::clamp(static_cast<int>(std::log(1e3) / std::log(mu)), 2, 40) : 40;
    Eigen::VectorXd xp = r.x;
    xp(2) += 1e-6 * r.length_scale;  // between the stops: the unstable direction lives there
    const vibro::RunSummary a = engine.run(r.t0, xp, r.v, r.t0 + T);
    const vibro::RunSummary b = engine.run(r.t0 + T, a.x, a.v, r.t0 + m * T);
    const double d_a = std::hypot((a.x - r.x).norm(), (a.v - r.v).norm());
    const double d_b = std::pow(std::hypot((b.x - r.x).norm(), (b.v - r.v).norm()) / d_a, 1.0 / (m - 1));
    fmt::print("| {} | {:.2f} | {:.2f} | {:.2f} | {} | {} | {} | {:.1e} | {:.6f} | {} of {} | {:.1e} | {} | {:.1e} | {:.4f} / {:.4f} |\n",
               n, setup, guess, shot, r.iterations, r.krylov_products, r.multipliers.products, r.residual, mu,
               r.multipliers.converged_count, r.multipliers.values.size(), r.multipliers.ritz_residual,
               r.multipliers.stable ? "yes" : "no", rerun, mu, d_b);
  }
  return 0;
}
