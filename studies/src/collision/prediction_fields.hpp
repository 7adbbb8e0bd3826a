#pragma once
// The collision predictor's settings table ([prediction] of collision studies and sim scenes).

#include "../fem_reference/setting_fields.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"

namespace touchstone::studies {

/// Every PredictionSettings field but the cycle period (the caller's: 1 / the haptic rate).
const std::vector<SettingField<realtime::collision::PredictionSettings>>& prediction_fields();

}  // namespace touchstone::studies
