#include "touchstone/realtime/collision/collision_prediction.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::collision {

namespace {

using Eigen::Vector3d;

constexpr double pi = 3.14159265358979323846;

const PredictionSettings& validated(const PredictionSettings& settings) {
  settings.validate();
  return settings;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// History (eqs. 1–2)

ToolPathHistory::ToolPathHistory(int window_samples) noexcept
    : window_(std::clamp(window_samples, 1, max_window_samples)) {}

void ToolPathHistory::push(const Vector3d& position) noexcept {
  positions_[next_] = position;
  next_ = next_ + 1 == window_ ? 0 : next_ + 1;
  if (size_ < window_) ++size_;
}

void ToolPathHistory::clear() noexcept {
  next_ = 0;
  size_ = 0;
}

const Vector3d& ToolPathHistory::previous(int i) const noexcept {
  int index = next_ - i;
  if (index < 0) index += window_;
  return positions_[index];
}

Vector3d ToolPathHistory::mean_tool_path(const Vector3d& current) const noexcept {
  if (size_ == 0) return Vector3d::Zero();
  // Eq. 2 as written: the average of the differences (small numbers summed, not positions).
  // While filling, the entries 0 … size_ − 1 are the ones written.
  Vector3d sum = Vector3d::Zero();
  for (int k = 0; k < size_; ++k) sum += current - positions_[k];
  return sum / size_;
}

// ---------------------------------------------------------------------------------------------
// Settings

void PredictionSettings::validate() const {
  const auto reject = [](const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("PredictionSettings." + field + " = " + std::to_string(value) + " " + rule);
  };
  const auto positive = [&](const std::string& field, double value) {
    if (!(value > 0) || !std::isfinite(value)) reject(field, value, "must be finite and > 0");
  };
  if (window_samples < 1 || window_samples > max_window_samples)
    reject("window_samples", window_samples, "must be in [1, " + std::to_string(max_window_samples) + "]");
  if (sample_period_cycles < 1 || sample_period_cycles > 1000)
    reject("sample_period_cycles", sample_period_cycles, "must be in [1, 1000]");
  positive("straight_line_range_m", straight_line_range_m);
  if (!(direction_threshold_rad > 0 && direction_threshold_rad <= pi))
    reject("direction_threshold_rad", direction_threshold_rad, "must be in (0, pi]");
  if (!(margin_m >= 0) || !std::isfinite(margin_m)) reject("margin_m", margin_m, "must be finite and >= 0");
  positive("handover_distance_m", handover_distance_m);
  positive("near_exit_distance_m", near_exit_distance_m);
  if (!(corridor_step_fraction > 0 && corridor_step_fraction <= 1))
    reject("corridor_step_fraction", corridor_step_fraction, "must be in (0, 1]");
  if (corridor_balls < 1 || corridor_balls > max_corridor_balls)
    reject("corridor_balls", corridor_balls, "must be in [1, " + std::to_string(max_corridor_balls) + "]");
  positive("ray_max_distance_m", ray_max_distance_m);
  if (ray_max_distance_m < straight_line_range_m)
    reject("ray_max_distance_m", ray_max_distance_m, "must be >= straight_line_range_m");
  if (!(min_path_length_m >= 0) || !std::isfinite(min_path_length_m))
    reject("min_path_length_m", min_path_length_m, "must be finite and >= 0");
  if (detection_period_cycles < 1 || detection_period_cycles > 1000)
    reject("detection_period_cycles", detection_period_cycles, "must be in [1, 1000]");
  positive("max_tip_speed_m_per_s", max_tip_speed_m_per_s);
  positive("cycle_period_s", cycle_period_s);
  if (direction_check_period_cycles < 0 || direction_check_period_cycles % detection_period_cycles != 0)
    reject("direction_check_period_cycles", direction_check_period_cycles,
           "must be 0 or a positive multiple of detection_period_cycles");
}

// ---------------------------------------------------------------------------------------------
// One prediction

CollisionPrediction predict_collision(const SurfaceQueries& surface, const PredictionSettings& settings,
                                      const Vector3d& anchor, const ClosestSurfacePoint& closest,
                                      const Vector3d& mean_tool_path, double mean_sample_age_s,
                                      double shrink_m, Corridor& corridor, QueryCounters* counters,
                                      long long* closest_point_queries, long long* ray_casts) noexcept {
  CollisionPrediction prediction;
  prediction.anchor = anchor;
  prediction.anchor_distance_m = closest.distance_m;
  prediction.closest_point = closest.point;
  corridor.size = 0;

  // The ball around the anchor: certified to D − margin, tested at D − margin − shrink. Too
  // thin to be worth it (or a non-finite distance): full detection instead.
  const double safe = closest.distance_m - settings.margin_m;
  const double full = safe - shrink_m;
  if (!(full > settings.handover_distance_m)) {
    prediction.near_surface = true;
    return prediction;
  }
  corridor.size = 1;
  // Without a predicted point within the straight-line range, a tool that is not moving away
  // from the surface has its ball tested only to D − range (at least half its radius), so
  // that it predicts again once it may have come within the range: the paper's "re-predict
  // every cycle" outside the range, done only when it can matter. Moving away (the mean tool
  // path points away from the closest point), the whole ball is used.
  const auto out_of_range = [&]() {
    const bool moving_away = mean_tool_path.dot(closest.point - anchor) < 0;
    const double reduced =
        moving_away ? full
                    : std::min(full, std::max(closest.distance_m - settings.straight_line_range_m, 0.5 * full));
    corridor.balls[0] = {anchor, reduced * reduced, safe * safe};
    return prediction;
  };

  const double length = mean_tool_path.norm();
  if (!(length >= settings.min_path_length_m) || !(length > 0)) return out_of_range();
  const Vector3d direction = mean_tool_path / length;
  prediction.has_direction = true;
  prediction.direction = direction;
  prediction.speed_m_per_s = mean_sample_age_s > 0 ? length / mean_sample_age_s : 0;

  // The paper's predicted point: the mean tool path ray-cast from the current position.
  if (ray_casts != nullptr) ++*ray_casts;
  const SurfaceHit hit = surface.first_hit_ray(anchor, direction, settings.ray_max_distance_m, counters);
  if (!hit.hit) return out_of_range();
  prediction.valid = true;
  prediction.point = hit.point;
  prediction.normal = hit.normal;
  prediction.path_distance_m = hit.distance_m;
  prediction.time_to_contact_s = prediction.speed_m_per_s > 0 ? hit.distance_m / prediction.speed_m_per_s
                                                              : std::numeric_limits<double>::infinity();
  if (hit.distance_m > settings.straight_line_range_m) return out_of_range();
  prediction.in_range = true;
  corridor.balls[0] = {anchor, full * full, safe * safe};

  // Within the straight-line range: certify balls along the straight path toward C. A cursor
  // steps a fraction of its own check radius each time (so it converges on a surface it
  // approaches head-on); a ball is kept only when it reaches further along the path than the
  // last kept one (head-on, every later ball lies inside the first).
  const int capacity = std::min(settings.corridor_balls, max_corridor_balls);
  double along = 0;
  double radius = full;
  double kept_front = full;
  for (int iteration = 0; iteration < 4 * max_corridor_balls && corridor.size < capacity; ++iteration) {
    along += settings.corridor_step_fraction * radius;
    if (along >= hit.distance_m) break;
    const Vector3d centre = anchor + along * direction;
    if (closest_point_queries != nullptr) ++*closest_point_queries;
    const double ball_safe = surface.closest_point(centre, counters).distance_m - settings.margin_m;
    const double ball_check = ball_safe - shrink_m;
    if (!(ball_check > settings.handover_distance_m)) break;
    radius = ball_check;
    if (along + ball_check > kept_front) {
      corridor.balls[corridor.size++] = {centre, ball_check * ball_check, ball_safe * ball_safe};
      kept_front = along + ball_check;
    }
  }
  return prediction;
}

// ---------------------------------------------------------------------------------------------
// The reference: full detection every cycle

bool FullDetectionReference::step(const Vector3d& tip_position, SurfaceHit* hit, QueryCounters* counters) noexcept {
  if (!tip_position.allFinite()) return false;
  bool began = false;
  if (!started_) {
    started_ = true;
    in_contact_ = surface_->contains(tip_position, counters);
    if (in_contact_ && hit != nullptr) {
      *hit = SurfaceHit{};
      hit->hit = true;
      hit->point = tip_position;
    }
    began = in_contact_;
  } else if (!in_contact_) {
    const SurfaceHit first = surface_->first_hit_segment(previous_, tip_position, counters);
    if (first.hit) {
      in_contact_ = true;
      began = true;
      if (hit != nullptr) *hit = first;
    }
  } else if (!surface_->contains(tip_position, counters)) {
    in_contact_ = false;
  }
  previous_ = tip_position;
  return began;
}

// ---------------------------------------------------------------------------------------------
// The predictor

CollisionPredictor::CollisionPredictor(const SurfaceQueries& surface, const PredictionSettings& settings)
    : surface_(surface),
      settings_(validated(settings)),
      shrink_m_(settings.detection_period_cycles > 1
                    ? settings.detection_period_cycles * settings.max_tip_speed_m_per_s * settings.cycle_period_s
                    : 0.0),
      cos_threshold_(std::cos(settings.direction_threshold_rad)),
      history_(settings.window_samples),
      reference_(surface) {}

void CollisionPredictor::reset() noexcept {
  history_.clear();
  newest_sample_cycle_ = -1;
  cycle_ = 0;
  detection_countdown_ = 0;
  sample_countdown_ = 0;
  direction_countdown_ = 0;
  phase_ = PredictorPhase::start;
  check_radius2_ = -1;
  ball_ = 0;
  corridor_.size = 0;
  prediction_ = CollisionPrediction{};
  contact_hit_ = SurfaceHit{};
  reference_.reset();
}

PredictionStep CollisionPredictor::step(const Vector3d& p) noexcept {
  PredictionStep out;
  if (!p.allFinite()) {
    ++counters_.invalid_inputs;
    out.status = PredictionStatus::invalid_input;
    return out;
  }
  ++counters_.cycles;
  // Countdowns instead of cycle % N: an integer division would cost more than the check.
  const bool detection_cycle = detection_countdown_ == 0;
  detection_countdown_ = detection_cycle ? settings_.detection_period_cycles - 1 : detection_countdown_ - 1;
  bool direction_cycle = false;
  if (settings_.direction_check_period_cycles > 0) {
    direction_cycle = direction_countdown_ == 0;
    direction_countdown_ = direction_cycle ? settings_.direction_check_period_cycles - 1 : direction_countdown_ - 1;
  }

  switch (phase_) {
    case PredictorPhase::corridor:
      // The per-cycle work of the paper: one distance, one comparison.
      ++counters_.cheap_distances;
      if ((p - check_centre_).squaredNorm() < check_radius2_) {
        out.status = PredictionStatus::free;
        // Optional: re-predict when the hand turned or retreats while still certified (the
        // period is a multiple of N, so this is a detection cycle).
        if (direction_cycle && !direction_still_valid(p)) out = predict_at(p, true, true);
        else ++counters_.cheap_checks;
      } else {
        out = on_corridor_exit(p, detection_cycle);
      }
      break;
    case PredictorPhase::deferred:
      // Between detection cycles: tested against the certified radius itself.
      ++counters_.cheap_distances;
      if ((p - check_centre_).squaredNorm() < check_radius2_) {
        if (!detection_cycle) {
          ++counters_.cheap_checks;
          out.status = PredictionStatus::deferred;
        } else {
          out = predict_at(p, true, true);
        }
      } else {
        ++counters_.forced_predictions;
        out = predict_at(p, false, true);
        out.forced = true;
      }
      break;
    case PredictorPhase::near_surface:
      out = on_near_surface(p, detection_cycle);
      break;
    case PredictorPhase::in_contact:
      out = on_in_contact(p);
      break;
    case PredictorPhase::start:
      out = on_start(p);
      break;
  }

  if (settings_.audit) audit(p, out);
  if (sample_countdown_ == 0) {
    history_.push(p);
    newest_sample_cycle_ = cycle_;
    sample_countdown_ = settings_.sample_period_cycles - 1;
  } else {
    --sample_countdown_;
  }
  previous_ = p;
  ++cycle_;
  return out;
}

PredictionStep CollisionPredictor::on_start(const Vector3d& p) noexcept {
  PredictionStep out;
  ++counters_.contact_checks;
  if (surface_.contains(p, &counters_.queries)) {
    SurfaceHit hit;
    hit.hit = true;
    hit.point = p;
    begin_contact(hit, out);
    return out;
  }
  return predict_at(p, true, false);
}

PredictionStep CollisionPredictor::on_corridor_exit(const Vector3d& p, bool detection_cycle) noexcept {
  PredictionStep out;
  // Into a later ball of the corridor (usually the next one). Both ends of this cycle's motion
  // must lie in it: a segment from one ball into another can leave their union (by up to its
  // length), a segment inside one ball cannot.
  const auto holds_step = [&](int i, double radius2) {
    counters_.cheap_distances += 2;
    const Vector3d& centre = corridor_.balls[i].centre;
    return (p - centre).squaredNorm() < radius2 && (previous_ - centre).squaredNorm() < radius2;
  };
  for (int i = ball_ + 1; i < corridor_.size; ++i) {
    if (holds_step(i, corridor_.balls[i].check_radius2_m2)) {
      enter_ball(i, false);
      ++counters_.corridor_advances;
      out.status = PredictionStatus::corridor_advance;
      return out;
    }
  }
  if (!detection_cycle) {
    // Still inside a certified radius: the prediction waits for the next detection cycle.
    for (int i = ball_; i < corridor_.size; ++i) {
      if (holds_step(i, corridor_.balls[i].safe_radius2_m2)) {
        enter_ball(i, true);
        phase_ = PredictorPhase::deferred;
        ++counters_.deferrals;
        out.status = PredictionStatus::deferral_start;
        return out;
      }
    }
    ++counters_.forced_predictions;
    out = predict_at(p, false, true);
    out.forced = true;
    return out;
  }
  return predict_at(p, false, true);
}

PredictionStep CollisionPredictor::on_near_surface(const Vector3d& p, bool detection_cycle) noexcept {
  PredictionStep out;
  ++counters_.full_detections;
  const SurfaceHit hit = surface_.first_hit_segment(previous_, p, &counters_.queries);
  if (hit.hit) {
    begin_contact(hit, out);
    return out;
  }
  const double exit = settings_.near_exit_distance_m;
  if (detection_cycle && (p - near_anchor_).squaredNorm() > exit * exit) {
    out = predict_at(p, true, false);
    if (phase_ == PredictorPhase::near_surface) out.status = PredictionStatus::full_detection;
    return out;
  }
  out.status = PredictionStatus::full_detection;
  return out;
}

PredictionStep CollisionPredictor::on_in_contact(const Vector3d& p) noexcept {
  PredictionStep out;
  ++counters_.contact_checks;
  if (surface_.contains(p, &counters_.queries)) {
    out.status = PredictionStatus::in_contact;
    return out;
  }
  // Out again, just outside the surface: full detection until the tip moves away.
  ++counters_.releases;
  phase_ = PredictorPhase::near_surface;
  near_anchor_ = p;
  out.status = PredictionStatus::released;
  return out;
}

PredictionStep CollisionPredictor::predict_at(const Vector3d& p, bool step_certified, bool had_prediction) noexcept {
  PredictionStep out;
  const Vector3d mean_path = history_.mean_tool_path(p);
  const RepredictionCause cause = had_prediction ? classify(p, mean_path) : RepredictionCause::none;

  ++counters_.closest_point_queries;
  const ClosestSurfacePoint closest = surface_.closest_point(p, &counters_.queries);
  if (!step_certified) {
    // The tip left every certified ball, so this cycle's motion may have crossed the surface:
    // the new ball clears it when both ends lie inside, otherwise full detection decides.
    if ((p - previous_).norm() < closest.distance_m - settings_.margin_m) {
      ++counters_.certified_steps;
    } else {
      ++counters_.full_detections;
      const SurfaceHit hit = surface_.first_hit_segment(previous_, p, &counters_.queries);
      if (hit.hit) {
        begin_contact(hit, out);
        return out;
      }
    }
  }

  prediction_ = predict_collision(surface_, settings_, p, closest, mean_path, mean_sample_age_s(), shrink_m_,
                                  corridor_, &counters_.queries, &counters_.closest_point_queries,
                                  &counters_.ray_casts);
  prediction_.cycle = cycle_;
  if (prediction_.near_surface) {
    if (phase_ != PredictorPhase::near_surface) ++counters_.handovers;
    phase_ = PredictorPhase::near_surface;
    near_anchor_ = p;
    out.status = PredictionStatus::handover;
    return out;
  }
  phase_ = PredictorPhase::corridor;
  enter_ball(0, false);
  switch (cause) {
    case RepredictionCause::none:
      ++counters_.predictions;
      out.status = PredictionStatus::predicted;
      return out;
    case RepredictionCause::direction_change: ++counters_.repredictions_direction; break;
    case RepredictionCause::retreat: ++counters_.repredictions_retreat; break;
    case RepredictionCause::out_of_range: ++counters_.repredictions_range; break;
    case RepredictionCause::ball_exit: ++counters_.repredictions_ball_exit; break;
  }
  out.status = PredictionStatus::repredicted;
  out.cause = cause;
  return out;
}

RepredictionCause CollisionPredictor::classify(const Vector3d& p, const Vector3d& mean_path) const noexcept {
  const CollisionPrediction& old = prediction_;
  const double length = mean_path.norm();
  if (old.has_direction && length >= settings_.min_path_length_m && length > 0) {
    // Moving away from the predicted point, or turned beyond the threshold.
    const double cosine = mean_path.dot(old.direction) / length;
    if (cosine <= 0) return RepredictionCause::retreat;
    if (cosine < cos_threshold_) return RepredictionCause::direction_change;
  }
  if (!old.in_range || (p - old.point).norm() > settings_.straight_line_range_m)
    return RepredictionCause::out_of_range;
  return RepredictionCause::ball_exit;
}

bool CollisionPredictor::direction_still_valid(const Vector3d& p) noexcept {
  ++counters_.direction_checks;
  const Vector3d mean_path = history_.mean_tool_path(p);
  const double length = mean_path.norm();
  if (!(length >= settings_.min_path_length_m) || !(length > 0)) return true;  // resting: keep
  if (!prediction_.has_direction) return false;                               // moving now
  return mean_path.dot(prediction_.direction) >= cos_threshold_ * length;
}

void CollisionPredictor::begin_contact(const SurfaceHit& hit, PredictionStep& out) noexcept {
  phase_ = PredictorPhase::in_contact;
  contact_hit_ = hit;
  ++counters_.contacts;
  out.status = PredictionStatus::contact;
  out.cause = RepredictionCause::none;
  out.hit = hit;
}

void CollisionPredictor::enter_ball(int index, bool safe_radius) noexcept {
  ball_ = index;
  check_centre_ = corridor_.balls[index].centre;
  check_radius2_ = safe_radius ? corridor_.balls[index].safe_radius2_m2 : corridor_.balls[index].check_radius2_m2;
}

double CollisionPredictor::mean_sample_age_s() const noexcept {
  const int n = history_.size();
  if (n == 0) return 0;
  // Sample i (1 = newest) is (cycle − newest) + (i − 1)·period cycles old.
  const double newest_age = static_cast<double>(cycle_ - newest_sample_cycle_);
  const double mean_age = newest_age + 0.5 * (n - 1) * settings_.sample_period_cycles;
  return mean_age * settings_.cycle_period_s;
}

void CollisionPredictor::audit(const Vector3d& p, const PredictionStep& out) noexcept {
  const bool began = reference_.step(p, nullptr, &counters_.audit_queries);
  const bool reported = out.status == PredictionStatus::contact;
  if (began) {
    ++counters_.audited_contacts;
    if (!reported) {
      switch (out.status) {
        case PredictionStatus::free:
        case PredictionStatus::corridor_advance: ++counters_.misses_cheap_check; break;
        case PredictionStatus::deferral_start:
        case PredictionStatus::deferred: ++counters_.misses_deferred; break;
        default: ++counters_.misses_other; break;
      }
    }
  } else if (reported) {
    ++counters_.spurious_contacts;
  }
}

}  // namespace touchstone::realtime::collision
