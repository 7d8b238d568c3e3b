// pseudoAngle(): a cheap monotone stand-in for atan2, for azimuth bins and bark texture.
#pragma once

namespace thicket::sim {

// A cheap stand-in for atan2(y, x) that increases with it: [0, 4) over a turn from +x, one unit
// per quadrant. Undefined at (0, 0).
inline double pseudoAngle(double x, double y) {
  if (y >= 0) return x >= 0 ? y / (x + y) : 1 - x / (y - x);
  return x < 0 ? 2 + y / (x + y) : 3 + x / (x - y);
}

}  // namespace thicket::sim
