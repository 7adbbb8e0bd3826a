// Force extraction (tool_force.hpp): the cutoff of the traction integral's domain form and its
// derivative (checked by finite differences), and the extraction quadrature checked against the
// divergence theorem on the hemisphere: Σ_q ω_q ∇w(x_q) = ∮_∂Ω w n dA, which on B3 is a
// one-dimensional integral over the spherical cap (w = 0 before the cut and the base).
#include "hemisphere_fixture.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace touchstone::realtime::mfs {
namespace {

using testing::hemisphere;
using testing::hemisphere_radius_m;
using testing::pole_contact;
using testing::tool_radius_m;

constexpr double pi = 3.14159265358979323846;

TEST(ExtractionCutoff, IsOneInsideZeroOutsideAndItsSlopeMatchesFiniteDifferences) {
  const double inner = 3e-3, outer = 10e-3;
  EXPECT_EQ(extraction_cutoff(0.0, inner, outer), 1.0);
  EXPECT_EQ(extraction_cutoff(inner, inner, outer), 1.0);
  EXPECT_EQ(extraction_cutoff(outer, inner, outer), 0.0);
  EXPECT_EQ(extraction_cutoff(2 * outer, inner, outer), 0.0);
  EXPECT_NEAR(extraction_cutoff(0.5 * (inner + outer), inner, outer), 0.5, 1e-15);
  double slope = 1;
  extraction_cutoff(inner, inner, outer, &slope);
  EXPECT_EQ(slope, 0.0) << "C¹ where the shell starts";
  extraction_cutoff(outer, inner, outer, &slope);
  EXPECT_EQ(slope, 0.0) << "C¹ where the shell ends";
  for (const double s : {0.1, 0.3, 0.5, 0.77, 0.95}) {
    const double rho = inner + s * (outer - inner), h = 1e-7;
    extraction_cutoff(rho, inner, outer, &slope);
    const double central = (extraction_cutoff(rho + h, inner, outer) - extraction_cutoff(rho - h, inner, outer)) / (2 * h);
    EXPECT_NEAR(slope, central, 1e-6 * std::abs(central)) << "s = " << s;
    EXPECT_LT(slope, 0.0);
  }
}

TEST(ExtractionQuadrature, IsTheDivergenceTheoremOnTheHemisphere) {
  const double inner = 1.5 * tool_radius_m, outer = 4 * tool_radius_m, radius = hemisphere_radius_m;
  const PatchQuadrature shell = extraction_quadrature(hemisphere(), pole_contact(), inner, outer);
  ASSERT_FALSE(shell.points.empty());
  Eigen::Vector3d domain = Eigen::Vector3d::Zero();
  for (std::size_t q = 0; q < shell.points.size(); ++q) {
    const double rho = (shell.points[q] - pole_contact().point).norm();
    EXPECT_GE(rho, inner * (1 - 1e-12));
    EXPECT_LE(rho, outer * (1 + 1e-12));
    domain += shell.weights[q] * shell.normals[q];
  }
  // ∮ w n dA on the sphere |x| = R near the pole: polar angle φ, chord ρ = 2R sin(φ/2),
  // n_z = cos φ, dA = 2π R² sin φ dφ (Simpson, 20000 intervals).
  const int intervals = 20000;
  const double phi_max = 2 * std::asin(outer / (2 * radius));
  double boundary = 0;
  for (int i = 0; i <= intervals; ++i) {
    const double phi = phi_max * i / intervals;
    const double weight = (i == 0 || i == intervals) ? 1 : (i % 2 ? 4 : 2);
    boundary += weight * extraction_cutoff(2 * radius * std::sin(phi / 2), inner, outer) * std::cos(phi) * 2 * pi *
                radius * radius * std::sin(phi);
  }
  boundary *= phi_max / intervals / 3;
  // The surface is the gmsh triangulation (edge 0.5 mm), not the sphere: its chord sag and the
  // Gauss rules leave ~1e-4.
  EXPECT_NEAR(domain.z(), boundary, 1e-3 * boundary);
  EXPECT_LT(std::hypot(domain.x(), domain.y()), 1e-3 * boundary);
}

TEST(ExtractionQuadrature, TheDomainFormOfAConstantStressIsItsBoundaryIntegral) {
  // An affine displacement u = G x is reproduced exactly by the MLS (parameters u_J = G x_J), so
  // σ is constant and the traction map must give σ Σ_q ω_q ∇w_q for the model's own shell.
  LocalModelSettings settings;
  settings.formulation = Formulation::galerkin;
  settings.sprinkling.node_count = 35;
  settings.force.energy = false;
  const geometry::Material material{10.0e3, 0.45};
  const LocalModel model = build_local_model(hemisphere(), pole_contact(), material, settings);
  ASSERT_TRUE(model.ok()) << model.status;
  Eigen::Matrix3d gradient;
  gradient << 1e-3, 2e-3, -4e-4, 5e-4, -3e-3, 1e-3, 2e-4, 7e-4, 1.5e-3;
  Eigen::VectorXd parameters(3 * static_cast<Eigen::Index>(model.cloud.size()));
  for (std::size_t j = 0; j < model.cloud.size(); ++j) parameters.segment<3>(3 * j) = gradient * model.cloud.positions[j];
  const Eigen::Matrix3d strain = 0.5 * (gradient + gradient.transpose());
  const Eigen::Matrix3d stress =
      material.lame_lambda_Pa() * strain.trace() * Eigen::Matrix3d::Identity() + 2 * material.shear_modulus_Pa() * strain;
  const PatchQuadrature shell =
      extraction_quadrature(hemisphere(), pole_contact(), settings.force.extraction_inner_tool_radii * tool_radius_m,
                            settings.force.extraction_outer_local_radii * settings.sprinkling.local_radius_m,
                            settings.force.extraction_radial_points, settings.force.extraction_polar_points,
                            settings.force.extraction_azimuth_points);
  Eigen::Vector3d gradient_integral = Eigen::Vector3d::Zero();
  for (std::size_t q = 0; q < shell.points.size(); ++q) gradient_integral += shell.weights[q] * shell.normals[q];
  const Eigen::Vector3d expected = stress * gradient_integral;
  const Eigen::Vector3d extracted = model.traction_map * parameters;
  EXPECT_LT((extracted - expected).norm(), 1e-9 * expected.norm())
      << extracted.transpose() << " vs " << expected.transpose();
}

TEST(ExtractionQuadrature, AnEmptyShellIsRefusedBeforeTheBuildNamingBothFactors) {
  LocalModelSettings settings;
  settings.formulation = Formulation::galerkin;
  settings.force.extraction_outer_local_radii = 0.2;  // 0.2 L = 2.5 mm < 1.5 a = 3.75 mm
  try {
    build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings);
    FAIL() << "an empty extraction shell must be refused";
  } catch (const std::invalid_argument& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find("extraction_inner_tool_radii"), std::string::npos) << what;
    EXPECT_NE(what.find("extraction_outer_local_radii"), std::string::npos) << what;
  }
  settings.force.traction = false;  // without the traction integral the shell does not matter
  EXPECT_TRUE(build_local_model(hemisphere(), pole_contact(), geometry::Material{}, settings).ok());
}

}  // namespace
}  // namespace touchstone::realtime::mfs
