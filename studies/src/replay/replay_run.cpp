// The palpation replay run (see the header): the real-time run on rank 0, the contacts' reference
// solves spread over the ranks (each rank writes its contacts' records; the FEM cache makes a
// rerun resume), the tick-by-tick comparison and the outputs on rank 0. One contact's reference
// is contact_reference.cpp.
#include "touchstone/studies/palpation_replay.hpp"

#include "contact_reference.hpp"

#include "touchstone/fem/richardson.hpp"
#include "touchstone/fem/tool_stiffness.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/realtime/runtime/contact_model.hpp"
#include "touchstone/realtime/runtime/surface_deformation.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"
#include "touchstone/studies/organ_atlas.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/sim_scene.hpp"
#include "touchstone/version.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>

namespace touchstone::studies {

namespace {
namespace fs = std::filesystem;
namespace rt = realtime::runtime;
using nlohmann::json;
using replay::Contact;
using replay::pack;
using replay::reference_geometry;
using replay::unpack;
using replay::verify_contact;

constexpr double pi = 3.14159265358979323846;

/// Frames whose reference force is below this fraction of the run's largest reference force are
/// left out of the relative errors (a press just beginning: both forces near zero).
constexpr double relative_error_floor = 0.05;


/// One tick of the real-time run with a model in use.
struct Frame {
  double time_s = 0;
  Eigen::Vector3d tip_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d mfs_force_N = Eigen::Vector3d::Zero();  ///< on the tissue, push-only
  std::uint64_t model_id = 0;
};

/// The models that gave a force, in order of first use, and the ones the study verifies.
std::vector<std::uint64_t> select_models(const PalpationReplayStudy& study, const std::vector<Frame>& frames,
                                         const std::vector<std::string>& only) {
  std::vector<std::uint64_t> used;
  for (const auto& f : frames)
    if (used.empty() || std::find(used.begin(), used.end(), f.model_id) == used.end()) used.push_back(f.model_id);
  std::vector<std::uint64_t> chosen;
  switch (study.selection) {
    case ContactSelection::all: chosen = used; break;
    case ContactSelection::every:
      for (std::size_t i = 0; i < used.size(); i += static_cast<std::size_t>(study.every)) chosen.push_back(used[i]);
      break;
    case ContactSelection::frames:
      for (const double t : study.frame_times_s) {
        const auto nearest = std::min_element(frames.begin(), frames.end(), [t](const Frame& a, const Frame& b) {
          return std::abs(a.time_s - t) < std::abs(b.time_s - t);
        });
        if (std::abs(nearest->time_s - t) > 0.5e-3 + 1e-9)
          throw std::invalid_argument(study.config_path + ": replay.frames: no contact at t = " + format_number(t) +
                                      " s (the tool presses with a model in use from " + format_number(frames.front().time_s) +
                                      " s; the nearest such tick is at " + format_number(nearest->time_s) + " s)");
        if (std::find(chosen.begin(), chosen.end(), nearest->model_id) == chosen.end()) chosen.push_back(nearest->model_id);
      }
      break;
  }
  if (!only.empty()) {
    std::vector<std::uint64_t> kept;
    for (const auto id : chosen) {
      const std::string label = "model" + std::to_string(id);
      if (std::any_of(only.begin(), only.end(), [&](const std::string& text) { return label.find(text) != std::string::npos; }))
        kept.push_back(id);
    }
    chosen = kept;
  }
  return chosen;
}


/// |F_mfs − F_ref| statistics over a set of frames.
struct ErrorSums {
  double difference_sq = 0, reference_sq = 0, max_abs_N = 0, max_rel = 0, max_angle_rad = 0;
  long long frames = 0, relative_frames = 0;
  double relative_l2() const { return reference_sq > 0 ? std::sqrt(difference_sq / reference_sq) : 0.0; }
};

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  if (a.norm() == 0 || b.norm() == 0) return 0;
  return std::atan2(a.cross(b).norm(), a.dot(b));
}


/// The real-time run of the scene (rank 0): its ticks with a model in use, its summary and the
/// contacts the study verifies. Throws std::invalid_argument for a run there is nothing to verify
/// in.
struct RealtimeRun {
  std::vector<Frame> frames;
  json summary;
  std::vector<Contact> contacts;
  double seconds = 0;
};

RealtimeRun run_realtime(const PalpationReplayStudy& study, const SimScene& scene, const ReplayRunOptions& options,
                         const fs::path& out, const std::string& realtime_directory, const std::string& organ_file) {
  RealtimeRun run;
  fs::create_directories(out);
  SimOptions sim;
  sim.virtual_clock = true;
  sim.output_directory = realtime_directory;
  sim.replay_path = study.recording_path;
  if (study.duration_s > 0) sim.duration_s = study.duration_s;
  sim.print = !options.quiet;
  sim.force_history_observer = [&run](const std::vector<rt::ForceSample>& chunk) {
    for (const auto& s : chunk)
      if (s.model_id != 0 && run.frames.size() < rt::max_force_history_samples)
        run.frames.push_back({s.time_s, s.tip_m, s.exact_N, s.model_id});
  };
  const auto sim_start = std::chrono::steady_clock::now();
  run.summary = run_sim(scene, sim);
  run.seconds = seconds_since(sim_start);
  if (run.frames.size() >= rt::max_force_history_samples)
    throw std::invalid_argument("the run pressed for more than " + std::to_string(rt::max_force_history_samples) +
                                " ticks, more than a replay keeps: shorten [replay] duration");
  if (run.frames.empty())
    throw std::invalid_argument(
        (study.recording_path.empty() ? "the scene's device (" + study.scene_path + ")" : "the recording '" + study.recording_path + "'") +
        " never presses the organ '" + organ_file + "' with a model in use: nothing to verify (a recording made on another organ, or in other units?)");
  const auto chosen = select_models(study, run.frames, options.only);
  if (chosen.empty()) throw std::invalid_argument("--only selects none of the run's contacts (they are named model<id>)");
  for (const auto& m : run.summary.at("models")) {
    const auto id = m.at("model_id").get<std::uint64_t>();
    if (std::find(chosen.begin(), chosen.end(), id) != chosen.end())
      run.contacts.push_back({id, vector_from_json(m.at("contact_point_m")), vector_from_json(m.at("direction"))});
  }
  if (run.contacts.size() != chosen.size())
    throw std::runtime_error("the run's model records miss some of its contacts (more models than it keeps records of)");
  return run;
}

/// Tick by tick: each verified tick's MFS force against K_ref (tip − c) of its contact, and the
/// surface displacements of both models; writes frames.csv.
struct TickComparison {
  ErrorSums total;
  std::map<std::uint64_t, ErrorSums> per_contact;
  std::map<std::uint64_t, std::pair<double, Eigen::Vector3d>> deepest;  ///< depth [m], U [m]
  std::map<std::uint64_t, std::pair<double, double>> displacement_sums;  ///< Σ|u_mfs − u_ref|², Σ|u_ref|² [m²]
  std::pair<double, double> total_displacement{0.0, 0.0};
  double max_reference_N = 0;
  double floor_N = 0;  ///< references below this are left out of the relative errors
  json worst_frames = json::array();
  json series = json::array();  ///< decimated for the report's plot
};

TickComparison compare_ticks(const std::vector<Frame>& frames, const std::map<std::uint64_t, json>& verified,
                             const std::map<std::uint64_t, json>& run_models, const fs::path& out) {
  TickComparison ticks;
  // Per contact, the local vertices both models give a displacement at: G_v (MFS) and D_v
  // (reference), each per unit tool displacement.
  struct VertexMaps {
    std::vector<Eigen::Matrix3d> mfs, reference;
  };
  std::map<std::uint64_t, VertexMaps> vertex_maps;
  for (const auto& [id, v] : verified) {
    VertexMaps& maps = vertex_maps[id];
    for (const auto& vertex : v.at("vertices")) {
      if (vertex.at("reference").is_null()) continue;
      maps.mfs.push_back(matrix_from_json(vertex.at("mfs")));
      maps.reference.push_back(matrix_from_json(vertex.at("reference")));
    }
  }

  for (const auto& f : frames) {
    auto it = verified.find(f.model_id);
    if (it == verified.end()) continue;
    const json& m = run_models.at(f.model_id);
    const Eigen::Vector3d c = vector_from_json(m.at("contact_point_m")), d = vector_from_json(m.at("direction"));
    const Eigen::Vector3d reference = rt::push_only(matrix_from_json(it->second.at("reference_stiffness_N_per_m")) * (f.tip_m - c), d);
    ticks.max_reference_N = std::max(ticks.max_reference_N, reference.norm());
  }
  ticks.floor_N = relative_error_floor * ticks.max_reference_N;

  AtomicFileWriter frames_csv((out / "frames.csv").string());
  frames_csv.append("time_s,model_id,tip_x_m,tip_y_m,tip_z_m,depth_m,mfs_x_N,mfs_y_N,mfs_z_N,reference_x_N,reference_y_N,"
                    "reference_z_N,error_N,relative_error,angle_deg,displacement_error\n");
  struct Worst {
    double time_s, error_N, relative;
    std::uint64_t model_id;
  };
  std::vector<Worst> worst;
  const std::size_t stride = std::max<std::size_t>(1, frames.size() / 4000);
  std::size_t index = 0;
  char line[640];
  for (const auto& f : frames) {
    auto it = verified.find(f.model_id);
    if (it == verified.end()) continue;
    const json& m = run_models.at(f.model_id);
    const Eigen::Vector3d c = vector_from_json(m.at("contact_point_m")), d = vector_from_json(m.at("direction"));
    const Eigen::Vector3d u = f.tip_m - c;
    const Eigen::Vector3d reference = rt::push_only(matrix_from_json(it->second.at("reference_stiffness_N_per_m")) * u, d);
    const double error = (f.mfs_force_N - reference).norm();
    const double relative = reference.norm() >= ticks.floor_N && ticks.floor_N > 0 ? error / reference.norm() : std::nan("");
    const double angle = angle_between(f.mfs_force_N, reference);
    // The surface displacement of the local vertices at this tick (both linear in U).
    const VertexMaps& maps = vertex_maps.at(f.model_id);
    double displacement_difference_sq = 0, displacement_reference_sq = 0;
    for (std::size_t k = 0; k < maps.mfs.size(); ++k) {
      const Eigen::Vector3d ur = maps.reference[k] * u;
      displacement_difference_sq += (maps.mfs[k] * u - ur).squaredNorm();
      displacement_reference_sq += ur.squaredNorm();
    }
    ticks.displacement_sums[f.model_id].first += displacement_difference_sq;
    ticks.displacement_sums[f.model_id].second += displacement_reference_sq;
    ticks.total_displacement.first += displacement_difference_sq;
    ticks.total_displacement.second += displacement_reference_sq;
    const double displacement_error =
        displacement_reference_sq > 0 ? std::sqrt(displacement_difference_sq / displacement_reference_sq) : std::nan("");
    for (ErrorSums* sums : {&ticks.total, &ticks.per_contact[f.model_id]}) {
      sums->difference_sq += error * error;
      sums->reference_sq += reference.squaredNorm();
      sums->max_abs_N = std::max(sums->max_abs_N, error);
      ++sums->frames;
      if (std::isfinite(relative)) {
        sums->max_rel = std::max(sums->max_rel, relative);
        sums->max_angle_rad = std::max(sums->max_angle_rad, angle);
        ++sums->relative_frames;
      }
    }
    const double depth = u.dot(d);
    auto& deep = ticks.deepest[f.model_id];
    if (depth > deep.first) deep = {depth, u};
    worst.push_back({f.time_s, error, relative, f.model_id});
    const int n = std::snprintf(line, sizeof line, "%.6f,%llu,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.6g,%.6g,%.6g,%.6g\n",
                                f.time_s, static_cast<unsigned long long>(f.model_id), f.tip_m.x(), f.tip_m.y(), f.tip_m.z(), depth,
                                f.mfs_force_N.x(), f.mfs_force_N.y(), f.mfs_force_N.z(), reference.x(), reference.y(), reference.z(),
                                error, relative, angle * 180 / pi, displacement_error);
    frames_csv.append(std::string(line, static_cast<std::size_t>(std::clamp(n, 0, static_cast<int>(sizeof line) - 1))));
    if (index++ % stride == 0)
      ticks.series.push_back({f.time_s, f.model_id, f.mfs_force_N.norm(), reference.norm(), std::isfinite(relative) ? json(relative) : json(nullptr),
                        angle * 180 / pi, json_number(displacement_error)});
  }
  frames_csv.commit();
  std::sort(worst.begin(), worst.end(), [](const Worst& a, const Worst& b) { return a.error_N > b.error_N; });
  for (std::size_t i = 0; i < worst.size() && i < 10; ++i)
    ticks.worst_frames.push_back({{"time_s", worst[i].time_s}, {"model_id", worst[i].model_id}, {"error_N", worst[i].error_N},
                            {"relative_error", json_number(worst[i].relative)}});
  return ticks;
}

/// Per contact: stiffness, force errors, displacements at the deepest press, and its ParaView
/// surface; writes contacts.csv and paraview/contacts.pvd.
struct ContactRows {
  json rows = json::array();
  double error_sq = 0;          ///< Σ over contacts of (relative L2 force error)²
  double rebuild_mismatch = 0;  ///< largest ‖K_t rebuilt − K_t of the run‖ / ‖K_t‖
};

ContactRows write_contact_outputs(const std::vector<Contact>& contacts, const std::map<std::uint64_t, json>& verified,
                                  const std::map<std::uint64_t, json>& run_models, TickComparison& ticks,
                                  const geometry::TriangleSurface& organ, const fs::path& out) {
  ContactRows result;
  char line[640];
  const fs::path paraview = out / "paraview";
  fs::create_directories(paraview);
  std::string pvd = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n";
  AtomicFileWriter contacts_csv((out / "contacts.csv").string());
  contacts_csv.append("model_id,reason,time_s,frames,x_m,y_m,z_m,k_mfs_N_per_m,k_reference_N_per_m,stiffness_error,"
                      "force_error_l2,force_error_max_N,reference_uncertainty,displacement_error_l2,exterior,dofs_finest\n");
  for (const auto& c : contacts) {
    const json& v = verified.at(c.model_id);
    const json& m = run_models.at(c.model_id);
    const Eigen::Vector3d d = c.direction;
    const Eigen::Matrix3d k_mfs = matrix_from_json(m.at("tool_stiffness_N_per_m"));
    const Eigen::Matrix3d k_ref = matrix_from_json(v.at("reference_stiffness_N_per_m"));
    const Eigen::Matrix3d k_rebuilt = matrix_from_json(v.at("rebuilt_tool_stiffness_N_per_m"));
    result.rebuild_mismatch = std::max(result.rebuild_mismatch, (k_rebuilt - k_mfs).norm() / k_mfs.norm());
    const double kn_mfs = d.dot(k_mfs * d), kn_ref = d.dot(k_ref * d);
    const ErrorSums& e = ticks.per_contact[c.model_id];
    result.error_sq += e.relative_l2() * e.relative_l2();

    // Surface displacements at the ticks.deepest press: u_v = G_v U (MFS), D_v U (reference).
    const Eigen::Vector3d u_deep = ticks.deepest[c.model_id].second;
    std::vector<Eigen::Vector3d> u_mfs(organ.vertices().size(), Eigen::Vector3d::Zero()), u_ref = u_mfs, u_diff = u_mfs;
    double diff_sq = 0, ref_sq = 0;
    long long found = 0, compared = 0;
    for (const auto& vertex : v.at("vertices")) {
      const auto index_v = vertex.at("vertex").get<std::size_t>();
      ++compared;
      u_mfs[index_v] = matrix_from_json(vertex.at("mfs")) * u_deep;  // the tool's part: the reference has no body loads
      if (vertex.at("reference").is_null()) continue;
      ++found;
      u_ref[index_v] = matrix_from_json(vertex.at("reference")) * u_deep;
      u_diff[index_v] = u_mfs[index_v] - u_ref[index_v];
      diff_sq += u_diff[index_v].squaredNorm();
      ref_sq += u_ref[index_v].squaredNorm();
    }
    const double displacement_error = ref_sq > 0 ? std::sqrt(diff_sq / ref_sq) : std::nan("");
    // The split: how much of the difference is one translation of the whole local region (the
    // organ moving as a body, which a field confined to the ball cannot show).
    Eigen::Vector3d mean_difference = Eigen::Vector3d::Zero();
    for (const auto& vertex : v.at("vertices"))
      if (!vertex.at("reference").is_null()) mean_difference += u_diff[vertex.at("vertex").get<std::size_t>()];
    if (found > 0) mean_difference /= static_cast<double>(found);
    const double translated_sq = diff_sq - static_cast<double>(found) * mean_difference.squaredNorm();
    const double displacement_error_local = ref_sq > 0 ? std::sqrt(std::max(0.0, translated_sq) / ref_sq) : std::nan("");
    const std::string vtp = c.label() + "_surface.vtp";
    meshes::SurfaceWriteOptions write;
    write.point_vectors = {{"displacement_mfs_m", u_mfs}, {"displacement_reference_m", u_ref}, {"difference_m", u_diff}};
    meshes::write_surface_mesh((paraview / vtp).string(), organ.vertices(), organ.triangles(), write);
    pvd += "    <DataSet timestep=\"" + format_number(m.at("adopted_s").get<double>()) + "\" file=\"" + vtp + "\"/>\n";

    json row{{"model_id", c.model_id},
             {"label", c.label()},
             {"reason", m.at("reason")},
             {"adopted_s", m.at("adopted_s")},
             {"contact_point_m", m.at("contact_point_m")},
             {"direction", m.at("direction")},
             {"exterior_used", m.at("exterior_used")},
             {"node_count", m.at("node_count")},
             {"mfs_stiffness_N_per_m", m.at("tool_stiffness_N_per_m")},
             {"reference_stiffness_N_per_m", v.at("reference_stiffness_N_per_m")},
             {"axial_stiffness_mfs_N_per_m", kn_mfs},
             {"axial_stiffness_reference_N_per_m", kn_ref},
             {"stiffness_error", kn_mfs / kn_ref - 1},
             {"frames", e.frames},
             {"force_error_l2", e.relative_l2()},
             {"force_error_max_N", e.max_abs_N},
             {"force_error_max_relative", e.relative_frames > 0 ? json(e.max_rel) : json(nullptr)},
             {"force_angle_max_deg", e.max_angle_rad * 180 / pi},
             {"reference_convergence", v.at("convergence")},
             {"reference_levels", v.at("levels")},
             {"deepest_press_m", ticks.deepest[c.model_id].first},
             {"displacement_error_l2", json_number(displacement_error)},
             {"displacement_mean_difference_m", vector_json(mean_difference)},
             {"displacement_error_l2_without_mean", json_number(displacement_error_local)},
             {"displacement_error_l2_over_ticks",
              json_number(ticks.displacement_sums[c.model_id].second > 0
                              ? std::sqrt(ticks.displacement_sums[c.model_id].first / ticks.displacement_sums[c.model_id].second)
                              : std::nan(""))},
             {"displacement_vertices", compared},
             {"displacement_vertices_found", found},
             {"paraview_surface", "paraview/" + vtp},
             {"paraview_reference", v.at("reference_vtu")},
             {"solved_on_rank", v.at("rank")},
             {"seconds", v.at("seconds")}};
    result.rows.push_back(row);
    std::snprintf(line, sizeof line, "%llu,%s,%.6f,%lld,%.17g,%.17g,%.17g,%.9g,%.9g,%.6g,%.6g,%.6g,%.6g,%.6g,%s,%zu\n",
                  static_cast<unsigned long long>(c.model_id), m.at("reason").get<std::string>().c_str(), m.at("adopted_s").get<double>(),
                  e.frames, c.point_m.x(), c.point_m.y(), c.point_m.z(), kn_mfs, kn_ref, kn_mfs / kn_ref - 1, e.relative_l2(),
                  e.max_abs_N, value_or_nan(v.at("convergence"), "relative_uncertainty"), displacement_error,
                  m.at("exterior_used").get<std::string>().c_str(), v.at("levels").back().at("dofs").get<std::size_t>());
    contacts_csv.append(line);
  }
  contacts_csv.commit();
  pvd += "  </Collection>\n</VTKFile>\n";
  write_file_atomically((paraview / "contacts.pvd").string(), pvd);
  return result;
}

}  // namespace

