#pragma once
/// @file
/// Collision prediction (paper §3.1–3.2), made safe.
///
/// The paper: keep the last m tool-tip positions, low-pass the tool path vector (eq. 1) into the
/// mean tool path (eq. 2), ray-cast it to a predicted collision point, and — within a straight-line
/// range of 5–10 mm — spend only one distance computation and one comparison per cycle until the
/// tool reaches that point. Taken literally this can miss a contact: the hand may turn, and a
/// non-convex organ may be hit beside the predicted point.
///
/// What makes it safe here is a certificate, not the prediction. With D the unsigned distance
/// from a point A to the surface, the open ball B(A, D) contains no surface point; a segment
/// whose two ends lie in a ball lies in it (balls are convex). So while every tip position since
/// A stays in B(A, D − margin), no motion segment of the tip can have touched the surface — for
/// any path shape, tremor or change of direction. The per-cycle test is one squared distance and
/// one comparison, |P − A|² < (D − margin)², with no surface query.
///
/// The paper's predicted point C (the first hit of the ray from A along the mean tool path)
/// decides how far ahead the certificate reaches. Outside the straight-line range the ball is
/// only tested to D − range (at least half its radius), so the tip predicts again when it may
/// have come within the range — the paper's per-cycle prediction outside the range, done only
/// when it can change something. Within the range, head-on (mean path along the surface normal)
/// |C − A| = D and the single ball already covers the straight path up to the margin before C.
/// Obliquely |C − A| > D, and the ball alone would be left long before C; so at prediction time
/// a corridor of certified balls is built along the straight path toward C (a few closest-point
/// queries, while there is time to spare before contact). In the haptic cycle the tip is tested
/// against the current ball only. Passing into the next ball costs two more distances: that
/// ball must hold both ends of the cycle's motion, because a segment from one ball into another
/// can leave their union (the surface is ≥ margin outside each ball, so only steps longer than
/// the margin could touch it there — 0.1 m/s at 1 kHz — but the certificate must not depend on
/// speed). The
/// corridor ends where its balls would be thinner than `handover_distance_m`, i.e. where the
/// predicted point is nearly reached; leaving it there hands over to full detection (the tip's
/// motion segment against the surface, every cycle) until contact or until the tip moves away.
/// Leaving the corridor anywhere else triggers a re-prediction, whose cause is classified from
/// the mean tool path: retreat, change of direction, out of the straight-line range, or a plain
/// exit (lateral drift). The prediction also gives the expected time of contact, |C − A| over
/// the approach speed estimated from the mean tool path.
///
/// Reduced-rate prediction (the paper's "another advantage"): with `detection_period_cycles`
/// N > 1 the queries of prediction (closest point, ray, corridor) run only on every N-th cycle,
/// as if in a slower thread. Each ball then has a check radius shrunk by N·s_max, where
/// s_max = max_tip_speed × cycle_period bounds the tip's travel per cycle: a tip that leaves the
/// check radius between detection cycles is, under the speed bound, still inside the certified
/// radius at the next detection cycle, so the re-prediction waits for it (status
/// `deferral_start`, then `deferred`).
/// Safety never rests on the speed bound: while deferred the tip is tested against the
/// certified radius itself, and if it leaves that too (the bound was violated) a prediction is
/// forced at once and counted. Full detection near the surface and contact tracking always run
/// every cycle. What it buys: every prediction query lands on a detection cycle (schedulable
/// off the haptic thread). What it costs: a near zone wider by N·s_max, so the full-detection
/// cycles per approach grow with N while the prediction queries stay about the same (see the
/// reduced-rate sweep of test_collision_prediction) — with a certified corridor the haptic-rate
/// cost is already low, so N > 1 is worth it only when prediction must leave the haptic thread.
///
/// test_collision_prediction holds it to full detection on every cycle (brute-force queries,
/// tremor approaches on an icosphere and on fused spheres with dimples): no contact may be
/// missed and none reported that full detection does not report. How many cycles are one
/// distance + one comparison, and what an approach costs in queries against full detection
/// every cycle, is in the top-level README (Measured: collision detection and prediction).
///
/// Contact is defined as full detection every cycle would report it (`FullDetectionReference`):
/// outside the surface, contact begins in the cycle whose motion segment P_prev → P first hits
/// the surface; in contact, it ends in the first cycle where the tip is no longer inside.

