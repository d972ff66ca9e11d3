#pragma once
/// \file branch_runner.hpp
/// One branch followed by pseudo-arclength steps, its bifurcations detected between neighbouring
/// points and located (private to the analysis layer; continuation.hpp describes the method).
/// The work is split by concept over three files:
///  * branch_runner.cpp: the stepping (predictor y + h t, the corrector, the step control, the
///    guards against landing back on the branch, jumps over grazing corners, section moves);
///  * grazing_corner.cpp: the step onto the orbits with the impact a grazing adds;
///  * bifurcation_detection.cpp: what changed between two neighbours (test functions changing
///    sign, the event signature) and how each change is to be located;
///  * bifurcation_location.cpp: the location itself (Illinois on the arclength, the one-sided
///    secant in p, bisection on the signature) and the record of the result.
#include "corrector.hpp"

#include <cstddef>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vibro::detail {

/// The scalar whose zero is located between two branch points (NaN: not defined at this point,
/// the location falls back to bisection on the event signature).
using TestFunction = std::function<double(const Node&)>;

class BranchRunner {
 public:
  BranchRunner(Continuer& c, const ContinuationOptions& o, ContinuationResult& result,
               const ContinuationProgress& progress)
      : c_(c), o_(o), result_(result), progress_(progress) {}

  /// Follows the branch from `start` along `t` (unit, scaled), appending to `branch`. Period
  /// doublings located on it (while depth < max_doublings) are added to *doublings with the
  /// branch's index, for branch switching.
  void follow(Node start, VectorXd t, Branch& branch, int branch_index, int depth,
              std::vector<std::pair<Node, int>>* doublings);
  /// Appends n to the branch and reports it to the progress callback.
  void append(Branch& branch, const Node& n);
  /// Where set, the branch points located on the branches this runner follows are added to it
  /// with their branch's index, for branch switching (branch_switching.hpp).
  std::vector<std::pair<Node, int>>* branch_points = nullptr;

 private:
  /// How a bifurcation between two neighbours is located.
  enum class Mode {
    two_sided,   ///< Illinois on the arclength: f smooth through the zero (fold, PD, NS)
    one_sided,   ///< secant in p from the side where f is defined and smooth (grazing, rising)
    bisection,   ///< on the event signature: the condition is not smooth in p
    in_p         ///< Illinois in p, each point carried along its neighbour's tangent (branch point)
  };

  // Stepping (branch_runner.cpp).
  static bool near_nonsmooth(const Node& n);
  static bool single_change(const Signature& a, const Signature& b);
  static bool loses_impact(const Signature& a, const Signature& b);
  void fold_before_grazing(const Node& cur, double h, int branch_index);
  static int real_above_one(const FloquetMultipliers& m);
  static std::string unseen_crossing(const BranchPoint& a, const BranchPoint& b);
  std::optional<Node> jump(const Node& cur, double last_dp, const std::vector<VectorXd>& trail);
  static bool lands_back(const std::vector<VectorXd>& trail, const VectorXd& y);
  bool back_to_change(const std::vector<VectorXd>& trail, const VectorXd& y) const;
  /// The first orbit with the impact a grazing of cur's adds, by steps along corner_tangent
  /// (lifted: from predictors raised onto the impacting side to second order).
  std::optional<Node> corner(const Node& cur, bool lifted = false);  // grazing_corner.cpp
  /// The unit tangent (scaled) of the branch of orbits with the impact a grazing of cur's adds,
  /// at cur (an orbit at or near the grazing), oriented into the impacting side, and the stop.
  std::optional<std::pair<VectorXd, int>> corner_tangent(const Node& cur);  // grazing_corner.cpp
  std::optional<Node> nearest_across(const Node& cur, Node far, double width);
  std::optional<Node> shoot_at(const Node& from, double p, const VectorXd& along);
  void locate_at_end(const Node& cur, double last_dp, int branch_index);
  std::optional<Node> resection(const Node& cur, double margin);
  void carry(std::vector<VectorXd>& trail, double old_theta) const;

  // Detection (bifurcation_detection.cpp).
  bool examine(const Node& a, Node& b, int branch_index, int depth, std::vector<std::pair<Node, int>>* doublings,
               bool refuse_hidden_fold = false);
  bool fold_beside_grazing(const Node& a, const Node& b, std::size_t first);
  void point_away(const Node& a, Node& b, std::size_t first) const;
  static std::function<bool(const Node&)> same_counts(const Signature& s, std::size_t j,
                                                     std::vector<int> Signature::*field);

  // Location (bifurcation_location.cpp).
  std::optional<Node> on_limit(const Node& a, const Node& b, double limit);
  std::optional<Node> illinois(const Node& a, const Node& b, const TestFunction& f, bool smooth, int* count,
                               const std::function<bool(const Node&)>& same_as_a = {});
  std::optional<Node> at_p(const Node& from, double p, const VectorXd& along);
  std::optional<Node> along_to_p(const Node& from, double p);
  std::optional<Node> illinois_in_p(const Node& a, const Node& b, const TestFunction& f, int* count,
                                    std::string* why);
  std::optional<Node> one_sided(const Node& good, const Node& bad, const TestFunction& f,
                                const std::function<bool(const Node&)>& on_good, int* count,
                                double solved = std::numeric_limits<double>::infinity());
  std::optional<Node> nearer_feature(const Node& good, const Node& bad, const TestFunction& f,
                                    const std::function<bool(const Node&)>& on_good, int* count);
  std::optional<Node> bisect(const Node& a, const Node& b, const std::function<bool(const Node&)>& same_as_a,
                             int* count);
  bool small_against_scale(const Node& a, const Node& at, const TestFunction& f, int* count, std::string* why);
  void record(BifurcationKind kind, int stop, const Node& a, const Node& b, int branch_index,
              const TestFunction& f, Mode mode, const std::function<bool(const Node&)>& same_as_a,
              const std::string& note);

  Continuer& c_;
  const ContinuationOptions& o_;
  ContinuationResult& result_;
  const ContinuationProgress& progress_;
  Node last_located_;
  Signature behind_;  ///< the events before the last multiple change crossed (no step goes back to them there)
  std::size_t behind_at_ = 0;  ///< the trail's index of the last point before that change
  Signature undo_;    ///< the events before the change the last step crossed (the next step does not go back to them)
  double located_p_ = kNaN;  ///< one-sided location: the extrapolated zero
  double bracket_low_ = 0.0, bracket_high_ = 0.0;
  bool located_smooth_ = true;
  bool one_sided_solved_ = true;
  // corner_tangent's second-order data (grazing_corner.cpp): the scaled shift raising the gap
  // maximum by one length unit, the impact speed per unit step, |g''| at the grazing.
  VectorXd corner_rise_;
  double corner_u_ = 0.0, corner_g2_ = 0.0;  ///< one_sided: its zero solved, not only the end of the good side found
};

}  // namespace vibro::detail
