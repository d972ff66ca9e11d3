#include "vibro/taylor/expression.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <numbers>
#include <utility>

namespace vibro::taylor {

ExpressionError::ExpressionError(int line_, int column_, std::string message_)
    : std::invalid_argument((line_ > 0 ? std::to_string(line_) + ":" : std::string()) +
                            std::to_string(column_) + ": " + message_),
      line(line_), column(column_), message(std::move(message_)) {}

const char* function_name(Function f) {
  switch (f) {
    case Function::Sin: return "sin";
    case Function::Cos: return "cos";
    case Function::Tan: return "tan";
    case Function::Atan: return "atan";
    case Function::Exp: return "exp";
    case Function::Log: return "log";
    case Function::Sqrt: return "sqrt";
    case Function::Tanh: return "tanh";
  }
  return "?";
}

namespace {

constexpr Function kFunctions[] = {Function::Sin, Function::Cos, Function::Tan, Function::Atan,
                                   Function::Exp, Function::Log, Function::Sqrt, Function::Tanh};

constexpr const char* kNonSmooth[] = {"abs", "fabs", "sign", "sgn", "floor", "ceil", "round",
                                      "min", "max", "mod", "fmod", "step", "heaviside", "H"};

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      const bool same = std::tolower(static_cast<unsigned char>(a[i - 1])) ==
                        std::tolower(static_cast<unsigned char>(b[j - 1]));
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (same ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// " (did you mean 'x'?)" for the nearest candidate, or "".
std::string did_you_mean(std::string_view name, const std::vector<std::string>& candidates) {
  // Up to a third of the name's letters may differ (none for names of one or two letters, whose
  // every neighbour would be within reach), case aside.
  std::string best;
  std::size_t best_distance = (name.size() >= 3 ? std::max<std::size_t>(1, name.size() / 3) : 0) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(name, c);
    if (d < best_distance) {
      best_distance = d;
      best = c;
    }
  }
  return best.empty() ? std::string() : " (did you mean '" + best + "'?)";
}

class Parser {
 public:
  Parser(std::string_view text, const Symbols& symbols, ExpressionTree& tree, ExpressionSource source)
      : text_(text), symbols_(symbols), tree_(tree), source_(source) {}

  int parse() {
    skip_space();
    if (pos_ == text_.size()) fail(pos_, "empty expression");
    const int root = expression();
    skip_space();
    if (pos_ != text_.size()) {
      if (text_[pos_] == ')') fail(pos_, "unmatched ')'");
      fail(pos_, "unexpected '" + std::string(1, text_[pos_]) + "' after a complete expression");
    }
    return root;
  }

 private:
  [[noreturn]] void fail(std::size_t at, const std::string& message) const {
    throw ExpressionError(source_.line, source_.column + static_cast<int>(at), message);
  }
  int column(std::size_t at) const { return source_.column + static_cast<int>(at); }

