#include "thicket/local_planner/loco.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>

#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>

namespace thicket::local_planner {

DistanceField esdfField(const EsdfLayer& esdf) {
  return [&esdf](const Eigen::Vector3d& p) { return sampleEsdf(esdf, p); };
}

ClearanceCheck checkClearance(const PolynomialTrajectory& trajectory, double from,
                              const DistanceField& field, double required, double escape_slack) {
  ClearanceCheck result;
  result.min_distance = std::numeric_limits<double>::infinity();
  const double duration = trajectory.duration();
  // The samples of the acceptance test from `from` on: the same times, so that a trajectory checked
  // again on the same map passes again.
  const int first =
      static_cast<int>(std::ceil(std::clamp(from, 0.0, duration) / kClearanceCheckDt));
  result.threshold = required;
  for (int k = first;; ++k) {
    const double t = std::min(k * kClearanceCheckDt, duration);
    const Eigen::Vector3d p = trajectory.evaluate(t);
    const EsdfSample e = field(p);
    const double d = e.known ? e.distance : 0.0;
    if (k == first && e.known) result.threshold = std::min(required, d - escape_slack);
    result.min_distance = std::min(result.min_distance, d);
    if (result.reason.empty() && (!e.known || d < result.threshold)) {
      char text[160];
      if (e.known) {
        std::snprintf(text, sizeof(text),
                      "sample at t=%.2f s, (%.2f, %.2f, %.2f): distance %.4f m < %.4f m%s", t,
                      p.x(), p.y(), p.z(), d, result.threshold,
                      result.threshold < required ? " (its start's, inside the margin)" : "");
      } else {
        std::snprintf(text, sizeof(text), "sample at t=%.2f s, (%.2f, %.2f, %.2f) is unknown", t,
                      p.x(), p.y(), p.z());
      }
      result.reason = text;
    }
    if (t >= duration) break;
  }
  result.clear = result.reason.empty();
  return result;
}

Potential collisionPotential(double distance, double radius, double epsilon) {
  const double d = distance - radius;
  if (d < 0) return {-d + 0.5 * epsilon, -1.0};
  if (d <= epsilon) return {(d - epsilon) * (d - epsilon) / (2 * epsilon), (d - epsilon) / epsilon};
  return {0, 0};
}

void LocoOptions::declare(Params& p) {
  p("w_d", w_d, "weight of the jerk cost J_d", Range::atLeast(0));
  p("w_c", w_c, "weight of the collision cost J_c", Range::atLeast(0));
  p("w_g", w_g, "weight of the soft goal cost J_g", Range::atLeast(0));
  p("robot_radius", robot_radius, "[m]", Range::positive());
  p("potential_margin", potential_margin,
    "the collision potential's epsilon is robot_radius + this [m]", Range::positive());
  p("sample_dt", sample_dt,
    "time step of the collision integral [s] (acceptance checks every 0.02 s)",
    Range::between(0.001, 1));
  p("clearance_margin", clearance_margin,
    "accepted samples need ESDF distance >= robot_radius + this: the mapper's certified "
    "overestimate plus the dip between 0.02 s samples [m]",
    Range::atLeast(0));
  p("potential_buffer", potential_buffer,
    "the collision potential rises this far beyond the accepted clearance, so an optimum pressed "
    "against it passes the 0.02 s acceptance [m]",
    Range::between(0, 1));
  p("escape_slack", escape_slack,
    "a plan that starts inside the clearance margin, or less than this outside it, may come this "
    "much closer than its start (and must end outside the margin); 0: never closer [m]",
    Range::between(0, 0.01));
  p("v_max", v_max, "[m/s]", Range::positive());
  p("a_max", a_max, "[m/s^2]", Range::positive());
  p("segments", segments, "polynomial segments per trajectory", Range::between(1, 10));
  p("time_scale", time_scale, "segment time: this times the velocity-ramp time", Range::positive());
  p("restarts", restarts, "random restarts when a solution is not accepted",
    Range::between(0, 100));
  p("restart_radius", restart_radius, "restarts move inner vertices by up to this per axis [m]",
    Range::atLeast(0));
  p("max_iterations", max_iterations, "L-BFGS iterations per solve", Range::between(1, 10000));
  p("function_tolerance", function_tolerance,
    "a solve stops when an iteration lowers the cost by less than this fraction",
    Range::between(1e-12, 1));
  p("goal_smoothing", goal_smoothing, "delta of the smoothed goal distance [m]", Range::positive());
}

// ---- the problem ----

LocoProblem::LocoProblem(const LocoOptions& options, JerkSpline spline, const SplineEnds& ends,
                         DistanceField field)
    : options_(options),
      spline_(std::move(spline)),
      fixed_(spline_.fixedDerivatives(ends)),
      goal_(ends.end_position),
      field_(std::move(field)) {
  if (!goal_.allFinite()) throw std::invalid_argument("LocoProblem: the goal must be finite");
  // Samples at k Δt and at the very end; the start is fixed, so it carries no gradient but does
  // count for acceptance.
  const double total = spline_.duration();
  std::vector<double> times;
  for (int k = 0; k * options_.sample_dt < total - 1e-9; ++k)
    times.push_back(k * options_.sample_dt);
  times.push_back(total);
  int segment = 0;
  double segment_start = 0;
  for (double t : times) {
    while (segment + 1 < spline_.numSegments() &&
           t >= segment_start + spline_.segmentTimes()[static_cast<size_t>(segment)]) {
      segment_start += spline_.segmentTimes()[static_cast<size_t>(segment)];
      ++segment;
    }
    const double tau = t - segment_start;
    const Eigen::MatrixXd& map = spline_.coefficientMap(segment);
    samples_.push_back({segment, tau, t, JerkSpline::basis(tau, 0).transpose() * map,
                        JerkSpline::basis(tau, 1).transpose() * map});
  }
}

namespace {

// gradient += (scale * row)' * along: element (i, j) gains (scale * row(i)) * along(j), the
// products Eigen's lazy outer product forms, but in a loop over the three columns that the
// compiler sees whole (Eigen's generic assignment loop for a dynamic-size matrix took 3 % of a
// benchmark trial).
void addOuter(Derivatives& gradient, double scale, const Eigen::Ref<const Eigen::RowVectorXd>& row,
              const Eigen::RowVector3d& along) {
  for (Eigen::Index i = 0; i < gradient.rows(); ++i) {
    const double scaled = scale * row[i];
    for (int j = 0; j < 3; ++j) gradient(i, j) += scaled * along[j];
  }
}

}  // namespace

LocoCost LocoProblem::cost(const Derivatives& free, Derivatives* gradient) const {
  LocoCost cost;
  cost.derivative = spline_.jerkCost(fixed_, free, gradient);
  if (gradient) *gradient *= options_.w_d;
  const int nf = spline_.numFixed();
  const int np = spline_.numFree();
  const double dt = options_.sample_dt;
  const double epsilon = options_.epsilon();
  // The potential rises from a little beyond the clearance acceptance asks for, so an optimum
  // pressed against it (seen every sample_dt) still clears it at every acceptance sample.
  const double clearance = options_.requiredClearance() + options_.potential_buffer;
  for (const Sample& s : samples_) {
    const Eigen::RowVector3d p = s.position_row.head(nf) * fixed_ + s.position_row.tail(np) * free;
    const Eigen::RowVector3d v = s.velocity_row.head(nf) * fixed_ + s.velocity_row.tail(np) * free;
    const EsdfSample e = field_(p.transpose());
    const Potential c = collisionPotential(e.known ? e.distance : 0.0, clearance, epsilon);
    const double speed = v.norm();
    // The end, at rest, counts as if flown at v_max: a free end cannot settle in an obstacle.
    const double weight = &s == &samples_.back() ? speed + options_.v_max : speed;
    cost.collision += c.value * weight * dt;
    if (gradient && c.value > 0) {
      // d/dD of c(d(p)) ||v|| Δt: through the position (distance gradient) and the speed.
      if (e.known && c.derivative != 0) {
        addOuter(*gradient, options_.w_c * c.derivative * weight * dt, s.position_row.tail(np),
                 e.gradient.transpose());
      }
      if (speed > 1e-12) {
        addOuter(*gradient, options_.w_c * c.value * dt / speed, s.velocity_row.tail(np), v);
      }
    }
  }
  if (spline_.freeEndPosition()) {
    const Eigen::RowVector3d error = free.row(spline_.endPositionRow()) - goal_.transpose();
    const double delta = options_.goal_smoothing;
    const double smooth = std::sqrt(error.squaredNorm() + delta * delta);
    cost.goal = smooth - delta;
    if (gradient) gradient->row(spline_.endPositionRow()) += options_.w_g * error / smooth;
  }
  cost.total =
      options_.w_d * cost.derivative + options_.w_c * cost.collision + options_.w_g * cost.goal;
  return cost;
}

LocoProblem::Check LocoProblem::check(const Derivatives& free) const {
  Check result;
  result.min_distance = std::numeric_limits<double>::infinity();
  auto trajectory = PolynomialTrajectory::create(0, spline_.segments(fixed_, free));
  if (!trajectory) {
    result.reason = "not a valid trajectory: " + trajectory.error();
    return result;
  }
  const double required = options_.requiredClearance();
  const ClearanceCheck clearance =
      checkClearance(*trajectory, 0, field_, required, options_.escape_slack);
  result.min_distance = clearance.min_distance;
  result.collision_free = clearance.clear;
  constexpr double kLimitDt = 0.01;
  result.max_speed = trajectory->maxSpeed(kLimitDt);
  result.max_acceleration = trajectory->maxAcceleration(kLimitDt);
  char text[160];
  // A plan that starts inside the margin (held to its start's clearance) must end outside it, so
  // that successive plans cannot creep along an obstacle by the dip between samples.
  double end_distance = required;
  if (clearance.clear && clearance.threshold < required) {
    const EsdfSample end = field_(trajectory->evaluate(trajectory->duration()));
    end_distance = end.known ? end.distance : 0.0;
  }
  if (!result.collision_free) {
    result.reason = clearance.reason;
  } else if (end_distance < required) {
    result.collision_free = false;
    std::snprintf(text, sizeof(text),
                  "it starts inside the clearance margin and ends there too (%.4f m < %.4f m)",
                  end_distance, required);
    result.reason = text;
  } else if (result.max_speed > options_.v_max + 1e-6) {
    std::snprintf(text, sizeof(text), "speed %.3f m/s above v_max %.2f m/s", result.max_speed,
                  options_.v_max);
    result.reason = text;
  } else if (result.max_acceleration > options_.a_max + 1e-6) {
    std::snprintf(text, sizeof(text), "acceleration %.3f m/s^2 above a_max %.2f m/s^2",
                  result.max_acceleration, options_.a_max);
    result.reason = text;
  }
  return result;
}

namespace {

class LocoFunction final : public ceres::FirstOrderFunction {
 public:
  explicit LocoFunction(const LocoProblem& problem) : problem_(problem) {}

