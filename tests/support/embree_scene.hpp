#pragma once
// Embree 3 (float) over a triangle mesh: the independent oracle of the BVH tests and the speed
// reference of collision_benchmark. Never used by the library (it cannot count overlap tests).

#include <Eigen/Core>
#include <embree3/rtcore.h>

#include <limits>
#include <utility>
#include <vector>

namespace touchstone::testing {

class EmbreeScene {
 public:
  EmbreeScene(const std::vector<Eigen::Vector3d>& vertices, const std::vector<Eigen::Vector3i>& triangles) {
    device_ = rtcNewDevice(nullptr);
    scene_ = rtcNewScene(device_);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* coordinates = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices.size()));
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      for (int k = 0; k < 3; ++k) coordinates[3 * i + k] = static_cast<float>(vertices[i][k]);
    }
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) indices[3 * i + k] = static_cast<unsigned>(triangles[i][k]);
    }
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene_, geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(scene_);
  }
  ~EmbreeScene() {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  /// First hit of origin + t·direction, 0 ≤ t ≤ max_t (t in units of `direction`; a segment
  /// from → to is direction = to − from, max_t = 1): (t, triangle), triangle −1 and t = ∞ for none.
  std::pair<double, int> first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double max_t) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit query{};
    query.ray.org_x = static_cast<float>(origin.x());
    query.ray.org_y = static_cast<float>(origin.y());
    query.ray.org_z = static_cast<float>(origin.z());
    query.ray.dir_x = static_cast<float>(direction.x());
    query.ray.dir_y = static_cast<float>(direction.y());
    query.ray.dir_z = static_cast<float>(direction.z());
    query.ray.tnear = 0;
    query.ray.tfar = static_cast<float>(max_t);
    query.ray.mask = ~0u;
    query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    query.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &query);
    if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {std::numeric_limits<double>::infinity(), -1};
    return {query.ray.tfar, static_cast<int>(query.hit.primID)};
  }

 private:
  RTCDevice device_;
  RTCScene scene_;
};

}  // namespace touchstone::testing
