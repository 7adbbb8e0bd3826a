#pragma once
// Private to realtime/src/runtime: the graphics loop (30 Hz). The deformed organ (only the
// vertices of the local domain move), the tool and the force go to every output; an output
// that throws is disabled and noted, the run goes on.

#include "runtime_state.hpp"

namespace touchstone::realtime::runtime {

struct GraphicsLoop {
  RuntimeState& sim;
  DeformedSurface surface;
  std::vector<bool> sink_alive;
  WorkCounters work;  // graphics fields only
  int frame_index = 0;

  explicit GraphicsLoop(RuntimeState& sim_) : sim(sim_), surface(sim_.organ), sink_alive(sim_.sinks.size(), true) {}

  void frame(double time_s);
};

}  // namespace touchstone::realtime::runtime
