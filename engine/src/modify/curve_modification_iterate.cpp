// The modification recipe of seed paper 004 (Figure 9): repeated steps, nose-point errors after
// each (Tables 1-2) and the improvement efficiency rho (eq. 22) as the stopping rule.

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include "modify/curve_modification_detail.hpp"

namespace nurbsreg::engine {

std::optional<std::string> ModifyOptions::validate() const {
  if (!std::isfinite(rho_min)) return "rho_min: not a finite number";
  if (max_iterations < 1) return "max_iterations: must be >= 1";
  if (!(tolerance >= 0.0)) return "tolerance: must be >= 0";
  if (!(weights.min_weight_ratio >= 0.0 && weights.min_weight_ratio < 1.0)) {
    return "weights.min_weight_ratio: must be in [0, 1)";
  }
  return std::nullopt;
}

namespace {

struct Runner {
  const ModifyOptions& options;
  std::vector<Vec3> targets;  // one per segment
  std::vector<Vec3> joins;    // joining points of the input curve (held by eqs. 20-21)
  NurbsCurve curve;
  std::vector<ModifyStep> steps;

  std::vector<NosePoint> noses() const { return nose_points(curve, options.nose_rule); }

  void record(const std::string& operation, const std::string& note) {
    ModifyStep step;
    step.operation = operation;
    step.errors = nose_errors(noses(), targets);
    for (double e : step.errors)
      step.total += e;
    const ModifyStep* kept = nullptr;
    for (const ModifyStep& s : steps) {
      if (!s.reverted) kept = &s;
    }
    step.rho = kept ? improvement_efficiency(kept->errors, step.errors) : 0.0;
    for (int i = 0; i < curve.count(); ++i)
      step.weights.push_back(curve.weight(i));
    step.knots = curve.knots;
    step.note = note;
    steps.push_back(std::move(step));
  }

  // One dB step (eq. 7).
  std::string move_points() {
    const std::vector<NosePoint> n = noses();
    StepResult r = move_control_points(curve, n, targets);
    if (r.applicable) curve = std::move(r.curve);
    return r.message;
  }

  // One dW step (eq. 13 + Process 1); false when no positive allocation exists.
  bool change(std::string& note) {
    const std::vector<NosePoint> n = noses();
    StepResult r = change_weights(curve, n, targets, options.weights);
    note = r.message;
    if (!r.applicable) return false;
    curve = std::move(r.curve);
    return true;
  }

  // One dW/X step: weights, then the joining points back in place where the degree allows it.
  bool change_and_position(std::string& note) {
    if (!change(note)) return false;
    StepResult x = position_joining_knots(curve, joins);
    note += "; " + x.message;
    if (x.applicable) curve = std::move(x.curve);
    return true;
  }
};

}  // namespace

ModifyResult modify_curve(const NurbsCurve& input, std::span<const SegmentTarget> targets,
                          const ModifyOptions& options) {
  if (auto e = input.validate()) throw std::invalid_argument("curve \"" + input.name + "\": " + *e);
  if (auto e = options.validate()) throw std::invalid_argument("options: " + *e);
  const std::vector<NosePoint> initial = nose_points(input, options.nose_rule);
  const int n = static_cast<int>(initial.size());
  if (targets.empty()) {
    throw std::invalid_argument("curve \"" + input.name + "\": no targets");
  }
  Runner run{options, {}, joining_points(input), input, {}};
  for (const NosePoint& nose : initial)
    run.targets.push_back(nose.point);
  std::set<int> seen;
  for (const SegmentTarget& t : targets) {
    if (t.segment < 0 || t.segment >= n) {
      throw std::invalid_argument("curve \"" + input.name + "\": target for segment " +
                                  std::to_string(t.segment) + ", but the curve has " +
                                  std::to_string(n) + " segments (0.." + std::to_string(n - 1) +
                                  ")");
    }
    if (!seen.insert(t.segment).second) {
      throw std::invalid_argument("curve \"" + input.name + "\": two targets for segment " +
                                  std::to_string(t.segment));
    }
    if (!t.point.allFinite()) {
      throw std::invalid_argument("curve \"" + input.name + "\": target for segment " +
                                  std::to_string(t.segment) + " is not a finite point");
    }
    Vec3 p = t.point;
    if (input.dimension == 2) p.z() = 0.0;  // a planar curve's targets live in its plane
    run.targets[t.segment] = p;
  }
  run.record("initial", "");

  ModifyResult result;
  const bool has_knot_step = options.method == ModifyMethod::weights_knots ||
                             (options.method == ModifyMethod::combined && options.iterate);
  // The repeated step of each method; combined without `iterate` is the paper's dW -> dW -> dB.
  auto step = [&](std::string& name, std::string& note) -> bool {
    switch (options.method) {
      case ModifyMethod::points:
        name = "dB";
        note = run.move_points();
        return true;
      case ModifyMethod::weights:
        name = "dW";
        return run.change(note);
      case ModifyMethod::weights_knots:
      case ModifyMethod::combined:
        name = has_knot_step ? "dW/X" : "dW";
        return has_knot_step ? run.change_and_position(note) : run.change(note);
    }
    return false;
  };

  const int repeats = options.iterate                            ? options.max_iterations
                      : options.method == ModifyMethod::combined ? 2
                                                                 : 1;
  result.termination = options.iterate ? "max_iterations reached" : "single pass";
  for (int it = 0; it < repeats; ++it) {
    if (run.steps.back().total <= options.tolerance) {  // never a reverted row: the loop ends there
      result.termination = "total error below tolerance";
      break;
    }
    const NurbsCurve before = run.curve;
    std::string name;
    std::string note;
    if (!step(name, note)) {
      result.termination = "step not applicable: " + note;
      break;
    }
    run.record(name, note);
    if (!options.iterate) continue;
    const double rho = run.steps.back().rho;
    if (rho < 0.0) {
      // A step that makes the total error worse is not kept (the paper stops there too).
      run.curve = before;
      run.steps.back().note += "; reverted: rho < 0";
      run.steps.back().reverted = true;
      run.steps.back().weights.clear();
      run.steps.back().knots.clear();
      result.termination = "rho < 0 (step reverted)";
      break;
    }
    if (rho < options.rho_min) {
      result.termination = "rho < rho_min";
      break;
    }
  }
  double kept_total = 0.0;
  for (const ModifyStep& s : run.steps) {
    if (!s.reverted) kept_total = s.total;
  }
  if (options.method == ModifyMethod::combined && kept_total > options.tolerance) {
    // The paper's recipe ends with control-point movement: exact at the current nose parameters.
    const std::string note = run.move_points();
    run.record("dB", note);
  }
  result.curve = std::move(run.curve);
  result.steps = std::move(run.steps);
  return result;
}

}  // namespace nurbsreg::engine