#include "touchstone/realtime/collision/surface_queries.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>

namespace touchstone::realtime::collision {

/// Largest window m the tool-path history can hold (storage is fixed: no cycle allocates).
inline constexpr int max_window_samples = 256;
/// Largest number of certified balls in a corridor.
inline constexpr int max_corridor_balls = 16;

/// Tool path vector (eq. 1): P_current − P_previous [m].
inline Eigen::Vector3d tool_path_vector(const Eigen::Vector3d& current,
                                        const Eigen::Vector3d& previous) noexcept {
  return current - previous;
}

/// The last m sampled tool-tip positions in a fixed-capacity ring buffer.
class ToolPathHistory {
 public:
  /// `window_samples` is m, clamped to [1, max_window_samples].
  explicit ToolPathHistory(int window_samples = 10) noexcept;

  /// Adds the newest position; once m are held the oldest is dropped.
  void push(const Eigen::Vector3d& position) noexcept;
  void clear() noexcept;

  int window() const noexcept { return window_; }
  /// Positions held: min(pushes since clear, m).
  int size() const noexcept { return size_; }
  /// P_i of eq. 2: i = 1 is the newest position held, i = size() the oldest. Precondition
  /// 1 ≤ i ≤ size().
  const Eigen::Vector3d& previous(int i) const noexcept;

  /// Mean tool path (eq. 2), P̄ = (1/m) Σ_{i=1..m} (P_current − P_i) [m], over the size()
  /// positions held (m once full). A moving average of the tool path vectors: for motion at
  /// constant velocity v sampled every Δt, P̄ = v Δt (m + 1)/2 when the newest sample is one Δt
  /// old. Zero when empty.
  Eigen::Vector3d mean_tool_path(const Eigen::Vector3d& current) const noexcept;

