#pragma once
/// @file
/// Trivially copyable stand-ins for Eigen's fixed-size types, for values that cross threads
/// through a Seqlock (Eigen's matrices are not trivially copyable).

#include <Eigen/Core>

#include <array>

namespace touchstone::realtime::concurrency {

using PlainVector3 = std::array<double, 3>;
using PlainMatrix3 = std::array<double, 9>;  ///< column-major, as Eigen

inline PlainVector3 plain(const Eigen::Vector3d& v) noexcept { return {{v.x(), v.y(), v.z()}}; }
inline Eigen::Vector3d eigen(const PlainVector3& v) noexcept { return {v[0], v[1], v[2]}; }
inline PlainMatrix3 plain(const Eigen::Matrix3d& m) noexcept {
  PlainMatrix3 out{};
  Eigen::Map<Eigen::Matrix3d>(out.data()) = m;
  return out;
}
inline Eigen::Matrix3d eigen(const PlainMatrix3& m) noexcept { return Eigen::Map<const Eigen::Matrix3d>(m.data()); }

}  // namespace touchstone::realtime::concurrency
