#include "graphics_loop.hpp"

namespace touchstone::realtime::runtime {

void GraphicsLoop::frame(double time_s) {
  ++work.graphics_frames;
  const HapticState state = sim.haptic_state.load();
  std::shared_ptr<const DeformationMap> map;
  {
    std::lock_guard lock(sim.deformation_mutex);
    map = sim.deformation;
  }
  const bool apply = state.in_contact && map && map->model_id == state.model_in_use;
  const Eigen::Vector3d tip = eigen(state.tip_m);
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();
  if (apply) {
    displacement = tip - map->contact_point_m;
    if (displacement.dot(map->direction) <= 0) displacement.setZero();
  }
  if (apply || surface.moved_vertices() > 0) {
    ++work.surface_updates;
    work.vertices_written += surface.update(map.get(), displacement, apply);
  }
  graphics::GraphicsFrame frame;
  frame.time_s = time_s;
  frame.index = frame_index++;
  frame.organ_vertices_m = &surface.vertices_m();
  frame.organ_displacement_m = &surface.displacement_m();
  frame.tool_tip_m = tip;
  frame.tool_axis = eigen(state.tool_axis).normalized();
  frame.tool_tip_radius_m = sim.settings.tool.tip_radius_m;
  frame.tool_shaft_length_m = sim.settings.tool.shaft_length_m;
  frame.tool_shaft_radius_m = sim.settings.tool.shaft_radius_m;
  frame.force_on_hand_N = eigen(state.force_on_hand_N);
  frame.in_contact = state.in_contact;
  for (std::size_t i = 0; i < sim.sinks.size(); ++i) {
    if (!sink_alive[i]) continue;
    try {
      sim.sinks[i]->frame(frame);
    } catch (const std::exception& error) {
      ++work.sink_errors;
      sink_alive[i] = false;
      std::lock_guard lock(sim.notes_mutex);
      sim.notes.push_back("graphics output '" + sim.sinks[i]->name() + "' failed and was disabled: " + error.what());
    }
  }
}

}  // namespace touchstone::realtime::runtime
