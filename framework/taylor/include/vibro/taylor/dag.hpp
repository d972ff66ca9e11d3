#pragma once
/// \file dag.hpp
/// Expressions compiled to a directed acyclic graph of elementary operations (the
/// "decomposition" of automatic differentiation: Jorba & Zou 2005, §2; Biscani & Izzo 2021, §2).
///
/// Each node is one of
///
///     leaves   Constant c, State z_i (z = [x; v], i < 2n), Time t, Parameter p_j
///     binary   a + b, a − b, a·b, a / b
///     unary    −a, a², a^α (α a real constant), exp a, log a, √a,
///              sin a, cos a (reads the cosine kept beside sin a), tan a, atan a, tanh a
///
/// stored in topological order (a node's operands come before it), so one pass in index order
/// computes every node. Construction goes through `add`, which
///   - shares common subexpressions: an operation with the same operands is stored once (a hash
///     of (operation, operands, constant)), so sin(x0) in three forces is computed once;
///   - folds constants: an operation on Constant leaves becomes a Constant; x + 0, x·1, x·0,
///     x^1, x^0 and −(−x) simplify;
///   - lowers powers: a^n for an integer constant |n| ≤ 64 becomes products by binary
///     exponentiation (x³ = x²·x, whose recurrences hold at a = 0 too), a^(−n) = 1 / a^n; a real
///     constant α gives the node a^α (its recurrence needs a(t) ≠ 0); a non-constant exponent
///     b gives exp(b·log a).
/// A node is `time_constant` when it depends only on constants and parameters: its Taylor
/// coefficients beyond the zeroth vanish, which the recurrences use (a product with a constant
/// is a scaling, O(p) instead of O(p²)).
///
/// Parameters are leaves, not folded constants, so that a continuation can change a parameter
/// value (and Ω, parameter 0) without recompiling.
///
/// Usage:
///     vibro::taylor::Dag dag(/*coordinates=*/1, /*parameters=*/{"Omega", "beta"});
///     vibro::taylor::ExpressionTree tree;
///     int root = parse_expression("-beta*x0^3", symbols, tree);
///     int node = dag.compile(tree, root);   // node index of the expression's value
#include "vibro/taylor/expression.hpp"

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

namespace vibro::taylor {

enum class Op : std::uint8_t {
  Constant, State, Time, Parameter,
  Add, Subtract, Multiply, Divide,
  Negate, Square, PowerReal, Exp, Log, Sqrt, Sin, Cos, Tan, Atan, Tanh
};
const char* op_name(Op op);

struct DagNode {
  Op op = Op::Constant;
  int a = -1;            ///< first operand (for Cos: the Sin node of the same argument)
  int b = -1;            ///< second operand
  double value = 0.0;    ///< Constant: its value; PowerReal: the exponent α
  int index = -1;        ///< State: i in z; Parameter: j
  bool time_constant = false;
  bool has_auxiliary = false;  ///< Sin (cos a), Tan (1 + tan²), Tanh (1 − tanh²), Atan (1 + a²)
};

class Dag {
 public:
  /// `coordinates` = n (state size 2n); `parameters`: names, Ω first by convention ("Omega").
  Dag(int coordinates, std::vector<std::string> parameters);

  /// Compiles the subtree of `tree` at `root` and returns its node. Symbols were resolved by the
  /// parser with the same n and parameter list less "Omega" (see TaylorSystem).
  int compile(const ExpressionTree& tree, int root);

  int constant(double c);
  int state(int i);
  int time();
  int parameter(int j);
  /// Adds (or finds) an operation node with simplification and folding as described above.
  int add(Op op, int a, int b = -1, double value = 0.0);
  int power(int base, int exponent);  ///< a^b with the lowering described above

  const std::vector<DagNode>& nodes() const { return nodes_; }
  int size() const { return static_cast<int>(nodes_.size()); }
  int coordinates() const { return coordinates_; }
  const std::vector<std::string>& parameters() const { return parameters_; }
  /// Readable text of a node (for messages: "log(x0) at a(t) = 0").
  std::string describe(int node) const;

 private:
  struct Key {
    Op op;
    int a, b, index;
    double value;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const;
  };
  int insert(DagNode node);
  bool is_constant(int node, double c) const;

  int coordinates_;
  std::vector<std::string> parameters_;
  std::vector<DagNode> nodes_;
  std::unordered_map<Key, int, KeyHash> index_;
};

}  // namespace vibro::taylor
