// Local trajectory optimization ("loco", docs/design.md §1): the jerk spline of spline.h shaped by
//
//   J = w_d J_d + w_c J_c + w_g J_g
//
// J_d the jerk cost; J_c = Σ_k c(d(f(t_k))) ||v(t_k)|| Δt the collision line integral sampled
// every Δt on the interpolated ESDF distance d (unknown space reads d = 0), plus the end point
// weighted as if flown at v_max (so a free end cannot come to rest inside an obstacle); J_g the
// soft goal cost ||f(T) - g|| (free end only). The potential c is CHOMP's (docs/design.md §1)
// measured from the clearance acceptance asks for, robot radius + clearance margin, rather than
// from the bare radius, so that the optimum clears the acceptance test instead of grazing it.
// Minimized over the free end-derivatives with Ceres' gradient-problem solver (L-BFGS),
// gradients in closed form. A solution is accepted only when every Δt sample is known with
// distance >= robot radius + clearance margin and the spline keeps v_max and a_max. A clear
// solution that is too fast is stretched in time and re-optimized from where it was (up to four
// times); one in collision restarts from seeded random perturbations.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "thicket/common/esdf_query.h"
#include "thicket/common/params.h"
#include "thicket/common/polynomial_trajectory.h"
#include "thicket/local_planner/spline.h"

namespace thicket::local_planner {

/// Where the planner reads clearance: the mirrored ESDF (esdfField) or, in tests, an analytic
/// field. Unknown points have known == false.
using DistanceField = std::function<EsdfSample(const Eigen::Vector3d&)>;

/// sampleEsdf on `esdf`, which must outlive the returned field.
DistanceField esdfField(const EsdfLayer& esdf);

/// The acceptance test samples clearance every this much [s]: far finer than the cost integral's
/// Δt, since between samples 0.2 m apart the distance to an obstacle beside the path dips by up to
/// ~1 cm.
constexpr double kClearanceCheckDt = 0.02;

/// The clearance part of the acceptance test on `trajectory`: its samples every kClearanceCheckDt
/// from its start, and its end, that are not before `from` seconds after its start (after its end
/// the vehicle rests there, so `from` beyond the end checks the end point alone).
///
/// Escape: when the first of those samples is known but already closer than `required` (the map
/// learned more about an obstacle beside a vehicle standing or flying there), the threshold is
/// that sample's own distance: a trajectory that never comes closer than where it starts passes,
/// so a vehicle inside the margin can leave it instead of being refused every cycle, and can never
/// be planned closer. (Loco's acceptance adds that such a plan must end outside the margin.)
/// `escape_slack` lowers that threshold a little more, and extends the escape to starts less than
/// that outside the margin: a vehicle at rest starts along the obstacle before the optimizer's
/// first collision sample sees it, and dips by a hair.
struct ClearanceCheck {
  bool clear = false;       ///< every sample known with distance >= the threshold
  double min_distance = 0;  ///< over the samples, 0 where unknown [m]
  std::string reason;       ///< the first sample that fails, in words; empty when clear
  /// `required`, or the first sample's distance less `escape_slack` when that is less (escape) [m]
  double threshold = 0;
};
ClearanceCheck checkClearance(const PolynomialTrajectory& trajectory, double from,
                              const DistanceField& field, double required, double escape_slack = 0);

/// CHOMP's collision potential of distance d (docs/design.md §1) and its derivative dc/dd. With
/// d' = d - radius: -d' + ε/2 inside the radius, (d' - ε)² / (2ε) within ε of it, 0 beyond.
/// Continuous with a continuous derivative. Loco passes robot radius + clearance margin.
struct Potential {
  double value = 0;
  double derivative = 0;
};
Potential collisionPotential(double distance, double radius, double epsilon);

struct LocoOptions {
  double w_d = 0.1;               ///< weight of the jerk cost
  double w_c = 10;                ///< weight of the collision cost
  double w_g = 2.5;               ///< weight of the soft goal cost
  double robot_radius = 0.5;      ///< [m]
  double potential_margin = 0.5;  ///< ε = robot_radius + this [m]
  double sample_dt = 0.1;         ///< Δt of the collision integral [s]
  /// Accepted samples need distance >= robot_radius + this. Derived, not tuned: the mapper's
  /// certified bound on how far above the robot radius the ESDF can read where the vehicle would
  /// be in collision (0.11 m at the default 0.1 m voxels, measured by `thicket-bench clearance`;
  /// README), plus the most the distance can dip between two acceptance samples 0.02 s apart at
  /// v_max (0.01 m) [m].
  double clearance_margin = 0.12;
  /// The collision potential rises from robot_radius + clearance_margin + this: an optimum pressed
  /// against the obstacles (the collision integral sees them every sample_dt) then still clears
  /// the acceptance, checked every 0.02 s, instead of missing it by a millimetre [m].
  double potential_buffer = 0.02;
  /// A plan that starts inside the margin, or less than this outside it, may come this much
  /// closer than its start (and must end outside the margin); 0: never closer (the paper) [m].
  double escape_slack = 0;
  double v_max = 1.0;  ///< [m/s]
  double a_max = 2.0;  ///< [m/s²]
  int segments = 3;
  double time_scale = 1.2;  ///< segment time: this × the velocity-ramp time, split evenly
  int restarts = 5;         ///< random restarts after the first solve
  /// Restarts move each inner vertex of the initial spline by up to this, per axis [m].
  double restart_radius = 1.0;
  int max_iterations = 100;  ///< L-BFGS iterations per solve
  /// A solve stops when an iteration lowers the cost by less than this fraction.
  double function_tolerance = 1e-4;
  /// ||f(T) - g|| is smoothed as sqrt(||.||² + δ²) - δ so its gradient exists at the goal [m].
  double goal_smoothing = 0.01;

