#pragma once
/// \file baseline_flow.hpp
/// The baselines' right-hand side and guards in fixed-size storage (N = the number of degrees of
/// freedom, or Eigen::Dynamic): the affine tables of baseline_events.hpp copied into
/// Eigen::Matrix<double, N, N> and friends when a contact mode is entered, so that a
/// right-hand side is two fixed-size n × n products and one cos and sin, with no allocation.
#include "baseline_events.hpp"

#include <cmath>

namespace vibro::bench {

template <int N>
struct FixedFlow {
  static constexpr int S = N == Eigen::Dynamic ? Eigen::Dynamic : 2 * N;
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  using State = Eigen::Matrix<double, S, 1>;
  using Rows = Eigen::Matrix<double, Eigen::Dynamic, N>;

  Eigen::Index n = 0;
  double omega = 0.0;
  // The current mode: x'' = f0 + fc cos + fs sin − K x − C v; held-stop forces λ = l0 + … − LK x − LC v.
  Mat K, C;
  Vec f0, fc, fs;
  Rows LK, LC;
  Eigen::VectorXd l0, lc, ls;
  ContactSet held;
  long evaluations = 0;

  template <class Z>
  auto xs(const Z& z) const {
    if constexpr (N == Eigen::Dynamic) return z.head(n);
    else return z.template head<N>();
  }
  template <class Z>
  auto vs(const Z& z) const {
    if constexpr (N == Eigen::Dynamic) return z.tail(n);
    else return z.template tail<N>();
  }

  void enter(const ModeTables& t) {
    K = t.K;
    C = t.C;
    f0 = t.f0;
    fc = t.fc;
    fs = t.fs;
    LK = t.LK;
    LC = t.LC;
    l0 = t.l0;
    lc = t.lc;
    ls = t.ls;
    held = t.set;
  }

  /// dz = [v; x''] at (t, z) (State or Eigen::Map of one).
  template <class Z, class DZ>
  void operator()(double t, const Z& z, DZ& dz) {
    ++evaluations;
    const double c = std::cos(omega * t), s = std::sin(omega * t);
    if constexpr (N == Eigen::Dynamic) {
      dz.head(n) = z.tail(n);
      dz.tail(n).noalias() = f0 + c * fc + s * fs;
      dz.tail(n).noalias() -= K * z.head(n);
      dz.tail(n).noalias() -= C * z.tail(n);
    } else {
      dz.template head<N>() = z.template tail<N>();
      dz.template tail<N>() = f0 + c * fc + s * fs - K * z.template head<N>() - C * z.template tail<N>();
    }
  }
};

/// Guards of a run's stops on a fixed-size state, in the current mode of `flow`.
template <int N>
struct FixedGuards {
  using Flow = FixedFlow<N>;
  using State = typename Flow::State;
  const BaselineEvents* events = nullptr;
  Eigen::Matrix<double, N, Eigen::Dynamic> normals;  ///< n × m
  std::vector<int> row;  ///< per stop: its row in the held set's tables, or -1 if free

  void init(const BaselineEvents& ev) {
    events = &ev;
    normals = ev.scene().normals();
    row.assign(static_cast<std::size_t>(ev.stops()), -1);
  }
  void enter(const Flow& flow) {
    std::fill(row.begin(), row.end(), -1);
    for (std::size_t a = 0; a < flow.held.size(); ++a) row[static_cast<std::size_t>(flow.held[a])] = static_cast<int>(a);
  }
  bool held(int j) const { return row[static_cast<std::size_t>(j)] >= 0; }
  /// g_j at (t, z): the gap of a free stop, −λ_j of a held one.
  template <class Z>
  double guard(const Flow& flow, int j, double t, const Z& z) const {
    const int a = row[static_cast<std::size_t>(j)];
    if (a < 0) {
      double g = normals.col(j).dot(flow.xs(z)) - events->stop(j).s0();
      if (events->moving(j)) {
        const double w = flow.omega;
        g -= events->stop(j).s_cos() * std::cos(w * t) + events->stop(j).s_sin() * std::sin(w * t);
      }
      return g;
    }
    const double w = flow.omega;
    return -(flow.l0(a) + flow.lc(a) * std::cos(w * t) + flow.ls(a) * std::sin(w * t) - flow.LK.row(a).dot(flow.xs(z)) -
             flow.LC.row(a).dot(flow.vs(z)));
  }
  /// dg_j/dt at (t, z); `dz` the right-hand side there (used for held stops only).
  template <class Z, class DZ>
  double guard_rate(const Flow& flow, int j, double t, const Z& z, const DZ& dz) const {
    const int a = row[static_cast<std::size_t>(j)];
    const double w = flow.omega;
    if (a < 0) {
      double r = normals.col(j).dot(flow.vs(z));
      if (events->moving(j))
        r -= w * (-events->stop(j).s_cos() * std::sin(w * t) + events->stop(j).s_sin() * std::cos(w * t));
      return r;
    }
    return -(w * (-flow.lc(a) * std::sin(w * t) + flow.ls(a) * std::cos(w * t)) - flow.LK.row(a).dot(flow.vs(z)) -
             flow.LC.row(a).dot(flow.vs(dz)));
  }
};

}  // namespace vibro::bench
