#include "superdyna/core/trajectory.h"

namespace superdyna {

double pathLength(const Trajectory& trajectory) {
  double length = 0.0;
  for (std::size_t i = 1; i < trajectory.size(); ++i) {
    length += (trajectory[i].T_w_x.t - trajectory[i - 1].T_w_x.t).norm();
  }
  return length;
}

}  // namespace superdyna