  bool Evaluate(const double* parameters, double* cost, double* gradient) const override {
    const int rows = problem_.spline().numFree();
    const Derivatives free = Eigen::Map<const Derivatives>(parameters, rows, 3);
    if (gradient == nullptr) {
      *cost = problem_.cost(free).total;
    } else {
      Derivatives g;
      *cost = problem_.cost(free, &g).total;
      Eigen::Map<Derivatives>(gradient, rows, 3) = g;
    }
    return std::isfinite(*cost);
  }
  int NumParameters() const override { return problem_.numParameters(); }

 private:
  const LocoProblem& problem_;
};

}  // namespace

LocoSolve LocoProblem::minimize(Derivatives& free) const {
  if (free.rows() != spline_.numFree()) {
    throw std::invalid_argument("LocoProblem::minimize: wrongly sized free derivatives");
  }
  ceres::GradientProblem problem(new LocoFunction(*this));
  ceres::GradientProblemSolver::Options solver_options;
  solver_options.line_search_direction_type = ceres::LBFGS;
  solver_options.max_num_iterations = options_.max_iterations;
  solver_options.function_tolerance = options_.function_tolerance;
  solver_options.gradient_tolerance = 1e-4 * options_.function_tolerance;
  solver_options.logging_type = ceres::SILENT;
  ceres::GradientProblemSolver::Summary summary;
  ceres::Solve(solver_options, problem, free.data(), &summary);
  return {static_cast<int>(summary.iterations.size()),
          ceres::TerminationTypeToString(summary.termination_type), summary.message};
}

// ---- the solver ----

namespace {

// Stretches of a clear but too fast spline per solve; they do not count as restarts.
constexpr int kMaxStretches = 4;

std::string format3(double x) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3f", x);
  return text;
}

}  // namespace

