#include "vibro/models/chain.hpp"

#include <cmath>
#include <sstream>
#include <string>

namespace vibro::models {
namespace {

void check_entries(const std::vector<double>& values, const char* field, bool positive) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double v = values[i];
    if (!std::isfinite(v) || (positive ? !(v > 0.0) : v < 0.0))
      throw InvalidInput("chain." + std::string(field) + "[" + std::to_string(i) + "] = " + number_text(v) +
                         ": must be a finite number " + (positive ? "> 0" : "≥ 0"));
  }
}

void check_scalar(double v, const char* field) {
  if (!std::isfinite(v) || v < 0.0)
    throw InvalidInput("chain." + std::string(field) + " = " + number_text(v) +
                       ": must be a finite number ≥ 0");
}

void check_length(const std::vector<double>& values, std::size_t expected, const char* field,
                  bool may_be_empty) {
  if (values.size() != expected && !(may_be_empty && values.empty()))
    throw InvalidInput("chain." + std::string(field) + ": has " + std::to_string(values.size()) +
                       " entries, expected " + std::to_string(expected) +
                       (may_be_empty ? " (or none)" : ""));
}

Eigen::VectorXd per_mass(const std::vector<double>& values, std::size_t n) {
  Eigen::VectorXd v = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < values.size(); ++i) v(static_cast<Eigen::Index>(i)) = values[i];
  return v;
}

/// Tridiagonal matrix of links between neighbours plus the two wall links.
Eigen::MatrixXd assemble(const std::vector<double>& links, double left, double right,
                         std::size_t n) {
  const auto N = static_cast<Eigen::Index>(n);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(N, N);
  for (std::size_t i = 0; i < links.size(); ++i) {
    const auto j = static_cast<Eigen::Index>(i);
    a(j, j) += links[i];
    a(j + 1, j + 1) += links[i];
    a(j, j + 1) -= links[i];
    a(j + 1, j) -= links[i];
  }
  a(0, 0) += left;
  a(N - 1, N - 1) += right;
  return a;
}

}  // namespace

LinearSystem build_chain(const Chain& chain) {
  const std::size_t n = chain.masses.size();
  if (n == 0) throw InvalidInput("chain.masses: is empty: a chain needs at least one mass");
  check_length(chain.springs, n - 1, "springs", n == 1);
  check_length(chain.dampers, n - 1, "dampers", true);
  check_length(chain.force_constant, n, "force_constant", true);
  check_length(chain.force_cosine, n, "force_cosine", true);
  check_length(chain.force_sine, n, "force_sine", true);
  check_entries(chain.masses, "masses", true);
  check_entries(chain.springs, "springs", false);
  check_entries(chain.dampers, "dampers", false);
  check_scalar(chain.left_spring, "left_spring");
  check_scalar(chain.left_damper, "left_damper");
  check_scalar(chain.right_spring, "right_spring");
  check_scalar(chain.right_damper, "right_damper");

  Eigen::MatrixXd M = per_mass(chain.masses, n).asDiagonal();
  Eigen::MatrixXd K = assemble(chain.springs, chain.left_spring, chain.right_spring, n);
  Eigen::MatrixXd C = assemble(chain.dampers, chain.left_damper, chain.right_damper, n);
  HarmonicForcing f{per_mass(chain.force_constant, n), per_mass(chain.force_cosine, n),
                    per_mass(chain.force_sine, n), chain.frequency};
  return LinearSystem(std::move(M), std::move(C), std::move(K), std::move(f));
}

Chain wagg2004_chain(const Wagg2004& p) {
  Chain c;
  c.masses = {p.m, p.m};
  c.springs = {p.k};
  c.dampers = {p.c};
  c.left_spring = p.k;
  c.left_damper = p.c;
  c.force_cosine = {p.A1, p.A2};
  c.frequency = p.frequency;
  return c;
}

ImpactSystem wagg2004(const Wagg2004& p) {
  std::vector<Stop> stops{Stop::lower(0, p.s1, p.r), Stop::upper(1, p.s2, p.r)};
  stops[0].name = "s1 (below mass 1)";
  stops[1].name = "s2 (above mass 2)";
  return ImpactSystem(build_chain(wagg2004_chain(p)), std::move(stops));
}

}  // namespace vibro::models
