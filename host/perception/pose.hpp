// pose.hpp - object pose (paper step III): scatter matrix, principal eigenvector, axis line, elongation.
#pragma once
#include "types.hpp"

namespace rbx1::vision {

enum class AxisSource { Edges, Area };

struct PoseOptions {
  AxisSource source = AxisSource::Edges;  // Eq. 8 on the edge points (the paper), or the area moments
  double elongated_min = 1.15;            // elongation at or above this: elongated (the axis is meaningful)
  double round_max = 1.08;                // r_max / r_min of the contour below this: round, orientation 0
};

// Eigen-decomposition of the scatter matrix; near-isotropic objects follow the rule in README.md.
Pose estimate_pose(const Geometry& g, const PoseOptions& opt = {});

// Angle of a direction folded into (-90, 90] degrees.
double fold_axis_deg(double deg);
// Principal axis (deg) and sqrt eigenvalue ratio of a 2x2 symmetric matrix [[a, b], [b, c]] (Eigen).
void principal_axis(double a, double b, double c, double& axis_deg, double& ratio);

}  // namespace rbx1::vision