 private:
  std::array<Eigen::Vector3d, max_window_samples> positions_{};
  int window_ = 10;
  int next_ = 0;  ///< index the next push writes
  int size_ = 0;
};

/// Settings of the predictor (SI units). Plain values with defaults; validate() names the field.
struct PredictionSettings {
  /// m of eq. 2: previous positions averaged into the mean tool path.
  int window_samples = 30;
  /// The history takes a sample every this many haptic cycles (10 at 1 kHz: the paper's lower
  /// system rate, 100 Hz). The window m × period must span a tremor period or more: m = 10 at
  /// 1 kHz (10 ms) predicts no better than eq. 1, while 30 samples at 100 Hz (300 ms) bring the
  /// predicted-point error to about the paper's 1 mm (test_tremor_model asserts both).
  int sample_period_cycles = 10;
  /// Within this distance of the predicted point motion is taken as straight and the corridor
  /// is built (paper: 5–10 mm). Farther out only the ball around the tip is certified.
  double straight_line_range_m = 0.0075;
  /// A re-prediction is classified as a change of direction when the mean tool path turned by
  /// more than this from the predicted direction (and, with direction checks, triggers one).
  double direction_threshold_rad = 0.35;
  /// Subtracted from every certified radius: covers the query's rounding and a tool tip of
  /// finite size (set it ≥ the tip radius for a spherical tip).
  double margin_m = 1e-4;
  /// The corridor ends where a ball's check radius would fall below this; within it of the
  /// surface full detection runs every cycle (the hand-over near the predicted point).
  /// 0.25 mm costs fewer queries per approach than 1 mm: fewer full-detection cycles for a few
  /// more predictions.
  double handover_distance_m = 2.5e-4;
  /// Full detection hands back to prediction once the tip is this far from where it began.
  double near_exit_distance_m = 1e-3;
  /// Corridor ball k + 1 is centred this fraction of ball k's check radius further along the
  /// straight path (in (0, 1]: consecutive balls overlap).
  double corridor_step_fraction = 0.75;
  /// Balls per corridor (≤ max_corridor_balls).
  int corridor_balls = max_corridor_balls;
  /// Longest ray cast for the predicted point [m].
  double ray_max_distance_m = 0.5;
  /// Mean tool paths shorter than this give no direction (a resting tool) [m].
  double min_path_length_m = 1e-6;
  /// Queries of prediction run on every N-th cycle only (1: every cycle).
  int detection_period_cycles = 1;
  /// Speed bound behind the reduced rate (N > 1): check radii shrink by N × this × cycle
  /// period. Violations are detected and force a prediction; they never cause a miss.
  double max_tip_speed_m_per_s = 0.25;
  /// Haptic cycle period [s].
  double cycle_period_s = 1e-3;
  /// When > 0, every this many cycles (a multiple of detection_period_cycles) the mean tool
  /// path is compared with the predicted direction, and a turn beyond the threshold or a
  /// retreat re-predicts at once. 0 (the paper's straight-line assumption): only when the tip
  /// leaves the corridor.
  int direction_check_period_cycles = 0;
  /// Also run `FullDetectionReference` every cycle and count misses (studies and tests; its
  /// queries are not counted as the predictor's work).
  bool audit = false;

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// A ball that contains no surface point: the tip is tested against `check_radius2_m2`;
/// `safe_radius2_m2` ≥ it is the certified (D − margin)².
struct CertifiedBall {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< [m]
  double check_radius2_m2 = 0;
  double safe_radius2_m2 = 0;
};

/// The certified corridor along the predicted straight path; ball 0 is centred on the anchor.
struct Corridor {
  std::array<CertifiedBall, max_corridor_balls> balls{};
  int size = 0;
};

/// One prediction, made at `anchor`.
struct CollisionPrediction {
  Eigen::Vector3d anchor = Eigen::Vector3d::Zero();     ///< tip position when made [m]
  double anchor_distance_m = 0;                         ///< D, unsigned distance anchor–surface
  Eigen::Vector3d closest_point = Eigen::Vector3d::Zero();
  /// Within handover_distance_m (+ margin and the reduced-rate shrink) of the surface: no
  /// corridor, full detection instead.
  bool near_surface = false;
  bool has_direction = false;                           ///< |P̄| ≥ min_path_length_m
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  ///< unit mean tool path
  double speed_m_per_s = 0;                             ///< |P̄| / mean sample age
  bool valid = false;                                   ///< the ray hit: a predicted point
  bool in_range = false;                                ///< and within straight_line_range_m
  Eigen::Vector3d point = Eigen::Vector3d::Zero();      ///< predicted collision point C [m]
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();     ///< outward face normal at C
  double path_distance_m = 0;                           ///< |C − anchor|
  double time_to_contact_s = 0;                         ///< path_distance / speed (∞ at rest)
  long long cycle = -1;                                 ///< cycle index when made
};

/// A prediction from `anchor` (paper §3.1): given the closest point there and the mean tool
/// path, ray-casts the predicted point and, within the straight-line range, fills `corridor`.
/// `shrink_m` is the reduced-rate shrink N·s_max (0 at N = 1); `mean_sample_age_s` converts
/// |P̄| to a speed. Queries are counted in `counters` (may be null); `closest_point_queries` and
/// `ray_casts` (may be null) count the calls. Allocation-free.
CollisionPrediction predict_collision(const SurfaceQueries& surface, const PredictionSettings& settings,
                                      const Eigen::Vector3d& anchor, const ClosestSurfacePoint& closest,
                                      const Eigen::Vector3d& mean_tool_path, double mean_sample_age_s,
                                      double shrink_m, Corridor& corridor, QueryCounters* counters,
                                      long long* closest_point_queries, long long* ray_casts) noexcept;

/// Contact as full detection every cycle reports it — the definition the predictor must match
/// (and the oracle of its audit). Outside: contact begins when the motion segment hits the
/// surface (or the first position is inside); in contact: ends when the tip is not inside.
class FullDetectionReference {
 public:
  explicit FullDetectionReference(const SurfaceQueries& surface) noexcept : surface_(&surface) {}
  /// Returns true when contact begins in this cycle; `hit` gets the segment's first hit.
  bool step(const Eigen::Vector3d& tip_position, SurfaceHit* hit = nullptr,
            QueryCounters* counters = nullptr) noexcept;
  bool in_contact() const noexcept { return in_contact_; }
  void reset() noexcept { started_ = false; in_contact_ = false; }