  void skip_space() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool accept(char c) {
    skip_space();
    if (pos_ < text_.size() && text_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }

  int add(ExpressionNode node) {
    tree_.nodes.push_back(node);
    return static_cast<int>(tree_.nodes.size()) - 1;
  }
  int binary(ExpressionNode::Kind kind, int left, int right, std::size_t at) {
    ExpressionNode n;
    n.kind = kind;
    n.left = left;
    n.right = right;
    n.column = column(at);
    return add(n);
  }

  // expression := term (('+' | '-') term)*
  int expression() {
    int left = term();
    for (;;) {
      skip_space();
      const std::size_t at = pos_;
      if (accept('+')) left = binary(ExpressionNode::Kind::Add, left, term(), at);
      else if (accept('-')) left = binary(ExpressionNode::Kind::Subtract, left, term(), at);
      else return left;
    }
  }
  // term := unary (('*' | '/') unary)*
  int term() {
    int left = unary();
    for (;;) {
      skip_space();
      const std::size_t at = pos_;
      if (accept('*')) {
        if (pos_ < text_.size() && text_[pos_] == '*') fail(pos_ - 1, "'**' is not an operator: write a power as x^2");
        left = binary(ExpressionNode::Kind::Multiply, left, unary(), at);
      } else if (accept('/')) {
        left = binary(ExpressionNode::Kind::Divide, left, unary(), at);
      } else {
        return left;
      }
    }
  }
  // unary := ('-' | '+') unary | power
  int unary() {
    skip_space();
    const std::size_t at = pos_;
    if (accept('-')) {
      ExpressionNode n;
      n.kind = ExpressionNode::Kind::Negate;
      n.left = unary();
      n.column = column(at);
      return add(n);
    }
    if (accept('+')) return unary();
    return power();
  }
  // power := primary ('^' unary)?        (right-associative through unary → power)
  int power() {
    const int base = primary();
    skip_space();
    const std::size_t at = pos_;
    if (accept('^')) return binary(ExpressionNode::Kind::Power, base, unary(), at);
    return base;
  }

  int primary() {
    skip_space();
    if (pos_ == text_.size()) fail(pos_, "expression ends where an operand is expected");
    const char c = text_[pos_];
    const std::size_t at = pos_;
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') return number();
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') return name();
    if (accept('(')) {
      const int inner = expression();
      if (!accept(')')) {
        skip_space();
        fail(pos_, pos_ == text_.size() ? "missing ')' for the '(' at column " + std::to_string(column(at))
                                        : "expected ')' here");
      }
      return inner;
    }
    if (c == ')') fail(at, "')' where an operand is expected");
    fail(at, "unexpected '" + std::string(1, c) + "' where an operand is expected");
  }

  int number() {
    const std::size_t start = pos_;
    while (pos_ < text_.size() && (std::isdigit(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '.')) ++pos_;
    if (pos_ < text_.size() && (text_[pos_] == 'e' || text_[pos_] == 'E')) {
      std::size_t p = pos_ + 1;
      if (p < text_.size() && (text_[p] == '+' || text_[p] == '-')) ++p;
      if (p < text_.size() && std::isdigit(static_cast<unsigned char>(text_[p]))) {
        pos_ = p;
        while (pos_ < text_.size() && std::isdigit(static_cast<unsigned char>(text_[pos_]))) ++pos_;
      }
    }
    const std::string_view digits = text_.substr(start, pos_ - start);
    double value = 0.0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (error != std::errc() || end != digits.data() + digits.size() || !std::isfinite(value))
      fail(start, "'" + std::string(digits) + "' is not a finite number");
    if (pos_ < text_.size() && (std::isalpha(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '_'))
      fail(pos_, "a name directly after the number '" + std::string(digits) + "': write '*' for a product");
    ExpressionNode n;
    n.kind = ExpressionNode::Kind::Number;
    n.value = value;
    n.column = column(start);
    return add(n);
  }

  std::vector<std::string> known_names() const {
    std::vector<std::string> names = {"t", "Omega", "pi"};
    for (Function f : kFunctions) names.emplace_back(function_name(f));
    for (int i = 0; i < symbols_.coordinates; ++i) {
      names.push_back("x" + std::to_string(i));
      names.push_back("v" + std::to_string(i));
    }
    names.insert(names.end(), symbols_.parameters.begin(), symbols_.parameters.end());
    return names;
  }

  int name() {
    const std::size_t start = pos_;
    while (pos_ < text_.size() && (std::isalnum(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '_')) ++pos_;
    const std::string word(text_.substr(start, pos_ - start));
    skip_space();
    const bool called = pos_ < text_.size() && text_[pos_] == '(';
    ExpressionNode n;
    n.column = column(start);

    for (const char* bad : kNonSmooth) {
      if (word == bad)
        fail(start, "'" + word + "' is not smooth: the Taylor engine needs a right-hand side with every "
                    "derivative along a step; model the switch as a stop or a contact law");
    }
    for (Function f : kFunctions) {
      if (word != function_name(f)) continue;
      if (!called) fail(start, "function '" + word + "' needs an argument: " + word + "(...)");
      const std::size_t open = pos_;
      ++pos_;
      skip_space();
      if (pos_ < text_.size() && text_[pos_] == ')') fail(open, "'" + word + "' takes 1 argument, got 0");
      n.kind = ExpressionNode::Kind::Call;
      n.function = f;
      n.left = expression();
      int count = 1;
      while (accept(',')) {
        expression();
        ++count;
      }
      if (count != 1) fail(open, "'" + word + "' takes 1 argument, got " + std::to_string(count));
      if (!accept(')')) {
        skip_space();
        fail(pos_, pos_ == text_.size() ? "missing ')' for the '(' at column " + std::to_string(column(open))
                                        : "expected ')' here");
      }
      return add(n);
    }
    if (called) fail(start, "unknown function '" + word + "'" + did_you_mean(word, known_names()));

    if (word == "t") {
      n.kind = ExpressionNode::Kind::Time;
      return add(n);
    }
    if (word == "Omega") {
      n.kind = ExpressionNode::Kind::Frequency;
      return add(n);
    }
    if (word == "pi") {
      n.kind = ExpressionNode::Kind::Number;
      n.value = std::numbers::pi;
      return add(n);
    }
    for (std::size_t i = 0; i < symbols_.parameters.size(); ++i) {
      if (word == symbols_.parameters[i]) {
        n.kind = ExpressionNode::Kind::Parameter;
        n.index = static_cast<int>(i);
        return add(n);
      }
    }
    if ((word[0] == 'x' || word[0] == 'v') && word.size() > 1 &&
        std::all_of(word.begin() + 1, word.end(), [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)); })) {
      long index = -1;
      const auto [end, error] = std::from_chars(word.data() + 1, word.data() + word.size(), index);
      if (error != std::errc() || end != word.data() + word.size() || index >= symbols_.coordinates)
        fail(start, "'" + word + "': index out of range, the system has n = " + std::to_string(symbols_.coordinates) +
                        " coordinates (" + word.substr(0, 1) + "0 … " + word.substr(0, 1) +
                        std::to_string(symbols_.coordinates - 1) + ")");
      n.kind = word[0] == 'x' ? ExpressionNode::Kind::Position : ExpressionNode::Kind::Velocity;
      n.index = static_cast<int>(index);
      return add(n);
    }
    fail(start, "unknown name '" + word + "'" + did_you_mean(word, known_names()));
  }

  std::string_view text_;
  const Symbols& symbols_;
  ExpressionTree& tree_;
  ExpressionSource source_;
  std::size_t pos_ = 0;
};

}  // namespace

int parse_expression(std::string_view text, const Symbols& symbols, ExpressionTree& tree,
                     ExpressionSource source) {
  const std::size_t size = tree.nodes.size();
  try {
    return Parser(text, symbols, tree, source).parse();
  } catch (...) {
    tree.nodes.resize(size);  // a failed parse leaves the tree as it was
    throw;
  }
}

}  // namespace vibro::taylor
