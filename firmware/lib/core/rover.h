// The rover's autonomy, hardware-free: one step function from Inputs to Outputs, one mode
// (RoverState), its work split by concern into a file each (see rover.cpp's head).
//
// It holds the waypoint list the host sent, rotates towards the next waypoint with the gyro
// PID, drives holding the heading inside the tolerance cone atan(cone_tol_mm / L), sweeps the
// sonar every sweep_interval_mm and reports close echoes, estimates its pose from the gyro,
// the wheels (or a speed model) and the camera fixes, carries on by dead reckoning when fixes
// or the whole radio stop, holds still when its position gets too uncertain, and stops on a
// silent or implausible gyro. No heap, no STL, no exceptions, no waiting: time is an input.
#pragma once
#include <stdint.h>

#include "body.h"

#include "detour_state.h"
#include "failsafe_state.h"
#include "frame.h"
#include "io.h"
#include "link_state.h"
#include "messages_gen.h"
#include "mission_state.h"
#include "motion_state.h"
#include "odometry_state.h"
#include "params.h"
#include "sonar_state.h"
#include "step_state.h"

namespace rovernav {
namespace core {

/// The sonar's result as a step's modes see it (one put off from the step before, or none).
struct SonarIn {
  bool valid;
  uint16_t range_mm;   ///< 0 = no echo
};

/// Bearing from a to b (radians, clockwise from +y).
float bearing_rad(Point a, Point b);

/// The Rover's working state: all of it but its parameters and its frame decoder, one aggregate
/// per concern, each written by its own file (see each header; where another file writes a
/// member, the header says which and why). RoverFields is an aggregate, and a base of the
/// Rover's, set as one block (`RoverFields{}`). Every field starts at zero (what is not zero at
/// the start, begin() sets), so that the Uno's global Rover is constant-initialised into .bss: no
/// start-up code at all, where setting it field by field took four bytes of flash for every byte
/// of state. Flags are one-bit fields without initialisers (value-initialisation clears them): a
/// byte each would cost the Uno's static RAM. An aggregate's flags share a byte, and some of its
/// bools joined them (StepState's booted and have_time, MissionState's active, LinkState's
/// schema_ok, FailsafeState's radio_lost): with a byte of flags per aggregate, that keeps the
/// static RAM no higher than the one shared block of flags there was; which bools, was chosen by
/// what each cost in flash. (AVR has no alignment: the aggregates add no padding.)
struct RoverFields {
  StepState step_;           // rover.cpp: the mode, the step's clock and its heavy jobs
  LinkState link_;           // link_in.cpp, link_out.cpp: frames, HELLO, a path arriving, signatures
  MissionState mission_;     // link_in.cpp: the host's path; the modes move along it
  FailsafeState failsafe_;   // failsafe.cpp: the gyro's, the radio's and the camera's watchdogs, faults
  OdometryState odometry_;   // odometry.cpp: the estimate, dead reckoning, the speed model
  MotionState motion_;       // mode_rotate.cpp, mode_drive.cpp: the heading PID, the commands, backing out
  SonarState sonar_;         // mode_scan.cpp, reflex.cpp: the sweep, the servo, the reflex
  DetourState detour_;       // detour.cpp: Blocked, Planning, the rover's own way round
};

/// What the shell keeps for the link in EEPROM and gives the rover at begin() (Uno: lib/hal/link_store).
struct LinkSecrets {
  bool has_key;
  uint8_t key[kSipKeyBytes];
  Counter48 tx_counter;   ///< the counters as last stored (0, 0 if never); rx_counter follows
  Counter48 rx_counter;   ///< tx_counter (link_store reads both at once)
  uint8_t fleet_id;       ///< 0: a lone rover; 1..kMaxRovers: rover k of a fleet ([fleet]), stored with the key
};

class Rover : private RoverFields {
 public:
  enum : uint16_t {
    kFirmwareVersion = 0x0100,  // 1.0
    kLinkDelayMs = 5,           // assumed radio and serial delay of a FIX, on top of its age_ms
    kGrowMarginMm = 10,         // the distance to the waypoint may grow this much before we turn
    kGyroRecoverMs = 500,       // a faulted gyro must be good this long before the fault clears
    kCalibrateAfterMs = 300,    // speed-model calibration starts this long into a straight drive
    kCalibrateMinMm = 100,      // and needs this much model distance between two fixes
    kBlockedWaitMs = 3000,      // blocked with no way round: how long to wait for the host's path
    kUnheardWaitMs = 1500,      // blocked, and the host has not said it heard the sweep: how long before sweeping again
    kSayTimes = 3,              // each echo and SCAN_DONE is said this many times (a lossy radio)
    kReflexLatencyMs = 150,     // ping result one step late, motor lag and coasting, in the stopping distance
    kReflexLooks = 6,           // the directions the reflex's pings cycle through
    kTurnLookAfterMm = 100,     // a sharp turn is preceded by a sweep unless one was this recent,
    kTurnLookCoverDeg = 45,     // ... and looked from within this of the heading the rover has now
    // The rover's corners swing within 129 mm of its centre (its half-diagonal). The sweep sees
    // from the sonar, 100 mm ahead of the centre: a face seen abeam of it may run back alongside
    // the rover, into that swing. An echo within kSwingMm of the centre (less its arc) counts as
    // within reach: one abeam of the sonar up to 150 mm off its axis (sqrt(100^2 + 150^2) - arc).
    kSwingMm = 175,
    kBackOffMaxMm = kBackOffMm,  // backing out stops after this much, cleared or not (protocol/vehicle.toml)
    kBackOffMinTurnDeg = 20,    // smaller turns than this barely swing the corners
    kBackOffTrackDeg = 15,      // backing out turns back onto the track first when this far off it
    kTrackAfterMs = 400,        // the heading is the track once the rover has driven this long
    // The body's memory (LocalPlanner::keep_near): a sweep keeps the echoes beside the front of
    // the body (between the centre and the sensor) within kKeepNearMm of the centre (the reach of
    // room_to_turn's checks, kSwingMm and beside(), with their arcs); a reflex ping's echo within
    // kRememberPingMm of the sensor is remembered too.
    kKeepNearMm = 350,
    // A kept echo (behind the sensor: no longer a face seen abeam that may run on alongside the
    // body) is within the corners' reach when its point is nearer than this to the centre: the
    // half-diagonal (body.h: 129 mm for the seed's body), and 11 mm for the turn's wobble. Its
    // arc is not added: with it, an echo seen 0.3 m off (an arc of 40 mm) stopped turns with
    // room to spare, and the back-offs that followed led 2 of 9 arenas tried into what the
    // rover had passed (seed 1: 22, 30).
    kCornerReachMm = kBodyHalfDiagonalMm + 11,
    kRememberPingMm = 400,
    // A turn on the spot of more than kTurnLookDeg ends with a look (the reflex's pings on the
    // side turned to, then ahead) before the drive: the sweep before it looked from the old
    // heading, and the ground beside the sensor's new place, where a wall's end may stand
    // inside the body's way, no beam of it covered (seed 1's arena 157).
    kTurnLookDeg = 45,
  };
  // The corners' reach holds the body (protocol/vehicle.toml): its half-diagonal.
  static_assert(4L * kCornerReachMm * kCornerReachMm >=
                    static_cast<int32_t>(kBodyLengthMm) * kBodyLengthMm + static_cast<int32_t>(kBodyWidthMm) * kBodyWidthMm,
                "kCornerReachMm is less than the body's half-diagonal");
  static constexpr float kPoseMaxErrorDeg = 60.0f;  // pose law: beyond this, turn on the spot first
  static constexpr float kPoseMinAbovePwm = 8.0f;   // pose law: the least drive above the dead band