json replay_atlas_agreement(const PalpationReplayStudy& study, const SimScene& scene) {
  const std::string held = describe_attachment(study.attachment);
  const auto& atlas = scene.settings.organ_atlas;
  if (!atlas)
    return {{"atlas", nullptr}, {"attachment", held}, {"attachment_checked", false},
            {"note", "the scene has no organ atlas: the real-time model uses the half-space exterior"}};
  json agreement{{"atlas", scene.atlas_path}, {"attachment", held}, {"attachment_checked", !atlas->attachment.empty()}};
  if (atlas->attachment.empty()) {
    agreement["note"] = "the organ atlas '" + scene.atlas_path +
                        "' does not record where its organ was held (written before atlases recorded it): "
                        "the replay's attachment is not checked against it";
  } else if (atlas->attachment != held) {
    throw std::invalid_argument(study.config_path + ": [organ] holds the organ " + held + ", but the scene's organ atlas '" +
                                scene.atlas_path + "' was made holding it " + atlas->attachment +
                                "; the real-time model's exterior knows only the atlas's attachment, so the reference "
                                "must hold the organ the same way (set the [organ] attachment rule to the atlas's)");
  }
  return agreement;
}

json run_palpation_replay(const PalpationReplayStudy& study, const ReplayRunOptions& options) {
  study.validate();
  const bool rank0 = fem::MpiSession::rank() == 0;
  const auto start = std::chrono::steady_clock::now();
  SimScene scene = read_sim_scene(study.scene_path);
  scene.write_time_series = false;  // the replay writes its own ParaView files
  scene.window = false;
  const fs::path out = options.output_directory;
  const std::string realtime_directory = (out / "realtime").string();
  const std::string organ_file = scene_organ_file(scene, realtime_directory);
  const double organ_unit_scale = scene.surface_path.empty() ? 1.0 : scene.surface_unit_scale;

  // The reference's mesh settings against the scene's tool, before anything runs.
  {
    const meshes::MeshParameters g = reference_geometry(study, scene.settings, organ_file, organ_unit_scale);
    try {
      g.validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(study.config_path + ": [mesh] against the scene's tool (tip_radius " +
                                  format_number(g.tool_radius_m) + " m): " + e.what());
    }
  }

  const json atlas_agreement = replay_atlas_agreement(study, scene);
  if (rank0 && !options.quiet && atlas_agreement.contains("note"))
    std::printf("%s: note: %s\n", study.name.c_str(), atlas_agreement.at("note").get<std::string>().c_str());

  // 1. The real-time run (rank 0), and the contacts every rank needs.
  RealtimeRun realtime;
  std::string failure;
  if (rank0) {
    try {
      realtime = run_realtime(study, scene, options, out, realtime_directory, organ_file);
    } catch (const std::exception& e) {
      failure = e.what();
    }
  }
  std::vector<double> status{failure.empty() ? 0.0 : 1.0};
  fem::MpiSession::broadcast_from_root(status);
  if (status[0] != 0) throw std::runtime_error(rank0 ? failure : "the real-time run on rank 0 failed");
  std::vector<double> packed = pack(realtime.contacts);
  fem::MpiSession::broadcast_from_root(packed);
  const std::vector<Contact> contacts = unpack(packed);

  // 2. The reference at each contact, spread over the ranks; each writes its contacts' records.
  meshes::SurfaceReadOptions read;
  read.unit_scale = organ_unit_scale;
  const geometry::TriangleSurface organ = meshes::load_surface(organ_file, read);
  const fs::path records = out / "contacts";
  if (rank0) fs::create_directories(records);
  fem::MpiSession::barrier();
  const unsigned ranks = fem::MpiSession::size(), rank = fem::MpiSession::rank();
  const auto fem_start = std::chrono::steady_clock::now();
  failure.clear();
  for (std::size_t i = rank; i < contacts.size(); i += ranks) {
    try {
      const json record = verify_contact(contacts[i], study, scene, organ, organ_file, organ_unit_scale, options);
      write_file_atomically((records / (contacts[i].label() + ".json")).string(), record.dump(1) + "\n");
    } catch (const std::exception& e) {
      failure = contacts[i].label() + " (c = " + vector_json(contacts[i].point_m).dump() + " m): " + e.what();
      break;
    }
  }
  std::vector<double> failed{failure.empty() ? 0.0 : 1.0};
  fem::MpiSession::sum_over_ranks(failed);
  if (!failure.empty()) throw std::runtime_error(failure);
  if (failed[0] != 0) throw std::runtime_error("another rank's reference solve failed (its message is above)");
  const double fem_seconds = seconds_since(fem_start);
  if (!rank0) return json::object();

  // 3. Tick by tick, on rank 0.
  std::map<std::uint64_t, json> verified;
  for (const auto& c : contacts) verified[c.model_id] = json::parse(read_file((records / (c.label() + ".json")).string()));
  std::map<std::uint64_t, json> run_models;
  for (const auto& m : realtime.summary.at("models")) run_models[m.at("model_id").get<std::uint64_t>()] = m;

  TickComparison ticks = compare_ticks(realtime.frames, verified, run_models, out);

  const ContactRows contact_outputs = write_contact_outputs(contacts, verified, run_models, ticks, organ, out);

  double max_uncertainty = 0;
  for (const auto& row : contact_outputs.rows) max_uncertainty = std::max(max_uncertainty, value_or_nan(row.at("reference_convergence"), "relative_uncertainty"));
  json document{
      {"study", study.name},
      {"kind", "palpation_replay"},
      {"provenance", provenance(options.config_text)},
      {"params", palpation_replay_params(study)},
      {"scene", scene.name},
      {"organ_file", organ_file},
      {"organ_atlas", scene.atlas_path},
      {"atlas_agreement", atlas_agreement},
      {"contact_condition", geometry::to_string(scene.settings.tool.condition)},
      {"realtime",
       {{"summary", "realtime/summary.json"},
        {"duration_s", realtime.summary.at("duration_s")},
        {"models", realtime.summary.at("models").size()},
        {"exterior_used", realtime.summary.at("model_builds").at("exterior_used")},
        {"frames_with_model", realtime.frames.size()},
        {"seconds", realtime.seconds}}},
      {"contacts", contact_outputs.rows},
      {"summary",
       {{"verified_contacts", contacts.size()},
        {"verified_frames", ticks.total.frames},
        {"force_error_l2", ticks.total.relative_l2()},
        {"force_error_rms_over_contacts", contacts.empty() ? 0.0 : std::sqrt(contact_outputs.error_sq / contacts.size())},
        {"force_error_max_N", ticks.total.max_abs_N},
        {"force_error_max_relative", ticks.total.relative_frames > 0 ? json(ticks.total.max_rel) : json(nullptr)},
        {"force_angle_max_deg", ticks.total.max_angle_rad * 180 / pi},
        {"displacement_error_l2",
         json_number(ticks.total_displacement.second > 0 ? std::sqrt(ticks.total_displacement.first / ticks.total_displacement.second) : std::nan(""))},
        {"relative_error_floor_N", ticks.floor_N},
        {"max_reference_force_N", ticks.max_reference_N},
        {"reference_uncertainty_max", max_uncertainty},
        {"rebuilt_stiffness_mismatch_max", contact_outputs.rebuild_mismatch}}},
      {"worst_frames", ticks.worst_frames},
      {"series_columns", {"time_s", "model_id", "mfs_force_N", "reference_force_N", "relative_error", "angle_deg", "displacement_error"}},
      {"series", ticks.series},
      {"timing",
       {{"mpi_ranks", ranks},
        {"realtime_s", realtime.seconds},
        {"reference_s", fem_seconds},
        {"total_s", seconds_since(start)}}},
      {"outputs",
       {{"frames_csv", "frames.csv"}, {"contacts_csv", "contacts.csv"}, {"paraview", "paraview/contacts.pvd"},
        {"realtime", "realtime/"}}}};
  write_file_atomically((out / "config.resolved.toml").string(), resolved_palpation_replay_toml(study));
  write_file_atomically((out / "results.json").string(), document.dump(2) + "\n");
  return document;
}

}  // namespace touchstone::studies
