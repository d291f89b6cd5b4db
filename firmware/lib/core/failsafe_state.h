// The watchdogs' state: the gyro's, the radio's and the camera's, and the fault.
#pragma once
#include <stdint.h>

#include "messages_gen.h"

namespace rovernav {
namespace core {

/// Written by failsafe.cpp. What the watchdogs watch comes from elsewhere, through the functions
/// below: link_in.cpp notes a frame taken (heard) and a fix taken (took_fix); rover.cpp's first
/// step starts the clocks (start), and its run_state() starts the look an outage asked for
/// (outage_looked).
struct FailsafeState {
  FaultCode fault = FaultCode::None;
  uint32_t gyro_last_ms = 0;
  uint16_t gyro_good_since_ms = 0;       ///< modulo 65,536: a faulted gyro's good run (cleared at 500 ms)
  int32_t rate_mdps = 0;                 ///< the gyro's last good yaw rate, as it came
  uint32_t last_rx_ms = 0;
  uint32_t last_fix_ms = 0;
  uint32_t radio_lost_since_ms = 0;
  bool dead_reckoning = false;
  bool had_fix = false;
  bool radio_lost : 1;                   ///< nothing taken from the radio for radio_timeout_ms
  bool look_after_outage : 1;            ///< the radio came back mid-mission: sweep before moving on
  bool gyro_good_run : 1;                ///< a faulted gyro is on a good run (since gyro_good_since_ms)

  void start(uint32_t now_ms) { last_rx_ms = gyro_last_ms = now_ms; }
  void heard(uint32_t now_ms) { last_rx_ms = now_ms; }
  void outage_looked() { look_after_outage = false; }
  /// A fix taken into the estimate; returns true when it ends dead reckoning (CameraBack).
  bool took_fix(uint32_t now_ms) {
    last_fix_ms = now_ms;
    had_fix = true;
    if (!dead_reckoning) return false;
    dead_reckoning = false;
    return true;
  }
};

}  // namespace core
}  // namespace rovernav