  constexpr Rover() : RoverFields{} {}
  /// boot_id must change at every reset; reset_cause goes out in the boot EVENT: the reset's
  /// flags, and kSignConsentResetBit when the shell found the consent pin held to GND at start-up
  /// (a keyed rover then takes an unsigned PROVISION; see on_provision). secrets: the stored link
  /// key and counters and the fleet id (nullptr: no key, the link unsigned, a lone rover).
  void begin(uint32_t boot_id, uint16_t reset_cause, const LinkSecrets* secrets = nullptr);
  void step(const Inputs& in, Outputs& out);

  // What the shell stores for the link (EEPROM on the Uno). Each returns true once per change.
  /// The counters to store now (with a key): at the first step, and when either has passed a
  /// multiple of kSignPersistStep since it was last stored.
  bool persist_due(Counter48& tx_counter, Counter48& rx_counter);
  enum : uint8_t { kKeyStore = 1, kKeyErase = 2 };
  /// A PROVISION was taken: kKeyStore (store link_key()) or kKeyErase; 0 if none.
  uint8_t take_key_change();
  const uint8_t* link_key() const { return link_.auth.key(); }
  /// The fleet id to store with the key (PROVISION's, or begin()'s): 0 a lone rover, k rover k of a fleet.
  uint8_t fleet_id() const { return link_.fleet_id(); }
  bool signing() const { return link_.auth.keyed(); }
  const AuthCounters& auth_counters() const { return link_.auth.counters(); }

