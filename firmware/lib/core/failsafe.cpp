// The watchdogs: a silent or implausible gyro raises a fault (cleared after kGyroRecoverMs of
// good samples); the radio's silence and the camera's are noticed and reported; a rover dead
// reckoning past what its estimate can vouch for stops safely (Hold) and resumes on fixes.
#include "rover.h"

#include "float_ops.h"

namespace rovernav {
namespace core {

void Rover::update_gyro(const Inputs& in, uint32_t now) {
  if (in.gyro_valid) {
    const int32_t rate_cdeg_s = in.gyro_rate_mdps / 10;
    const int32_t mag = rate_cdeg_s < 0 ? -rate_cdeg_s : rate_cdeg_s;
    if (mag > params_.gyro_max_rate_cdeg_s()) {
      gyro_good_run_ = false;
      if (fault_ == FaultCode::None) raise_fault(FaultCode::GyroImplausible);
      return;
    }
    gyro_last_ms_ = now;
    rate_mdps_ = in.gyro_rate_mdps;
    if (!gyro_good_run_) {
      gyro_good_run_ = true;
      gyro_good_since_ms_ = static_cast<uint16_t>(now);
    }
    if (fault_ != FaultCode::None && static_cast<uint16_t>(static_cast<uint16_t>(now) - gyro_good_since_ms_) >= kGyroRecoverMs) {
      const FaultCode cleared = fault_;
      fault_ = FaultCode::None;
      send_event(EventKind::FaultCleared, static_cast<uint16_t>(cleared));
      enter(RoverState::Idle);
    }
    return;
  }
  if (now - gyro_last_ms_ > params_.gyro_timeout_ms()) {
    gyro_good_run_ = false;
    rate_mdps_ = 0;
    if (fault_ == FaultCode::None) raise_fault(FaultCode::GyroSilent);
  }
}

void Rover::watch_link(uint32_t now) {
  const bool radio_now_lost = now - last_rx_ms_ > params_.radio_timeout_ms();
  if (radio_now_lost && !radio_lost_) {
    radio_lost_ = true;
    radio_lost_since_ms_ = now;
    send_event(EventKind::LinkLost, 0);
  } else if (!radio_now_lost && radio_lost_) {
    radio_lost_ = false;
    // What the sonar reported meanwhile was lost: look again. And a detour of its own, begun
    // alone, knows only the last sweep, where the host's map knows the walls: back on the host's
    // path (the nearest leg's end), whose leg that sweep checks; the host, who hears it, replans
    // or gives its word.
    look_after_outage_ = pick_target_ = mission_;
    detour_n_ = detour_i_ = 0;
    send_event(EventKind::LinkBack, saturate_u16(static_cast<float>(now - radio_lost_since_ms_) / 100.0f));
  }
  if (had_fix_ && !dead_reckoning_ && now - last_fix_ms_ > params_.fix_timeout_ms()) {
    dead_reckoning_ = true;
    dr_distance_mm_ = 0.0f;
    if (!radio_lost_) send_event(EventKind::CameraLost, camera_);
  }
  // Safe stop: never drive on past what the estimate can vouch for.
  const bool moving = state_ == RoverState::Rotate || state_ == RoverState::Drive || state_ == RoverState::Scan ||
                      state_ == RoverState::BackOff;
  if (mission_ && moving && dead_reckoning_) {
    const float u = uncertainty_2sd_mm();
    if (u >= 0.9f * params_.clearance_margin_mm() ||
        dr_distance_mm_ >= params_.dr_max_distance_mm()) {
      stop_sweep();
      enter(RoverState::Hold);
      send_event(EventKind::Hold, saturate_u16(u));
    }
  }
  if (state_ == RoverState::Hold && !dead_reckoning_ &&
      uncertainty_2sd_mm() < 0.5f * params_.clearance_margin_mm()) {
    pick_target_ = true;
    enter(RoverState::Rotate);
    send_event(EventKind::Resumed, wp_);
  }
}

void Rover::raise_fault(FaultCode code) {
  fault_ = code;
  stop_sweep();
  enter(RoverState::Fault);
  send_event(EventKind::Fault, static_cast<uint16_t>(code));
}

}  // namespace core
}  // namespace rovernav