  double epsilon() const { return robot_radius + potential_margin; }
  /// The clearance the acceptance asks of every sample: robot_radius + clearance_margin [m].
  double requiredClearance() const { return robot_radius + clearance_margin; }
  void declare(Params& p);
};

/// The cost terms of one spline (unweighted) and the total.
struct LocoCost {
  double derivative = 0;  ///< J_d
  double collision = 0;   ///< J_c
  double goal = 0;        ///< J_g (0 with a fixed end)
  double total = 0;       ///< w_d J_d + w_c J_c + w_g J_g
};

struct LocoResult {
  bool accepted = false;
  /// Why the best solution was not accepted ("sample at t=1.20 s: distance 0.31 m ...").
  std::string reason;
  /// The accepted spline or, when nothing was accepted, the best one tried.
  std::vector<PolynomialSegment> segments;
  Eigen::Vector3d end_position = Eigen::Vector3d::Zero();
  LocoCost cost;
  /// The smallest distance over the Δt samples (0 where unknown) [m].
  double min_distance = 0;
  int iterations = 0;  ///< solver iterations over all attempts
  int restarts = 0;    ///< random restarts used (time stretches not counted)
  /// How the solve that gave `segments` ended: Ceres's termination type ("CONVERGENCE",
  /// "NO_CONVERGENCE", "FAILURE", ...) and its message; empty when no solve ran.
  std::string termination;
  std::string termination_message;
};

/// What one L-BFGS run reports.
struct LocoSolve {
  int iterations = 0;
  std::string termination;  ///< Ceres's termination type, as TerminationTypeToString names it
  std::string message;      ///< Ceres's summary message
};

/// The problem one solve works on: a spline (times, free end or not), its fixed derivatives, the
/// goal and the field. Exposed for tests (gradients against finite differences) and benchmarks.
class LocoProblem {
 public:
  LocoProblem(const LocoOptions& options, JerkSpline spline, const SplineEnds& ends,
              DistanceField field);

  const JerkSpline& spline() const { return spline_; }
  const Derivatives& fixed() const { return fixed_; }
  int numParameters() const { return spline_.numFree() * 3; }

  /// The cost at free derivatives `free` and, with `gradient`, its gradient (same shape).
  LocoCost cost(const Derivatives& free, Derivatives* gradient = nullptr) const;

  /// Checks a spline for acceptance.
  struct Check {
    std::string reason;           ///< empty when accepted, else why not
    bool collision_free = false;  ///< every 0.02 s sample known and clear
    double min_distance = 0;      ///< over the 0.02 s samples, 0 where unknown [m]
    double max_speed = 0;         ///< at 0.01 s [m/s]
    double max_acceleration = 0;  ///< at 0.01 s [m/s²]
  };
  Check check(const Derivatives& free) const;

  /// Runs L-BFGS from `free` (updated in place).
  LocoSolve minimize(Derivatives& free) const;

 private:
  struct Sample {
    int segment;
    double tau;
    double t;
    Eigen::RowVectorXd position_row;  // basis' * coefficientMap: [d_F; d_P] -> position
    Eigen::RowVectorXd velocity_row;
  };

  LocoOptions options_;
  JerkSpline spline_;
  Derivatives fixed_;
  Eigen::Vector3d goal_;
  DistanceField field_;
  std::vector<Sample> samples_;
};

/// Plans one loco trajectory from `ends` toward ends.end_position (fixed end) or near it (free
/// end). `seed` makes the restarts reproducible. Throws std::invalid_argument on non-finite ends.
class Loco {
 public:
  /// Throws std::invalid_argument on options out of range.
  explicit Loco(LocoOptions options);
  const LocoOptions& options() const { return options_; }

  LocoResult solve(const SplineEnds& ends, bool free_end, const DistanceField& field,
                   uint64_t seed) const;

 private:
  LocoOptions options_;
};

}  // namespace thicket::local_planner
