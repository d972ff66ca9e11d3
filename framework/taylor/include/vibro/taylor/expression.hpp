#pragma once
/// \file expression.hpp
/// The expression language of nonlinear forces and guards, parsed into a syntax tree.
///
/// An expression is a smooth (real-analytic where defined) function of
///
///     x0 … x{n-1}   the positions,          v0 … v{n-1}   the velocities,
///     t             the time,                Omega         the forcing frequency Ω (rad/time),
///     pi            π,                       named parameters (any identifier the caller lists),
///
/// built with + − * / ^, unary minus, parentheses and the functions
///
///     sin cos tan atan exp log sqrt tanh      (one argument each).
///
/// Precedence, loosest first: + −; * /; unary −; ^ (right-associative, so 2^3^2 = 2^9 and
/// -x^2 = -(x^2); the exponent may carry its own sign: x^-2). Numbers are decimal with an
/// optional exponent (1, 0.5, 2e-3). The forcing frequency is spelled `Omega` (one name only,
/// so that `W` stays free for the user's parameters).
///
/// Only smooth functions are offered: the Taylor engine expands the right-hand side in a power
/// series over each step, which needs every derivative to exist along the step. abs, sign,
/// floor, ceil, round, min, max, mod, step, heaviside are refused with that reason; a switch in
/// the law is a stop or a contact law, whose events are located exactly.
///
/// Errors are ExpressionError{line, column, message}: `line` and `column` are the caller's
/// position of the expression's first character plus the offset inside it, so a scene loader
/// that knows where a YAML scalar starts passes that position in `ExpressionSource` and prefixes
/// its file name to the message.
///
/// Usage:
///     vibro::taylor::Symbols symbols{.coordinates = 1, .parameters = {"beta"}};
///     vibro::taylor::ExpressionTree tree;
///     int root = vibro::taylor::parse_expression("-beta*x0^3", symbols, tree, {12, 15});
///     // throws ExpressionError{12, 15 + offset, "..."} on bad input
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace vibro::taylor {

/// Bad expression text. `line`/`column` are 1-based positions in the caller's file (the
/// column of the offending character); what() is "line:column: message".
class ExpressionError : public std::invalid_argument {
 public:
  ExpressionError(int line, int column, std::string message);
  int line;
  int column;
  std::string message;  ///< without the position
};

/// Where the expression's first character sits in the caller's file (1-based; line 0: none).
struct ExpressionSource {
  int line = 0;
  int column = 1;
};

/// The names an expression may use besides the built-in ones.
struct Symbols {
  int coordinates = 0;                  ///< n: x0 … x{n-1}, v0 … v{n-1}
  std::vector<std::string> parameters;  ///< user parameter names (index = position here)
};

enum class Function { Sin, Cos, Tan, Atan, Exp, Log, Sqrt, Tanh };
const char* function_name(Function f);

/// One node of a syntax tree; children are indices into ExpressionTree::nodes.
struct ExpressionNode {
  enum class Kind { Number, Position, Velocity, Time, Frequency, Parameter, Negate, Add, Subtract,
                    Multiply, Divide, Power, Call };
  Kind kind = Kind::Number;
  double value = 0.0;            ///< Number
  int index = 0;                 ///< Position, Velocity, Parameter
  Function function = Function::Sin;  ///< Call
  int left = -1;                 ///< operand (unary, Call) or left operand
  int right = -1;                ///< right operand
  int column = 1;                ///< caller's column of the node's first character
};

/// Nodes of any number of parsed expressions (each parse appends and returns its root).
struct ExpressionTree {
  std::vector<ExpressionNode> nodes;
};

/// Parses `text`; appends its nodes to `tree` and returns the root's index. Throws
/// ExpressionError on a syntax error, an unknown name (with the nearest known one), a function
/// called with the wrong number of arguments, an index beyond n - 1, a non-smooth function or an
/// empty expression.
int parse_expression(std::string_view text, const Symbols& symbols, ExpressionTree& tree,
                     ExpressionSource source = {});

}  // namespace vibro::taylor
