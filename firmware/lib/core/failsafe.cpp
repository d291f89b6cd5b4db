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
      failsafe_.gyro_good_run = false;
      if (failsafe_.fault == FaultCode::None) raise_fault(FaultCode::GyroImplausible);
      return;
    }
    failsafe_.gyro_last_ms = now;
    failsafe_.rate_mdps = in.gyro_rate_mdps;
    if (!failsafe_.gyro_good_run) {
      failsafe_.gyro_good_run = true;
      failsafe_.gyro_good_since_ms = static_cast<uint16_t>(now);
    }
    if (failsafe_.fault != FaultCode::None && static_cast<uint16_t>(static_cast<uint16_t>(now) - failsafe_.gyro_good_since_ms) >= kGyroRecoverMs) {
      const FaultCode cleared = failsafe_.fault;
      failsafe_.fault = FaultCode::None;
      send_event(EventKind::FaultCleared, static_cast<uint16_t>(cleared));
      enter(RoverState::Idle);
    }
    return;
  }
  if (now - failsafe_.gyro_last_ms > params_.gyro_timeout_ms()) {
    failsafe_.gyro_good_run = false;
    failsafe_.rate_mdps = 0;
    if (failsafe_.fault == FaultCode::None) raise_fault(FaultCode::GyroSilent);
  }
}

void Rover::watch_link(uint32_t now) {
  const bool radio_now_lost = now - failsafe_.last_rx_ms > params_.radio_timeout_ms();
  if (radio_now_lost && !failsafe_.radio_lost) {
    failsafe_.radio_lost = true;
    failsafe_.radio_lost_since_ms = now;
    send_event(EventKind::LinkLost, 0);
  } else if (!radio_now_lost && failsafe_.radio_lost) {
    failsafe_.radio_lost = false;
    // What the sonar reported meanwhile was lost: look again. And a detour of its own, begun
    // alone, knows only the last sweep, where the host's map knows the walls: back on the host's
    // path (the nearest leg's end), whose leg that sweep checks; the host, who hears it, replans
    // or gives its word.
    failsafe_.look_after_outage = mission_.pick_if_active();
    detour_.drop();
    send_event(EventKind::LinkBack, saturate_u16(static_cast<float>(now - failsafe_.radio_lost_since_ms) / 100.0f));
  }
  if (failsafe_.had_fix && !failsafe_.dead_reckoning && now - failsafe_.last_fix_ms > params_.fix_timeout_ms()) {
    failsafe_.dead_reckoning = true;
    odometry_.restart_dr();
    if (!failsafe_.radio_lost) send_event(EventKind::CameraLost, link_.camera);
  }
  // Safe stop: never drive on past what the estimate can vouch for.
  const bool moving = step_.state == RoverState::Rotate || step_.state == RoverState::Drive || step_.state == RoverState::Scan ||
                      step_.state == RoverState::BackOff;
  if (mission_.active && moving && failsafe_.dead_reckoning) {
    const float u = uncertainty_2sd_mm();
    if (u >= 0.9f * params_.clearance_margin_mm() ||
        odometry_.dr_distance_mm >= params_.dr_max_distance_mm()) {
      stop_sweep();
      enter(RoverState::Hold);
      send_event(EventKind::Hold, saturate_u16(u));
    }
  }
  if (step_.state == RoverState::Hold && !failsafe_.dead_reckoning &&
      uncertainty_2sd_mm() < 0.5f * params_.clearance_margin_mm()) {
    mission_.pick_again();
    enter(RoverState::Rotate);
    send_event(EventKind::Resumed, mission_.wp);
  }
}

void Rover::raise_fault(FaultCode code) {
  failsafe_.fault = code;
  stop_sweep();
  enter(RoverState::Fault);
  send_event(EventKind::Fault, static_cast<uint16_t>(code));
}

}  // namespace core
}  // namespace rovernav