 private:
  const SurfaceQueries* surface_;
  Eigen::Vector3d previous_ = Eigen::Vector3d::Zero();
  bool started_ = false;
  bool in_contact_ = false;
};

/// What one haptic cycle did.
enum class PredictionStatus : std::uint8_t {
  free,              ///< inside the certified ball: one distance + one comparison, no query
  corridor_advance,  ///< left one corridor ball for a later one holding the whole step (two
                     ///< more distances per ball tried, no query)
  deferral_start,    ///< left a check radius between detection cycles but is still certified:
                     ///< the re-prediction waits for the next detection cycle (no query)
  deferred,          ///< waiting for it: one distance + one comparison against the certified
                     ///< radius, no query
  predicted,         ///< a prediction where none was valid (start, after full detection)
  repredicted,       ///< left the corridor: a new prediction (see the cause)
  handover,          ///< nearly at the surface: full detection from the next cycle
  full_detection,    ///< full detection ran (motion segment against the surface), no contact
  contact,           ///< contact began this cycle (`hit` is the first hit)
  in_contact,        ///< still inside the surface
  released,          ///< contact ended this cycle
  invalid_input,     ///< non-finite tip position: ignored, nothing changed
};

/// Why a re-prediction was made (classified against the previous prediction).
enum class RepredictionCause : std::uint8_t {
  none,              ///< not a re-prediction
  direction_change,  ///< the mean tool path turned beyond direction_threshold_rad
  retreat,           ///< the tool moves away (mean tool path against the predicted direction)
  out_of_range,      ///< the last prediction had no point within the straight-line range (the
                     ///< tip approached it), or the tip left that range
  ball_exit,         ///< left the certified corridor otherwise (drift, tremor, a near surface)
};

/// The result of one cycle.
struct PredictionStep {
  PredictionStatus status = PredictionStatus::free;
  RepredictionCause cause = RepredictionCause::none;
  /// This cycle's prediction ran off-schedule: the tip left the certified radius between
  /// detection cycles (the speed bound was violated).
  bool forced = false;
  SurfaceHit hit;  ///< valid when status == contact
};

/// Where the predictor is.
enum class PredictorPhase : std::uint8_t { start, corridor, deferred, near_surface, in_contact };

/// Work and events, accumulated since construction or reset_counters().
struct PredictionCounters {
  long long cycles = 0;
  long long invalid_inputs = 0;
  long long cheap_checks = 0;       ///< cycles decided by one distance + one comparison (free, deferred)
  long long cheap_distances = 0;    ///< squared distances to ball centres (in cheap and exit paths)
  long long corridor_advances = 0;
  long long predictions = 0;        ///< predictions with no valid one before
  long long repredictions_direction = 0;
  long long repredictions_retreat = 0;
  long long repredictions_range = 0;
  long long repredictions_ball_exit = 0;
  long long direction_checks = 0;
  long long handovers = 0;          ///< entries into full detection from a prediction
  long long deferrals = 0;
  long long forced_predictions = 0; ///< speed bound violated while deferred
  long long full_detections = 0;    ///< first_hit_segment calls
  long long certified_steps = 0;    ///< motion segments cleared by the new ball instead of a query
  long long contact_checks = 0;     ///< contains() calls while in contact
  long long closest_point_queries = 0;
  long long ray_casts = 0;
  long long contacts = 0;
  long long releases = 0;
  QueryCounters queries;            ///< box and triangle tests of the predictor's own queries
  // Audit (settings.audit): full detection every cycle as the reference.
  long long audited_contacts = 0;   ///< contacts the reference reported
  long long misses_cheap_check = 0; ///< the reference saw contact begin in a free/advance cycle
  long long misses_deferred = 0;    ///< … in a deferral_start or deferred cycle
  long long misses_other = 0;       ///< … in any other cycle without a contact status
  long long spurious_contacts = 0;  ///< contact reported, reference did not
  QueryCounters audit_queries;

