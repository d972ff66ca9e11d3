#include "vibro/taylor/taylor_step.hpp"
#include "vibro/taylor/horner.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vibro::taylor {

void TaylorSettings::validate() const {
  if (!(tolerance > 0.0 && tolerance < 1e-2))
    throw std::invalid_argument("TaylorSettings.tolerance = " + std::to_string(tolerance) +
                                ": must lie in (0, 0.01) (it sets the order p = min(20, ceil(-0.7 ln(tolerance) + 1)))");
  if (order != 0 && (order < 3 || order > 60))
    throw std::invalid_argument("TaylorSettings.order = " + std::to_string(order) +
                                ": must be 0 (from the tolerance) or lie in [3, 60]");
}

namespace {

// The sums below run in four interleaved partial sums: four independent chains of additions,
// so a long sum runs at the multiplier's throughput rather than at the adder's latency (the
// result differs from the left-to-right sum by rounding only).

// With SSE2 the four sums are the lanes of two pairs: the same products added in the same
// order, so the same bits as the scalar code, in half the arithmetic instructions.

#if defined(__SSE2__)
/// (y[i], y[i − 1]): two entries of y read backwards.
inline __m128d reversed(const double* y, int i) {
  const __m128d v = _mm_loadu_pd(y + i - 1);
  return _mm_shuffle_pd(v, v, 1);
}
#endif

/// Σ_{j=lo}^{hi} x_j y_{k−j}
inline double convolution(const double* x, const double* y, int k, int lo, int hi) {
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
  int j = lo;
#if defined(__SSE2__)
  __m128d low = _mm_setzero_pd(), high = _mm_setzero_pd();  // (s0, s1), (s2, s3)
  for (; j + 3 <= hi; j += 4) {
    low = _mm_add_pd(low, _mm_mul_pd(_mm_loadu_pd(x + j), reversed(y, k - j)));
    high = _mm_add_pd(high, _mm_mul_pd(_mm_loadu_pd(x + j + 2), reversed(y, k - j - 2)));
  }
  s0 = _mm_cvtsd_f64(low);
  s1 = _mm_cvtsd_f64(_mm_unpackhi_pd(low, low));
  s2 = _mm_cvtsd_f64(high);
  s3 = _mm_cvtsd_f64(_mm_unpackhi_pd(high, high));
#else
  for (; j + 3 <= hi; j += 4) {
    s0 += x[j] * y[k - j];
    s1 += x[j + 1] * y[k - j - 1];
    s2 += x[j + 2] * y[k - j - 2];
    s3 += x[j + 3] * y[k - j - 3];
  }
#endif
  for (; j <= hi; ++j) s0 += x[j] * y[k - j];
  return (s0 + s1) + (s2 + s3);
}
/// Σ_{j=1}^{k} j a_j y_{k−j} / k
inline double weighted(const double* a, const double* y, int k) {
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, w = 1.0;  // w = j as a double
  int j = 1;
#if defined(__SSE2__)
  __m128d low = _mm_setzero_pd(), high = _mm_setzero_pd();  // (s0, s1), (s2, s3)
  __m128d w_low = _mm_set_pd(2.0, 1.0), w_high = _mm_set_pd(4.0, 3.0);
  const __m128d four = _mm_set1_pd(4.0);
  for (; j + 3 <= k; j += 4, w += 4.0) {
    low = _mm_add_pd(low, _mm_mul_pd(_mm_mul_pd(w_low, _mm_loadu_pd(a + j)), reversed(y, k - j)));
    high = _mm_add_pd(high, _mm_mul_pd(_mm_mul_pd(w_high, _mm_loadu_pd(a + j + 2)), reversed(y, k - j - 2)));
    w_low = _mm_add_pd(w_low, four);
    w_high = _mm_add_pd(w_high, four);
  }
  s0 = _mm_cvtsd_f64(low);
  s1 = _mm_cvtsd_f64(_mm_unpackhi_pd(low, low));
  s2 = _mm_cvtsd_f64(high);
  s3 = _mm_cvtsd_f64(_mm_unpackhi_pd(high, high));
#else
  for (; j + 3 <= k; j += 4, w += 4.0) {
    s0 += w * a[j] * y[k - j];
    s1 += (w + 1.0) * a[j + 1] * y[k - j - 1];
    s2 += (w + 2.0) * a[j + 2] * y[k - j - 2];
    s3 += (w + 3.0) * a[j + 3] * y[k - j - 3];
  }
#endif
  for (; j <= k; ++j, w += 1.0) s0 += w * a[j] * y[k - j];
  return ((s0 + s1) + (s2 + s3)) / k;
}

/// Orders first … last of the linear part for N coordinates known at compile time (n = 1, 2: the
/// impact oscillators' size), each after tape(k) (the forces' order k), the same operations in
/// the same order as the general loops of TaylorStep::tape_orders and linear_order (the same
/// bits), with the loops unrolled and the operands in registers. Writes z_[k+1] for k < p.
template <int N, class Tape>
void fixed_linear_orders(int first, int last, int p, std::size_t width, double* z, const double* c, const double* ax,
                         const double* av, const double* minv, const int* forces, const double* drive, Tape&& tape) {
  std::size_t force_at[N];
  bool has_force[N];
  for (int i = 0; i < N; ++i) {
    has_force[i] = forces[i] >= 0;
    force_at[i] = has_force[i] ? static_cast<std::size_t>(forces[i]) * width : 0;
  }
  for (int k = first; k <= last; ++k) {
    tape(k);
    const auto uk = static_cast<std::size_t>(k);
    double force[N], acc[N];
    for (int i = 0; i < N; ++i) force[i] = has_force[i] ? c[force_at[i] + uk] : 0.0;
    for (int i = 0; i < N; ++i) {
      double a = 0.0;
      for (int j = 0; j < N; ++j)
        a += ax[i + j * N] * z[static_cast<std::size_t>(j) * width + uk] +
             av[i + j * N] * z[static_cast<std::size_t>(N + j) * width + uk] + minv[i + j * N] * force[j];
      acc[i] = drive ? a + drive[static_cast<std::size_t>(i) + uk * N] : a;
    }
    if (k == p) break;
    const double scale = 1.0 / (k + 1);
    for (int i = 0; i < N; ++i) {
      z[static_cast<std::size_t>(i) * width + uk + 1] = z[static_cast<std::size_t>(N + i) * width + uk] * scale;
      z[static_cast<std::size_t>(N + i) * width + uk + 1] = acc[i] * scale;
    }
  }
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

}  // namespace

TaylorStep::TaylorStep(const TaylorSystem& system, TaylorSettings settings)
    : system_(&system), settings_(settings) {
  settings_.validate();
  p_ = settings_.order > 0 ? settings_.order : std::min(20, static_cast<int>(std::ceil(-0.7 * std::log(settings_.tolerance) + 1.0)));
  safety_ = std::exp(-0.7 / (p_ - 1));
  inverse_root_[0] = std::pow(settings_.tolerance, -1.0 / (p_ - 1));
  inverse_root_[1] = std::pow(settings_.tolerance, -1.0 / p_);
  dim_ = system.state_size();
  parameters_ = system.parameter_values();
  const std::size_t nodes = static_cast<std::size_t>(system.dag().size());
  const std::size_t width = static_cast<std::size_t>(p_) + 1;
  c_.assign(nodes * width, 0.0);
  aux_.assign(nodes * width, 0.0);
  z_.assign(static_cast<std::size_t>(dim_) * width, 0.0);
  force_k_.resize(system.coordinates());
  acc_k_.resize(system.coordinates());
  if (settings_.variational) {
    dc_.assign(nodes * dim_ * width, 0.0);  // time-constant nodes' tangents stay 0
    y_.assign(static_cast<std::size_t>(dim_) * dim_ * width, 0.0);
    dforce_k_.resize(system.coordinates(), dim_);
    dacc_k_.resize(system.coordinates(), dim_);
  }
  const std::vector<DagNode>& dag = system.dag().nodes();
  for (std::size_t id = 0; id < dag.size(); ++id) {
    const DagNode& n = dag[id];
    if (n.time_constant) continue;  // its orders ≥ 1 are 0 (zeroed above, never written)
    Instruction in{Code::Time, id * width, n.a >= 0 ? static_cast<std::size_t>(n.a) * width : 0,
                   n.b >= 0 ? static_cast<std::size_t>(n.b) * width : 0, n.value};
    switch (n.op) {
      case Op::Constant: case Op::Parameter: continue;  // time-constant (not reached)
      case Op::Time: in.code = Code::Time; break;
      case Op::State: in.code = Code::State; in.a = static_cast<std::size_t>(n.index) * width; break;
      case Op::Add: in.code = Code::Add; break;
      case Op::Subtract: in.code = Code::Subtract; break;
      case Op::Negate: in.code = Code::Negate; break;
      case Op::Multiply:
        in.code = dag[n.a].time_constant ? Code::ScaleLeft : (dag[n.b].time_constant ? Code::ScaleRight : Code::Multiply);
        break;
      case Op::Square: in.code = Code::Square; break;
      case Op::Divide: in.code = dag[n.b].time_constant ? Code::DivideByConstant : Code::Divide; break;
      case Op::PowerReal: in.code = Code::PowerReal; break;
      case Op::Sqrt: in.code = Code::Sqrt; break;
      case Op::Exp: in.code = Code::Exp; break;
      case Op::Log: in.code = Code::Log; break;
      case Op::Sin: in.code = Code::Sin; break;
      case Op::Cos: in.code = Code::Cos; break;
      case Op::Tan: in.code = Code::Tan; break;
      case Op::Tanh: in.code = Code::Tanh; break;
      case Op::Atan: in.code = Code::Atan; break;
    }
    tape_.push_back(in);
  }
}

void TaylorStep::set_terms(const StepTerms& terms) {
  const int n = system_->coordinates();
  if (terms.acceleration && (terms.acceleration->rows() != n || terms.acceleration->cols() != p_ + 1))
    throw std::invalid_argument("StepTerms.acceleration must be n x (p + 1)");
  for (const Eigen::MatrixXd* a : {terms.position_matrix, terms.velocity_matrix})
    if (a && (a->rows() != n || a->cols() != n)) throw std::invalid_argument("StepTerms: A_x and A_v must be n x n");
  if (terms.normals) {
    const Eigen::Index m = terms.normals->cols();
    if (!terms.minv_normals || !terms.delassus_inverse || !terms.stop_acceleration || terms.normals->rows() != n ||
        terms.minv_normals->rows() != n || terms.minv_normals->cols() != m || terms.delassus_inverse->rows() != m ||
        terms.delassus_inverse->cols() != m || terms.stop_acceleration->rows() != m ||
        terms.stop_acceleration->cols() != p_ + 1)
      throw std::invalid_argument("StepTerms: a held set needs W, M^-1 W (n x k), G^-1 (k x k) and p'' (k x (p + 1))");
    if (lambda_.size() < static_cast<std::size_t>(m) * (p_ + 1)) lambda_.assign(static_cast<std::size_t>(m) * (p_ + 1), 0.0);
    if (residual_k_.size() < m) {
      residual_k_.resize(m);
      lambda_k_.resize(m);
    }
    if (settings_.variational && dresidual_k_.rows() < m) dresidual_k_.resize(m, dim_);
  }
  terms_ = terms;
}

StepStatus TaylorStep::rate(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0, Eigen::Ref<Eigen::VectorXd> out) {
  trouble_.clear();
  t0_ = t0;
  for (int i = 0; i < dim_; ++i) zc(i)[0] = z0[i];
  if (!z0.allFinite()) {
    trouble_ = "the state is not finite at t = " + number(t0);
    return StepStatus::not_finite;
  }
  if (!compute_order(0)) return StepStatus::domain_error;
  for (int i = 0; i < dim_; ++i) out[i] = zc(i)[1];
  return out.allFinite() ? StepStatus::ok : StepStatus::not_finite;
}

const double* TaylorStep::guard_coefficients(int g) const {
  return &c_[static_cast<std::size_t>(system_->guard_nodes()[g]) * (p_ + 1)];
}

#if defined(__GNUC__) || defined(__clang__)
[[gnu::always_inline]]
#endif
inline void TaylorStep::tape_order(int k) {
  // The same recurrences as node_order (the same operations in the same order: the same bits),
  // without the Dag's indirections.
  double* c = c_.data();
  double* u = aux_.data();
  const double* z = z_.data();
  for (const Instruction& in : tape_) {
    double* C = c + in.out;
    const double* A = c + in.a;
    const double* B = c + in.b;
    switch (in.code) {
      case Code::Time: C[k] = k == 1 ? 1.0 : 0.0; break;
      case Code::State: C[k] = z[in.a + static_cast<std::size_t>(k)]; break;
      case Code::Add: C[k] = A[k] + B[k]; break;
      case Code::Subtract: C[k] = A[k] - B[k]; break;
      case Code::Negate: C[k] = -A[k]; break;
      case Code::ScaleLeft: C[k] = A[0] * B[k]; break;
      case Code::ScaleRight: C[k] = A[k] * B[0]; break;
      case Code::Multiply: C[k] = convolution(A, B, k, 0, k); break;
      case Code::Square:
        C[k] = 2.0 * convolution(A, A, k, 0, (k + 1) / 2 - 1) + (k % 2 == 0 ? A[k / 2] * A[k / 2] : 0.0);
        break;
      case Code::DivideByConstant: C[k] = A[k] / B[0]; break;
      case Code::Divide: C[k] = (A[k] - convolution(B, C, k, 1, k)) / B[0]; break;
      case Code::PowerReal: {
        double s = 0.0;
        for (int j = 0; j < k; ++j) s += (in.value * (k - j) - j) * A[k - j] * C[j];
        C[k] = s / (k * A[0]);
        break;
      }
      case Code::Sqrt: C[k] = (A[k] - convolution(C, C, k, 1, k - 1)) / (2.0 * C[0]); break;
      case Code::Exp: C[k] = weighted(A, C, k); break;
      case Code::Log: {
        double s = 0.0;
        for (int j = 1; j < k; ++j) s += j * C[j] * A[k - j];
        C[k] = (A[k] - s / k) / A[0];
        break;
      }
      case Code::Sin: {
        double* U = u + in.out;
        C[k] = weighted(A, U, k);
        U[k] = -weighted(A, C, k);
        break;
      }
      case Code::Cos: C[k] = u[in.a + static_cast<std::size_t>(k)]; break;
      case Code::Tan: {
        double* U = u + in.out;
        C[k] = weighted(A, U, k);
        U[k] = convolution(C, C, k, 0, k);
        break;
      }
      case Code::Tanh: {
        double* U = u + in.out;
        C[k] = weighted(A, U, k);
        U[k] = -convolution(C, C, k, 0, k);
        break;
      }
      case Code::Atan: {
        double* U = u + in.out;
        U[k] = convolution(A, A, k, 0, k);
        double s = 0.0;
        for (int j = 1; j < k; ++j) s += (k - j) * U[j] * C[k - j];
        C[k] = (A[k] - s / k) / U[0];
        break;
      }
    }
  }
}

bool TaylorStep::compute_order(int k) {
  if (!node_order(k)) return false;
  return linear_order(k);
}

void TaylorStep::tape_orders() {
  // Orders 1 … p without tangents: the tape, then the linear part (as linear_order, the same
  // operations in the same order) with every loop bound and matrix hoisted out of the orders.
  const int n = system_->coordinates();
  const std::size_t width = static_cast<std::size_t>(p_) + 1;
  const auto un = static_cast<std::size_t>(n);
  double* z = z_.data();
  const double* c = c_.data();
  const double* ax = position_matrix().data();  // column-major n × n
  const double* av = velocity_matrix().data();
  const double* minv = system_->inverse_mass().data();
  const int* forces = system_->force_nodes().data();
  const double* drive = terms_.acceleration ? terms_.acceleration->data() : nullptr;  // n × (p + 1)
  const bool held = terms_.normals != nullptr;
  double* force = force_k_.data();
  double* acc = acc_k_.data();
  if (!held && (n == 1 || n == 2)) {
    // The tape inlined into the loop of the orders (no call per order).
    auto tape = [this](int k)
#if defined(__GNUC__) || defined(__clang__)
                    __attribute__((always_inline))
#endif
    { tape_order(k); };
    if (n == 1) fixed_linear_orders<1>(1, p_, p_, width, z, c, ax, av, minv, forces, drive, tape);
    else fixed_linear_orders<2>(1, p_, p_, width, z, c, ax, av, minv, forces, drive, tape);
    return;
  }
  for (int k = 1; k <= p_; ++k) {
    tape_order(k);
    if (held) {  // the constraint's projection (Eigen products): the general path
      linear_order(k);
      continue;
    }
    const auto uk = static_cast<std::size_t>(k);
    for (std::size_t i = 0; i < un; ++i) force[i] = forces[i] >= 0 ? c[static_cast<std::size_t>(forces[i]) * width + uk] : 0.0;
    for (std::size_t i = 0; i < un; ++i) {
      double a = 0.0;
      for (std::size_t j = 0; j < un; ++j)
        a += ax[i + j * un] * z[j * width + uk] + av[i + j * un] * z[(un + j) * width + uk] + minv[i + j * un] * force[j];
      acc[i] = drive ? a + drive[i + uk * un] : a;
    }
    if (k == p_) break;
    const double scale = 1.0 / (k + 1);
    for (std::size_t i = 0; i < un; ++i) {
      z[i * width + uk + 1] = z[(un + i) * width + uk] * scale;
      z[(un + i) * width + uk + 1] = acc[i] * scale;
    }
  }
}

bool TaylorStep::node_order(int k) {
  const std::vector<DagNode>& nodes = system_->dag().nodes();
  const int count = static_cast<int>(nodes.size());
  const bool tangents = settings_.variational;
  for (int id = 0; id < count; ++id) {
    const DagNode& n = nodes[id];
    double* C = c(id);
    if (n.time_constant && k > 0) continue;  // its orders ≥ 1 are 0 (zeroed by the constructor, never written)
    const double* A = n.a >= 0 ? c(n.a) : nullptr;
    const double* B = n.b >= 0 ? c(n.b) : nullptr;
    double* U = aux(id);
    auto domain = [&](const std::string& what) {
      trouble_ = system_->dag().describe(id) + ": " + what + " at t = " + number(t0_);
      return false;
    };
    switch (n.op) {
      case Op::Constant: C[k] = k == 0 ? n.value : 0.0; break;
      case Op::Parameter: C[k] = k == 0 ? parameters_[n.index] : 0.0; break;
      case Op::Time: C[k] = k == 0 ? t0_ : (k == 1 ? 1.0 : 0.0); break;
      case Op::State: C[k] = zc(n.index)[k]; break;
      case Op::Add: C[k] = A[k] + B[k]; break;
      case Op::Subtract: C[k] = A[k] - B[k]; break;
      case Op::Negate: C[k] = -A[k]; break;
      case Op::Multiply:
        if (nodes[n.a].time_constant) C[k] = A[0] * B[k];
        else if (nodes[n.b].time_constant) C[k] = A[k] * B[0];
        else C[k] = convolution(A, B, k, 0, k);
        break;
      case Op::Square:
        C[k] = 2.0 * convolution(A, A, k, 0, (k + 1) / 2 - 1) + (k % 2 == 0 ? A[k / 2] * A[k / 2] : 0.0);
        break;
      case Op::Divide:
        if (k == 0 && B[0] == 0.0) return domain("division by zero");
        C[k] = nodes[n.b].time_constant ? A[k] / B[0] : (A[k] - convolution(B, C, k, 1, k)) / B[0];
        break;
      case Op::PowerReal:
        if (k == 0) {
          if (A[0] == 0.0) return domain("base 0 of a real power (its derivatives are unbounded)");
          C[0] = std::pow(A[0], n.value);
          if (!std::isfinite(C[0])) return domain("real power of the base " + number(A[0]));
        } else {
          double s = 0.0;
          for (int j = 0; j < k; ++j) s += (n.value * (k - j) - j) * A[k - j] * C[j];
          C[k] = s / (k * A[0]);
        }
        break;
      case Op::Sqrt:
        if (k == 0) {
          if (!(A[0] > 0.0)) return domain("square root of " + number(A[0]) + " (needs a positive argument)");
          C[0] = std::sqrt(A[0]);
        } else {
          C[k] = (A[k] - convolution(C, C, k, 1, k - 1)) / (2.0 * C[0]);
        }
        break;
      case Op::Exp: C[k] = k == 0 ? std::exp(A[0]) : weighted(A, C, k); break;
      case Op::Log:
        if (k == 0) {
          if (!(A[0] > 0.0)) return domain("logarithm of " + number(A[0]) + " (needs a positive argument)");
          C[0] = std::log(A[0]);
        } else {
          double s = 0.0;
          for (int j = 1; j < k; ++j) s += j * C[j] * A[k - j];
          C[k] = (A[k] - s / k) / A[0];
        }
        break;
      case Op::Sin:  // U holds cos a
        if (k == 0) {
          C[0] = std::sin(A[0]);
          U[0] = std::cos(A[0]);
        } else {
          C[k] = weighted(A, U, k);
          U[k] = -weighted(A, C, k);
        }
        break;
      case Op::Cos: C[k] = aux(n.a)[k]; break;
      case Op::Tan:  // U = 1 + tan²
        if (k == 0) {
          C[0] = std::tan(A[0]);
          U[0] = 1.0 + C[0] * C[0];
        } else {
          C[k] = weighted(A, U, k);
          U[k] = convolution(C, C, k, 0, k);
        }
        break;
      case Op::Tanh:  // U = 1 − tanh²
        if (k == 0) {
          C[0] = std::tanh(A[0]);
          U[0] = 1.0 - C[0] * C[0];
        } else {
          C[k] = weighted(A, U, k);
          U[k] = -convolution(C, C, k, 0, k);
        }
        break;
      case Op::Atan:  // U = 1 + a²
        if (k == 0) {
          U[0] = 1.0 + A[0] * A[0];
          C[0] = std::atan(A[0]);
        } else {
          U[k] = convolution(A, A, k, 0, k);
          double s = 0.0;
          for (int j = 1; j < k; ++j) s += (k - j) * U[j] * C[k - j];
          C[k] = (A[k] - s / k) / U[0];
        }
        break;
    }
    if (!tangents || n.time_constant || n.op == Op::Time) continue;
    for (int d = 0; d < dim_; ++d) {
      double* dC = dc(id, d);
      const double* dA = n.a >= 0 ? dc(n.a, d) : nullptr;
      const double* dB = n.b >= 0 ? dc(n.b, d) : nullptr;
      switch (n.op) {
        case Op::State: dC[k] = yc(n.index, d)[k]; break;
        case Op::Add: dC[k] = dA[k] + dB[k]; break;
        case Op::Subtract: dC[k] = dA[k] - dB[k]; break;
        case Op::Negate: dC[k] = -dA[k]; break;
        case Op::Multiply:
          if (nodes[n.a].time_constant) dC[k] = A[0] * dB[k];
          else if (nodes[n.b].time_constant) dC[k] = dA[k] * B[0];
          else dC[k] = convolution(dA, B, k, 0, k) + convolution(A, dB, k, 0, k);
          break;
        case Op::Square: dC[k] = 2.0 * convolution(A, dA, k, 0, k); break;
        case Op::Divide:  // ċ b = ȧ − c ḃ
          dC[k] = nodes[n.b].time_constant
                      ? dA[k] / B[0]
                      : (dA[k] - convolution(C, dB, k, 0, k) - convolution(B, dC, k, 1, k)) / B[0];
          break;
        case Op::PowerReal:  // ċ a = α c ȧ
          dC[k] = (n.value * convolution(C, dA, k, 0, k) - convolution(A, dC, k, 1, k)) / A[0];
          break;
        case Op::Sqrt:  // 2 c ċ = ȧ
          dC[k] = (dA[k] - 2.0 * convolution(C, dC, k, 1, k)) / (2.0 * C[0]);
          break;
        case Op::Exp: dC[k] = convolution(C, dA, k, 0, k); break;
        case Op::Log: dC[k] = (dA[k] - convolution(A, dC, k, 1, k)) / A[0]; break;
        case Op::Sin: case Op::Tan: case Op::Tanh: dC[k] = convolution(U, dA, k, 0, k); break;
        case Op::Cos: {  // ċ = −sin(x) ẋ, x the argument of the Sin node n.a
          const int x = nodes[n.a].a;
          dC[k] = -convolution(c(n.a), dc(x, d), k, 0, k);
          break;
        }
        case Op::Atan: dC[k] = (dA[k] - convolution(U, dC, k, 1, k)) / U[0]; break;
        default: break;
      }
    }
  }
  return true;
}

bool TaylorStep::linear_order(int k) {
  // z_[k+1] = f_[k] / (k + 1), the linear part applied to the k-th coefficients, then the
  // supplied terms (StepTerms): the time series and the held stops' constraint.
  const bool tangents = settings_.variational;
  const int n = system_->coordinates();
  const Eigen::MatrixXd& ax = position_matrix();
  const Eigen::MatrixXd& av = velocity_matrix();
  const Eigen::MatrixXd& minv = system_->inverse_mass();
  const std::vector<int>& forces = system_->force_nodes();
  if (!tangents && terms_.normals == nullptr && (n == 1 || n == 2)) {  // the unrolled loops (the same bits)
    const std::size_t width = static_cast<std::size_t>(p_) + 1;
    const double* drive = terms_.acceleration ? terms_.acceleration->data() : nullptr;
    auto none = [](int) {};
    if (n == 1) fixed_linear_orders<1>(k, k, p_, width, z_.data(), c_.data(), ax.data(), av.data(), minv.data(), forces.data(), drive, none);
    else fixed_linear_orders<2>(k, k, p_, width, z_.data(), c_.data(), ax.data(), av.data(), minv.data(), forces.data(), drive, none);
    return true;
  }
  const double scale = 1.0 / (k + 1);
  for (int i = 0; i < n; ++i) force_k_[i] = forces[i] >= 0 ? c(forces[i])[k] : 0.0;
  for (int i = 0; i < n; ++i) {
    double a = 0.0;
    for (int j = 0; j < n; ++j) a += ax(i, j) * zc(j)[k] + av(i, j) * zc(n + j)[k] + minv(i, j) * force_k_[j];
    acc_k_[i] = terms_.acceleration ? a + (*terms_.acceleration)(i, k) : a;
  }
  const bool held = terms_.normals != nullptr;
  if (held) {  // λ_[k] = G⁻¹ (Wᵀ a_[k] − p̈_[k]);  a_[k] −= M⁻¹W λ_[k]
    const Eigen::Index m = terms_.normals->cols();
    auto r = residual_k_.head(m);
    auto l = lambda_k_.head(m);
    r.noalias() = terms_.normals->transpose() * acc_k_;
    r -= terms_.stop_acceleration->col(k);
    l.noalias() = *terms_.delassus_inverse * r;
    acc_k_.noalias() -= *terms_.minv_normals * l;
    for (Eigen::Index a = 0; a < m; ++a) lambda_[static_cast<std::size_t>(a) * (p_ + 1) + k] = l(a);
  }
  if (k == p_) return true;
  for (int i = 0; i < n; ++i) {
    zc(i)[k + 1] = zc(n + i)[k] * scale;
    zc(n + i)[k + 1] = acc_k_[i] * scale;
  }
  if (tangents) {
    for (int i = 0; i < n; ++i)
      for (int d = 0; d < dim_; ++d) dforce_k_(i, d) = forces[i] >= 0 ? dc(forces[i], d)[k] : 0.0;
    for (int i = 0; i < n; ++i)
      for (int d = 0; d < dim_; ++d) {
        double a = 0.0;
        for (int j = 0; j < n; ++j)
          a += ax(i, j) * yc(j, d)[k] + av(i, j) * yc(n + j, d)[k] + minv(i, j) * dforce_k_(j, d);
        dacc_k_(i, d) = a;
      }
    if (held) {  // the same projection on the tangents (p̈ does not depend on the state)
      const Eigen::Index m = terms_.normals->cols();
      auto r = dresidual_k_.topRows(m);
      r.noalias() = terms_.normals->transpose() * dacc_k_;
      const Eigen::MatrixXd l = *terms_.delassus_inverse * r;
      dacc_k_.noalias() -= *terms_.minv_normals * l;
    }
    for (int i = 0; i < n; ++i)
      for (int d = 0; d < dim_; ++d) {
        yc(i, d)[k + 1] = yc(n + i, d)[k] * scale;
        yc(n + i, d)[k + 1] = dacc_k_(i, d) * scale;
      }
  }
  return true;
}

StepStatus TaylorStep::expand(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0) {
  trouble_.clear();
  t0_ = t0;
  for (int i = 0; i < dim_; ++i) zc(i)[0] = z0[i];
  if (settings_.variational)
    for (int i = 0; i < dim_; ++i)
      for (int d = 0; d < dim_; ++d) yc(i, d)[0] = i == d ? 1.0 : 0.0;
  if (!z0.allFinite()) {
    trouble_ = "the state is not finite at t = " + number(t0);
    return StepStatus::not_finite;
  }
  if (!compute_order(0)) return StepStatus::domain_error;
  if (settings_.variational) {
    for (int k = 1; k <= p_; ++k)
      if (!compute_order(k)) return StepStatus::domain_error;
  } else {
    tape_orders();  // orders ≥ 1 have no domain to leave (the order-0 checks cover them)
  }

  // Order-p and order-(p−1) norms over z (and Φ, and the held stops' forces λ), the step from
  // their decay. λ counts because it is a guard of the step (its sign change is a release) and,
  // when every coordinate is held, z is constant while λ carries the drive's series.
  const Eigen::Index held = terms_.normals ? terms_.normals->cols() : 0;
  auto norm = [&](int k) {
    double m = 0.0;
    for (int i = 0; i < dim_; ++i) m = std::max(m, std::abs(zc(i)[k]));
    if (settings_.variational)
      for (int i = 0; i < dim_; ++i)
        for (int d = 0; d < dim_; ++d) m = std::max(m, std::abs(yc(i, d)[k]));
    for (Eigen::Index a = 0; a < held; ++a) m = std::max(m, std::abs(force_coefficients(static_cast<int>(a))[k]));
    return m;
  };
  double scale = 1.0;
  for (int i = 0; i < dim_; ++i) scale = std::max(scale, std::abs(z0[i]));
  for (Eigen::Index a = 0; a < held; ++a) scale = std::max(scale, std::abs(force_coefficients(static_cast<int>(a))[0]));
  const double tolerance = settings_.tolerance * scale;
  double h = std::numeric_limits<double>::infinity();
  double rho = std::numeric_limits<double>::infinity();
  for (int k : {p_ - 1, p_}) {
    const double m = norm(k);
    if (!std::isfinite(m)) {
      trouble_ = "a Taylor coefficient of order " + std::to_string(k) + " overflows at t = " + number(t0);
      return StepStatus::not_finite;
    }
    if (m > 0.0) {  // (S/m)^{1/k} = (εS/m)^{1/k} · ε^{−1/k}: one power per order
      const double h_k = std::pow(tolerance / m, 1.0 / k);
      h = std::min(h, h_k);
      rho = std::min(rho, h_k * inverse_root_[k == p_ ? 1 : 0]);
    }
  }
  h_ = h * safety_;
  rho_ = rho;
  if (h_ == 0.0 || std::isnan(h_)) {
    trouble_ = "step size " + number(h_) + " at t = " + number(t0);
    return StepStatus::not_finite;
  }
  return StepStatus::ok;
}

void TaylorStep::state(double tau, Eigen::Ref<Eigen::VectorXd> out) const {
  // Compensated Horner (horner.hpp): the state update then carries only the coefficients' own
  // rounding (z_[1] = v exact, v_[1] = f(z) to ε|f|, entering as ε|f|h).
  for (int i = 0; i < dim_; ++i) out[i] = horner_compensated(state_coefficients(i), p_, tau);
}

void TaylorStep::derivative(double tau, Eigen::Ref<Eigen::VectorXd> out) const {
  for (int i = 0; i < dim_; ++i) {
    const double* a = state_coefficients(i);
    double s = p_ * a[p_];
    for (int k = p_ - 1; k >= 1; --k) s = s * tau + k * a[k];
    out[i] = s;
  }
}

void TaylorStep::transition(double tau, Eigen::Ref<Eigen::MatrixXd> out) const {
  if (!settings_.variational) throw std::logic_error("TaylorStep::transition needs TaylorSettings.variational");
  for (int i = 0; i < dim_; ++i)
    for (int d = 0; d < dim_; ++d) {
      const double* a = &y_[(static_cast<std::size_t>(i) * dim_ + d) * (p_ + 1)];
      double s = a[p_];
      for (int k = p_ - 1; k >= 0; --k) s = s * tau + a[k];
      out(i, d) = s;
    }
}

double TaylorStep::guard_remainder(int g, double tau_max) const { return remainder(guard_coefficients(g), tau_max); }

double TaylorStep::guard_gradient(int g, int d) const {
  if (!settings_.variational) throw std::logic_error("TaylorStep::guard_gradient needs variational equations");
  return dc_[(static_cast<std::size_t>(system_->guard_nodes()[g]) * dim_ + static_cast<std::size_t>(d)) * (p_ + 1)];
}

double TaylorStep::remainder(const double* a, double tau_max) const {
  double rounding = 0.0, truncation = 0.0;
  remainder_parts(a, tau_max, &rounding, &truncation);
  return rounding + truncation;
}

void TaylorStep::remainder_parts(const double* a, double tau_max, double* rounding, double* truncation) const {
  const double h = std::min(h_, tau_max);
  // Rounding of the polynomial's evaluation: 4(p + 1) u Σ |g_k| h^k.
  double absolute_sum = 0.0, power = 1.0;
  for (int k = 0; k <= p_; ++k, power *= h) absolute_sum += std::abs(a[k]) * power;
  *rounding = 4.0 * (p_ + 1) * std::numeric_limits<double>::epsilon() * 0.5 * absolute_sum;
  *truncation = 0.0;
  if (!std::isfinite(rho_)) return;  // polynomial solution: no tail
  // Truncation: Cauchy estimate B r^{p+1} / (1 − r), r = h/ρ, with B = 2 max_{k ∈ {p−1, p}}
  // |g_k| ρ^k fitted to the last two orders (those that set the step).
  const double r = h / rho_;
  if (!(r < 1.0)) {
    *truncation = std::numeric_limits<double>::infinity();
    return;
  }
  // B r^{p+1} = 2 max(|g_{p−1}| / ρ², |g_p| / ρ) h^{p+1}, h^{p+1} left in `power` by the sum above.
  const double bound = std::max(std::abs(a[p_ - 1]) / (rho_ * rho_), std::abs(a[p_]) / rho_);
  *truncation = 2.0 * bound * power / (1.0 - r);
}

StepStatus advance(TaylorStep& step, double t0, const Eigen::Ref<const Eigen::VectorXd>& z0, double t1,
                   Eigen::Ref<Eigen::VectorXd> z1, Eigen::MatrixXd* phi, long* steps) {
  const int dim = step.system().state_size();
  Eigen::VectorXd z = z0;
  Eigen::MatrixXd step_phi;
  if (phi) {
    phi->setIdentity(dim, dim);
    step_phi.resize(dim, dim);
  }
  double t = t0, carry = 0.0;  // time reached: t − carry (Kahan: carry holds what t lost)
  long taken = 0;
  while (true) {
    const double remaining = (t1 - t) + carry;  // t1 − (t − carry)
    if (!(remaining > 0.0)) break;
    const StepStatus status = step.expand(t, z);
    if (status != StepStatus::ok) {
      if (steps) *steps = taken;
      return status;
    }
    const double h = std::min(step.step_size(), remaining);
    step.state(h, z);
    if (phi) {
      step.transition(h, step_phi);
      *phi = step_phi * *phi;
    }
    const double y = h - carry;
    const double sum = t + y;
    carry = (sum - t) - y;
    t = sum;
    ++taken;
  }
  z1 = z;
  if (steps) *steps = taken;
  return StepStatus::ok;
}

}  // namespace vibro::taylor
