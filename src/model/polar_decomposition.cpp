#include "polar_decomposition.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>

namespace softcontact::model {

Mat3 rotation_from_svd(const Mat3& F) {
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> f = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(F.data());
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(f, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  // Singular values come sorted in decreasing order: flipping the last columns moves a
  // reflection (det -1) onto the smallest singular value, which then carries the sign
  // of det F. Flipping both (det U = det V = -1) changes nothing in U V^T but keeps
  // S = V diag(s) V^T consistent.
  if (U.determinant() < 0) U.col(2) *= -1;
  if (V.determinant() < 0) V.col(2) *= -1;
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> r = U * V.transpose();
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R[3 * i + j] = r(i, j);
  return R;
}

}  // namespace softcontact::model
