// Numeric types fixed once for the whole core (style note 9): double precision, row-major
// N×k matrices so that numpy C-ordered arrays map onto them without copies.
#pragma once
#include <Eigen/Core>
#include <cstdint>

namespace diffavatar {

using RowMatX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowMatX2d = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;
using RowMatX3i = Eigen::Matrix<int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowMatX2i = Eigen::Matrix<int32_t, Eigen::Dynamic, 2, Eigen::RowMajor>;
using RowMatXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using VecXd = Eigen::VectorXd;
using VecXi = Eigen::Matrix<int32_t, Eigen::Dynamic, 1>;

using RefX3d = Eigen::Ref<const RowMatX3d>;
using RefX2d = Eigen::Ref<const RowMatX2d>;
using RefX3i = Eigen::Ref<const RowMatX3i>;
using RefX2i = Eigen::Ref<const RowMatX2i>;
using RefXd = Eigen::Ref<const VecXd>;

using Vec3 = Eigen::Vector3d;
using Vec2 = Eigen::Vector2d;

}  // namespace diffavatar