  // Read-only views for tests, the simulator and the shell.
  RoverState state() const { return step_.state; }
  /// The heavy jobs the last step did: kWorkFix (a FIX taken in), kWorkPlanned (the detour
  /// planner ran), kWorkOther (a sonar result taken in, a sweep ended, a waypoint chosen afresh);
  /// kWorkReserved: the step was kept for a job the one before put off (it took no FIX). A step
  /// does one heavy job and puts the others off (see step()).
  /// kWorkTag: a received frame's tag was computed (at most one a step; in none kept for a put-off job).
  enum : uint8_t { kWorkFix = 1u << 0, kWorkPlanned = 1u << 1, kWorkOther = 1u << 2, kWorkReserved = 1u << 3,
                   kWorkTag = 1u << 4 };
  enum : uint8_t { kWorkHeavy = kWorkFix | kWorkPlanned | kWorkOther | kWorkTag };
  static_assert(static_cast<int>(kWorkReserved) == static_cast<int>(StepState::kReserved), "StepState::spend_reserve() clears kWorkReserved");
  uint8_t step_work() const { return step_.work; }
  uint16_t flags() const;
  FaultCode fault() const { return failsafe_.fault; }
  const Estimator& estimator() const { return odometry_.est; }
  const Params& params() const { return params_; }
  uint8_t waypoint_index() const { return mission_.wp; }
  uint8_t waypoint_count() const { return mission_.path_len; }
  Waypoint waypoint(uint8_t i) const { return mission_.path[i]; }
  const FrameCounters& rx_counters() const { return decoder_.counters(); }
  uint16_t tx_dropped() const { return link_.tx.dropped(); }
  float speed_scale() const { return odometry_.speed_scale; }
  uint8_t detour_left() const { return static_cast<uint8_t>(detour_.n - detour_.i); }
  bool blocked() const { return step_.state == RoverState::Blocked; }
  bool planning_detour() const { return step_.state == RoverState::Planning; }
  float dr_distance_mm() const { return odometry_.dr_distance_mm; }
  /// The speed the rover cruises at (mm/s), from its drive command and speed model.
  float drive_speed_mm_s() const;
  /// The speed model: mm/s per PWM above the dead band, as calibrated.
  float mm_s_per_pwm() const;
  /// The forward reflex's range from the sensor: stopping distance at cruise speed plus the margin.
  float reflex_range_mm() const;

