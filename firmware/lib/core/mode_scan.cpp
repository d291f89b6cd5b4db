// Scan: stopped, the sonar swept from -90 to +90 degrees (Sweep), every reading reported.
#include "rover.h"

namespace rovernav {
namespace core {

void Rover::start_sweep() {
  sonar_.reflex_waiting = false;   // a ping still out belongs to the reflex, not to the sweep
  ++sonar_.scan_id;
  sonar_.scan_echoes = 0;
  detour_.sweep_starts();   // the host has not heard it: until a HEARTBEAT says the host heard this sweep
  enter(RoverState::Scan);   // ends a detour being planned
  // What was seen beside the front of the body, behind the sensor, stays (no ping of this sweep
  // reaches it); what the sweep looks at afresh, and what lies behind the centre, is forgotten.
  int16_t fx = 0, fy = 0;
  heading_q8(fx, fy);
  detour_.local.keep_near(here_mm(), kKeepNearMm, fx, fy, static_cast<int16_t>(params_.raw(Param::SonarOffsetMm)));
  sonar_.sweep.start(step_.now_ms(), sonar_.servo_cdeg, params_.sweep_step_ms());
}

void Rover::stop_sweep() {
  sonar_.sweep = Sweep();
  sonar_.servo_cdeg = 0;
}

// Scan: one step of the sweep; each ping's result reported (an echo within sonar_report_mm, or
// "nothing there" for the host to clear the cone); at the end, the leg checked against what it saw.
void Rover::mode_scan(const SonarIn& in, uint32_t now, Outputs& out) {
  const Params& p = params_;
  if (step_.work & kWorkFix) {   // the sweep goes on next step (a result that came is held)
    step_.defer();
    return;
  }
  int16_t servo = sonar_.servo_cdeg;
  bool fire = false;
  const Sweep::Echo echo = sonar_.sweep.step(now, in.valid, in.range_mm, servo, fire);
  sonar_.servo_cdeg = servo;
  out.fire_sonar = fire;
  if (echo.valid) {
    step_.did(kWorkOther);
    if (static_cast<uint16_t>(echo.range_mm - 1u) < p.sonar_report_mm()) {   // 0 < range <= report: 0 wraps to 65,535
      report_echo(echo.bearing_cdeg, echo.range_mm);
    } else {
      report_clear(echo.bearing_cdeg);   // nothing within the report range: the host clears the cone
    }
  }
  if (!sonar_.sweep.running()) {
    // The last reading (its OBSTACLE, signed, and its disk) was this step's job: the sweep's end
    // (its EVENT, signed, and the check of the leg against the echoes) takes the next.
    if (echo.valid) {
      step_.defer();
      return;
    }
    for (uint8_t i = 0; i < kSayTimes; ++i) send_event(EventKind::ScanDone, sonar_.scan_echoes);   // as the echoes (report_echo)
    sonar_.sweep_distance_mm = 0.0f;
    sonar_.sweep_heading_rad = odometry_.est.heading_rad();
    enter(RoverState::Rotate);
    replan_locally();
  }
}

}  // namespace core
}  // namespace rovernav
