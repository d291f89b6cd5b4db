// The step's own state (rover.cpp: step(), run_state(), enter()): the mode, the clock, and the
// one-heavy-job-a-step bookkeeping every mode takes part in.
#pragma once
#include <stdint.h>

#include "messages_gen.h"
#include "noinline.h"

namespace rovernav {
namespace core {

/// Written by rover.cpp. The modes' files, link_in.cpp and detour.cpp report the heavy jobs they
/// did and put jobs off through did(), defer() and spend_reserve().
struct StepState {
  RoverState state = RoverState::Idle;   ///< the mode: changed by Rover::enter() only
  uint8_t work = 0;                      ///< the heavy jobs this step did (Rover::kWork* bits)
  uint16_t held_sonar_mm = 0;            ///< a sonar result put off to the next step (see step())
  uint32_t last_ms = 0;                  ///< the step's time
  bool booted : 1;                       ///< the first step has been taken
  bool have_time : 1;                    ///< last_ms holds a step's time
  bool sonar_held : 1;                   ///< held_sonar_mm is waiting for this step
  bool put_off : 1;                      ///< this step put a job off: the next takes no FIX (kWorkReserved)

  /// A heavy job this step did (Rover::kWork* bits).
  /// The step's time, out of line: a four-byte load from the Uno's global Rover is 16 bytes of code.
  ROVERNAV_NOINLINE uint32_t now_ms() const { return last_ms; }
  void did(uint8_t job) { work = static_cast<uint8_t>(work | job); }
  /// This step puts a job off: the next is kept for it.
  void defer() { put_off = true; }
  /// The step kept for a put-off job is spent on it (Rover::kWorkReserved cleared).
  void spend_reserve() { work = static_cast<uint8_t>(work & ~kReserved); }
  enum : uint8_t { kReserved = 1u << 3 };   ///< Rover::kWorkReserved (rover.h checks they agree)
};

}  // namespace core
}  // namespace rovernav