 private:
  // rover.cpp: the step, the mode, helpers of every mode
  void run_state(const SonarIn& in, float dt_s, uint32_t now, Outputs& out);
  void enter(RoverState s);
  Point here_mm() const;
  Waypoint target() const;  ///< the detour point being approached, else mission_.path[mission_.wp]
  /// The distance to w (mm) and, when err_deg is given, the heading error towards it (degrees).
  float aim(Waypoint w, float* err_deg = nullptr) const;
  float cone_deg(float distance_mm) const;
  uint8_t closest_target() const;
  float heading_command(float error_deg, float dt_s);  // the heading PID's output (PWM)
  void set_wheels(float base, float u, bool biased, Outputs& out) const;
  ROVERNAV_NOINLINE float uncertainty_2sd_mm() const { return 2.0f * odometry_.est.position_sd_mm(); }
  // link_in.cpp
  void handle_frame(const Frame& f, uint32_t now, uint16_t late_ms);
  void on_fix(const msg::Fix& m, uint32_t now);
  void on_path(const msg::Path& m, uint8_t seq);
  void on_start(const msg::Start& m, uint8_t seq);
  void on_stop(const msg::Stop& m, uint8_t seq);
  void on_config(const msg::Config& m, uint8_t seq);
  void on_provision(const msg::Provision& m, uint8_t seq, uint32_t now, bool verified);
  uint8_t take_frames(const Inputs& in, uint32_t now);
  // link_out.cpp
  void ack(uint8_t msg_id, uint8_t seq);
  void nack(uint8_t msg_id, uint8_t seq, NackReason reason, uint16_t detail);
  void send_hello();
  void send_event(EventKind kind, uint16_t arg);
  void send_status();
  bool send_link_auth();
  void send_reading(int16_t bearing_cdeg, uint16_t range_mm, uint8_t times);
  void report_echo(int16_t bearing_cdeg, uint16_t range_mm);
  void report_clear(int16_t bearing_cdeg);
  // failsafe.cpp
  void update_gyro(const Inputs& in, uint32_t now);
  void watch_link(uint32_t now);
  void raise_fault(FaultCode code);
  // odometry.cpp
  void dead_reckon(const Inputs& in, float dt_s, uint32_t now);
  void calibrate_speed(const msg::Fix& m, uint32_t now, FixResult r);
  // mode_scan.cpp
  void start_sweep();  // at the step's time (step_.last_ms: every caller is within a step)
  void stop_sweep();  // ends a sweep and points the sonar ahead
  void mode_scan(const SonarIn& in, uint32_t now, Outputs& out);
  // mode_rotate.cpp
  bool mode_rotate(float err, float l, float dt_s, Outputs& out);
  void turn_on_spot(float err, float dt_s, Outputs& out);
  bool room_to_turn() const;
  void heading_q8(int16_t& fx_q8, int16_t& fy_q8) const;
  void back_off(float dt_s, Outputs& out);
  // mode_drive.cpp
  void mode_drive(const SonarIn& in, float err, float l, float dt_s, uint32_t now, Outputs& out);
  bool reached_waypoint(float& l, float& err);
  void pose_command(float rho_mm, float err_deg, Outputs& out);
  // reflex.cpp
  bool reflex(const SonarIn& in, uint32_t now, float l_mm, Outputs& out);
  bool reflex_on_path(int16_t look_cdeg, uint16_t range_mm, float l_mm) const;
  // detour.cpp
  void remember_echo(int16_t bearing_cdeg, uint16_t range_mm);
  Waypoint rejoin_point(float ahead_mm) const;
  void replan_locally();
  bool mode_blocked(uint32_t now);
  void plan_detour();
  void next_detour_goal();
  void continue_detour();
  void no_detour();

  Params params_ = {};
  FrameDecoder decoder_;
};

}  // namespace core
}  // namespace rovernav
