#include "thickness.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <limits>

namespace softcontact::collide {

double principal_thickness(const double* x, const std::vector<index_t>& vertices) {
  if (vertices.size() < 2) return 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (index_t v : vertices) mean += Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
  mean /= static_cast<double>(vertices.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (index_t v : vertices) {
    const Eigen::Vector3d d = Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]) - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  double thinnest = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 6; ++k) {
    const Eigen::Vector3d e = k < 3 ? Eigen::Vector3d(eig.eigenvectors().col(k)) : Eigen::Vector3d::Unit(k - 3);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (index_t v : vertices) {
      const double s = e.dot(Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]));
      lo = std::min(lo, s);
      hi = std::max(hi, s);
    }
    thinnest = std::min(thinnest, hi - lo);
  }
  return thinnest;
}

}  // namespace softcontact::collide
