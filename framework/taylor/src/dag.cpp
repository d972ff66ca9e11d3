#include "vibro/taylor/dag.hpp"

#include <cassert>
#include <cmath>
#include <cstring>
#include <functional>

namespace vibro::taylor {

const char* op_name(Op op) {
  switch (op) {
    case Op::Constant: return "constant";
    case Op::State: return "state";
    case Op::Time: return "t";
    case Op::Parameter: return "parameter";
    case Op::Add: return "+";
    case Op::Subtract: return "-";
    case Op::Multiply: return "*";
    case Op::Divide: return "/";
    case Op::Negate: return "-";
    case Op::Square: return "square";
    case Op::PowerReal: return "^";
    case Op::Exp: return "exp";
    case Op::Log: return "log";
    case Op::Sqrt: return "sqrt";
    case Op::Sin: return "sin";
    case Op::Cos: return "cos";
    case Op::Tan: return "tan";
    case Op::Atan: return "atan";
    case Op::Tanh: return "tanh";
  }
  return "?";
}

std::size_t Dag::KeyHash::operator()(const Key& k) const {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &k.value, sizeof bits);
  std::size_t h = std::hash<std::uint64_t>()(bits);
  for (std::size_t part : {static_cast<std::size_t>(k.op), static_cast<std::size_t>(k.a + 1),
                           static_cast<std::size_t>(k.b + 1), static_cast<std::size_t>(k.index + 1)})
    h ^= part + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
  return h;
}

Dag::Dag(int coordinates, std::vector<std::string> parameters)
    : coordinates_(coordinates), parameters_(std::move(parameters)) {}

int Dag::insert(DagNode node) {
  const Key key{node.op, node.a, node.b, node.index, node.value};
  const auto found = index_.find(key);
  if (found != index_.end()) return found->second;
  nodes_.push_back(node);
  const int id = size() - 1;
  index_.emplace(key, id);
  return id;
}

int Dag::constant(double c) {
  DagNode n;
  n.op = Op::Constant;
  n.value = c == 0.0 ? 0.0 : c;  // one node for +0 and -0
  n.time_constant = true;
  return insert(n);
}
int Dag::state(int i) {
  assert(i >= 0 && i < 2 * coordinates_);
  DagNode n;
  n.op = Op::State;
  n.index = i;
  return insert(n);
}
int Dag::time() {
  DagNode n;
  n.op = Op::Time;
  return insert(n);
}
int Dag::parameter(int j) {
  assert(j >= 0 && j < static_cast<int>(parameters_.size()));
  DagNode n;
  n.op = Op::Parameter;
  n.index = j;
  n.time_constant = true;
  return insert(n);
}

bool Dag::is_constant(int node, double c) const {
  return nodes_[node].op == Op::Constant && nodes_[node].value == c;
}

namespace {

double fold(Op op, double a, double b, double value) {
  switch (op) {
    case Op::Add: return a + b;
    case Op::Subtract: return a - b;
    case Op::Multiply: return a * b;
    case Op::Divide: return a / b;
    case Op::Negate: return -a;
    case Op::Square: return a * a;
    case Op::PowerReal: return std::pow(a, value);
    case Op::Exp: return std::exp(a);
    case Op::Log: return std::log(a);
    case Op::Sqrt: return std::sqrt(a);
    case Op::Sin: return std::sin(a);
    case Op::Cos: return std::cos(a);
    case Op::Tan: return std::tan(a);
    case Op::Atan: return std::atan(a);
    case Op::Tanh: return std::tanh(a);
    default: return std::nan("");
  }
}

}  // namespace

int Dag::add(Op op, int a, int b, double value) {
  const bool binary = op == Op::Add || op == Op::Subtract || op == Op::Multiply || op == Op::Divide;
  assert(a >= 0 && a < size() && (!binary || (b >= 0 && b < size())));
  const DagNode& na = nodes_[a];
  // Constant folding (a folded value that is not finite, e.g. log(-1), stays an operation so
  // that its evaluation reports the domain error with the step's context).
  if (na.op == Op::Constant && (!binary || nodes_[b].op == Op::Constant)) {
    const double folded = fold(op, na.value, binary ? nodes_[b].value : 0.0, value);
    if (std::isfinite(folded)) return constant(folded);
  }
  // Algebraic simplification.
  switch (op) {
    case Op::Add:
      if (is_constant(a, 0.0)) return b;
      if (is_constant(b, 0.0)) return a;
      if (b < a) std::swap(a, b);  // commutative: one node for a + b and b + a
      break;
    case Op::Subtract:
      if (is_constant(b, 0.0)) return a;
      if (is_constant(a, 0.0)) return add(Op::Negate, b);
      if (a == b) return constant(0.0);
      break;
    case Op::Multiply:
      if (is_constant(a, 0.0) || is_constant(b, 0.0)) return constant(0.0);
      if (is_constant(a, 1.0)) return b;
      if (is_constant(b, 1.0)) return a;
      if (is_constant(a, -1.0)) return add(Op::Negate, b);
      if (is_constant(b, -1.0)) return add(Op::Negate, a);
      if (a == b) return add(Op::Square, a);
      if (b < a) std::swap(a, b);
      break;
    case Op::Divide:
      if (is_constant(b, 1.0)) return a;
      if (is_constant(b, -1.0)) return add(Op::Negate, a);
      if (is_constant(a, 0.0)) return constant(0.0);
      break;
    case Op::Negate:
      if (na.op == Op::Negate) return na.a;
      break;
    case Op::PowerReal:
      if (value == 1.0) return a;
      if (value == 0.0) return constant(1.0);
      if (value == 2.0) return add(Op::Square, a);
      if (value == 0.5) return add(Op::Sqrt, a);
      break;
    default:
      break;
  }
  DagNode n;
  n.op = op;
  n.a = a;
  n.b = binary ? b : -1;
  n.value = op == Op::PowerReal ? value : 0.0;
  n.time_constant = nodes_[a].time_constant && (!binary || nodes_[b].time_constant);
  n.has_auxiliary = op == Op::Sin || op == Op::Tan || op == Op::Tanh || op == Op::Atan;
  if (op == Op::Cos) {
    // cos a is read from the auxiliary series of sin a (the pair's recurrence computes both).
    const int s = add(Op::Sin, a);
    if (nodes_[s].op == Op::Constant) return constant(std::cos(nodes_[a].value));
    n.a = s;
  }
  return insert(n);
}