Loco::Loco(LocoOptions options) : options_(std::move(options)) {
  // The rules of LocoOptions::declare, which YAML loading enforces too.
  if (const std::string error = paramsError(options_); !error.empty()) {
    throw std::invalid_argument("Loco: " + error);
  }
}

LocoResult Loco::solve(const SplineEnds& ends, bool free_end, const DistanceField& field,
                       uint64_t seed) const {
  if (!ends.start_position.allFinite() || !ends.start_velocity.allFinite() ||
      !ends.start_acceleration.allFinite() || !ends.end_position.allFinite()) {
    throw std::invalid_argument("Loco::solve: the start state and goal must be finite");
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> offset(-options_.restart_radius, options_.restart_radius);
  std::vector<double> times =
      segmentTimes((ends.end_position - ends.start_position).norm(), options_.v_max, options_.a_max,
                   options_.segments, options_.time_scale);

  LocoResult best;
  const double start_speed = ends.start_velocity.norm();
  const double start_acceleration = ends.start_acceleration.norm();
  if (start_speed > options_.v_max + 1e-6 || start_acceleration > options_.a_max + 1e-6) {
    // No spline from here keeps the limits; do not spend restarts finding that out.
    best.reason = "the start state exceeds the limits: " + format3(start_speed) + " m/s, " +
                  format3(start_acceleration) + " m/s^2";
    return best;
  }
  // Attempts rank by acceptance, then by clearance (a clear one only missed the limits), then by
  // cost.
  const auto rank = [](const LocoProblem::Check& check) {
    return check.reason.empty() ? 0 : check.collision_free ? 1 : 2;
  };
  int best_rank = 3;
  int stretches = 0;
  std::optional<Derivatives> warm_start;
  // Rebuilt only when a stretch changes the segment times; restarts reuse it.
  std::optional<LocoProblem> built;
  for (;;) {
    if (!built) built.emplace(options_, JerkSpline(times, free_end), ends, field);
    const LocoProblem& problem = *built;
    const JerkSpline& spline = problem.spline();
    Derivatives free;
    if (warm_start) {
      free = *warm_start;
      warm_start.reset();
    } else {
      free = spline.minimumJerkFree(problem.fixed(), ends.end_position);
      if (best.restarts > 0) {
        // A restart: the same problem from a randomly displaced set of inner vertices.
        for (int v = 1; v < spline.numSegments(); ++v) {
          const int row = spline.freeRow(v, 0);
          for (int axis = 0; axis < 3; ++axis) free(row, axis) += offset(rng);
        }
      }
    }
    const LocoSolve solve = problem.minimize(free);
    best.iterations += solve.iterations;
    const LocoProblem::Check check = problem.check(free);
    const LocoCost cost = problem.cost(free);
    if (rank(check) < best_rank || (rank(check) == best_rank && cost.total < best.cost.total)) {
      best_rank = rank(check);
      best.accepted = check.reason.empty();
      best.reason = check.reason;
      best.segments = spline.segments(problem.fixed(), free);
      best.end_position =
          best.segments.back().coefficients * JerkSpline::basis(best.segments.back().duration, 0);
      best.cost = cost;
      best.min_distance = check.min_distance;
      best.termination = solve.termination;
      best.termination_message = solve.message;
    }
    if (best.accepted) break;
    if (check.collision_free && stretches < kMaxStretches) {
      // Clear but too fast: stretch time by s (speed scales with 1/s, acceleration with 1/s²)
      // and continue from the clear path, its order-r derivatives scaled by 1/s^r.
      const double s = 1.05 * std::max({1.0, check.max_speed / options_.v_max,
                                        std::sqrt(check.max_acceleration / options_.a_max)});
      for (double& t : times) t *= s;
      for (int v = 0; v <= spline.numSegments(); ++v) {
        for (int r = 1; r < JerkSpline::kVertexDerivatives; ++r) {
          if (const int row = spline.freeRow(v, r); row >= 0) free.row(row) /= std::pow(s, r);
        }
      }
      warm_start = free;
      built.reset();
      ++stretches;
      continue;
    }
    if (best.restarts == options_.restarts) break;
    ++best.restarts;
  }
  return best;
}

}  // namespace thicket::local_planner