  long long repredictions() const noexcept {
    return repredictions_direction + repredictions_retreat + repredictions_range + repredictions_ball_exit;
  }
  long long misses() const noexcept { return misses_cheap_check + misses_deferred + misses_other; }
};

/// The predictor for one tool tip against one surface. The surface and the settings are
/// immutable after construction; the history, phase, prediction, corridor and counters are
/// the evolving state. Single-threaded; `surface` must outlive the predictor.
class CollisionPredictor {
 public:
  /// Validates the settings (throws std::invalid_argument naming the field).
  CollisionPredictor(const SurfaceQueries& surface, const PredictionSettings& settings);

  /// One haptic cycle with the tip's position [m]. Allocation-free.
  PredictionStep step(const Eigen::Vector3d& tip_position) noexcept;

  /// Back to the start (history, phase, prediction cleared; counters kept).
  void reset() noexcept;
  void reset_counters() noexcept { counters_ = PredictionCounters{}; }

  const PredictionSettings& settings() const noexcept { return settings_; }
  const PredictionCounters& counters() const noexcept { return counters_; }
  const CollisionPrediction& prediction() const noexcept { return prediction_; }
  const Corridor& corridor() const noexcept { return corridor_; }
  const ToolPathHistory& history() const noexcept { return history_; }
  PredictorPhase phase() const noexcept { return phase_; }
  /// Cycles stepped since construction or reset() (the index of the next cycle).
  long long cycle() const noexcept { return cycle_; }
  /// The first hit of the contact in progress (or the last one).
  const SurfaceHit& contact_hit() const noexcept { return contact_hit_; }

 private:
  PredictionStep on_start(const Eigen::Vector3d& p) noexcept;
  PredictionStep on_corridor_exit(const Eigen::Vector3d& p, bool detection_cycle) noexcept;
  PredictionStep on_near_surface(const Eigen::Vector3d& p, bool detection_cycle) noexcept;
  PredictionStep on_in_contact(const Eigen::Vector3d& p) noexcept;
  /// New prediction at p. `step_certified`: the motion segment previous_ → p is known to be
  /// free of the surface (both ends in a certified ball, or already tested).
  PredictionStep predict_at(const Eigen::Vector3d& p, bool step_certified, bool had_prediction) noexcept;
  RepredictionCause classify(const Eigen::Vector3d& p, const Eigen::Vector3d& mean_path) const noexcept;
  bool direction_still_valid(const Eigen::Vector3d& p) noexcept;
  void begin_contact(const SurfaceHit& hit, PredictionStep& out) noexcept;
  void enter_ball(int index, bool safe_radius) noexcept;
  double mean_sample_age_s() const noexcept;
  void audit(const Eigen::Vector3d& p, const PredictionStep& out) noexcept;

  const SurfaceQueries& surface_;
  const PredictionSettings settings_;
  const double shrink_m_;  ///< N·s_max for N > 1, else 0
  const double cos_threshold_;

  ToolPathHistory history_;
  long long newest_sample_cycle_ = -1;
  long long cycle_ = 0;
  // Countdowns to the next detection cycle, history sample and direction check (0: this one).
  int detection_countdown_ = 0;
  int sample_countdown_ = 0;
  int direction_countdown_ = 0;
  PredictorPhase phase_ = PredictorPhase::start;
  Eigen::Vector3d previous_ = Eigen::Vector3d::Zero();
  // The hot path's data: the ball the tip is tested against.
  Eigen::Vector3d check_centre_ = Eigen::Vector3d::Zero();
  double check_radius2_ = -1;
  int ball_ = 0;
  Corridor corridor_;
  CollisionPrediction prediction_;
  Eigen::Vector3d near_anchor_ = Eigen::Vector3d::Zero();
  SurfaceHit contact_hit_;
  PredictionCounters counters_;
  FullDetectionReference reference_;
};

}  // namespace touchstone::realtime::collision