int Dag::power(int base, int exponent) {
  const DagNode& e = nodes_[exponent];
  if (e.op == Op::Constant) {
    const double alpha = e.value;
    if (alpha == std::round(alpha) && std::abs(alpha) <= 64.0) {
      long n = static_cast<long>(std::abs(alpha));
      int result = constant(1.0);
      int square = base;
      while (n > 0) {  // binary exponentiation: x^13 = x · x⁴ · x⁸
        if (n & 1) result = add(Op::Multiply, result, square);
        n >>= 1;
        if (n > 0) square = add(Op::Square, square);
      }
      return alpha < 0 ? add(Op::Divide, constant(1.0), result) : result;
    }
    return add(Op::PowerReal, base, -1, alpha);
  }
  // a^b = exp(b · log a) for an exponent that is not a number (a parameter, or a function of
  // the state): defined for a > 0.
  return add(Op::Exp, add(Op::Multiply, exponent, add(Op::Log, base)));
}

int Dag::compile(const ExpressionTree& tree, int root) {
  const ExpressionNode& e = tree.nodes.at(root);
  using K = ExpressionNode::Kind;
  switch (e.kind) {
    case K::Number: return constant(e.value);
    case K::Position: return state(e.index);
    case K::Velocity: return state(coordinates_ + e.index);
    case K::Time: return time();
    case K::Frequency: return parameter(0);
    case K::Parameter: return parameter(e.index + 1);
    case K::Negate: return add(Op::Negate, compile(tree, e.left));
    case K::Add: return add(Op::Add, compile(tree, e.left), compile(tree, e.right));
    case K::Subtract: return add(Op::Subtract, compile(tree, e.left), compile(tree, e.right));
    case K::Multiply: return add(Op::Multiply, compile(tree, e.left), compile(tree, e.right));
    case K::Divide: return add(Op::Divide, compile(tree, e.left), compile(tree, e.right));
    case K::Power: return power(compile(tree, e.left), compile(tree, e.right));
    case K::Call: {
      const int a = compile(tree, e.left);
      switch (e.function) {
        case Function::Sin: return add(Op::Sin, a);
        case Function::Cos: return add(Op::Cos, a);
        case Function::Tan: return add(Op::Tan, a);
        case Function::Atan: return add(Op::Atan, a);
        case Function::Exp: return add(Op::Exp, a);
        case Function::Log: return add(Op::Log, a);
        case Function::Sqrt: return add(Op::Sqrt, a);
        case Function::Tanh: return add(Op::Tanh, a);
      }
    }
  }
  assert(false);
  return -1;
}

std::string Dag::describe(int id) const {
  const DagNode& n = nodes_[id];
  switch (n.op) {
    case Op::Constant: {
      char text[32];
      std::snprintf(text, sizeof text, "%.17g", n.value);
      return text;
    }
    case Op::State:
      return (n.index < coordinates_ ? "x" : "v") + std::to_string(n.index % coordinates_);
    case Op::Time: return "t";
    case Op::Parameter: return parameters_[n.index];
    case Op::Add: case Op::Subtract: case Op::Multiply: case Op::Divide:
      return "(" + describe(n.a) + " " + op_name(n.op) + " " + describe(n.b) + ")";
    case Op::Negate: return "-" + describe(n.a);
    case Op::Square: return describe(n.a) + "^2";
    case Op::PowerReal: {
      char text[32];
      std::snprintf(text, sizeof text, "%.17g", n.value);
      return describe(n.a) + "^" + text;
    }
    case Op::Cos: return "cos(" + describe(nodes_[n.a].a) + ")";
    default: return std::string(op_name(n.op)) + "(" + describe(n.a) + ")";
  }
}

}  // namespace vibro::taylor
