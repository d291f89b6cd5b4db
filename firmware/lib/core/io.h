// The core's boundary: what the shell reads each tick (Inputs) and what it must do (Outputs).
// Plain structs, no pointers into hardware; the Uno shell, the native tests and the simulator
// (through rover_abi) all fill and read the same fields.
#pragma once
#include <stdint.h>

#include "vehicle_gen.h"

namespace rovernav {
namespace core {

enum : uint8_t { kTxPerStep = kUartBufferBytes };  // at most this many bytes leave per step: the TX buffer

// Whether the core reads wheel encoders (Inputs.wheels_valid) at all. The Uno's shell has none
// to read: main.cpp never sets wheels_valid, and the image leaves out the encoders' dead
// reckoning (120 bytes of its flash), as dead code the compiler cannot see. The native core,
// the tests and the simulator keep it. A shell that reads encoders on the Uno turns this on.
#if defined(ROVERNAV_UNO)
constexpr bool kReadsWheelEncoders = false;
#else
constexpr bool kReadsWheelEncoders = true;
#endif

struct Inputs {
  uint32_t now_ms;            ///< monotonic time; wraps after 49 days
  bool gyro_valid;            ///< a fresh gyro sample this step
  int32_t gyro_rate_mdps;     ///< yaw rate in millidegrees/s, clockwise seen from above
  bool sonar_valid;           ///< the result of the last fire_sonar is here
  uint16_t sonar_range_mm;    ///< 0 = no echo
  bool wheels_valid;          ///< wheel encoders fitted and read
  int16_t left_ticks;         ///< ticks since the previous step, forward positive
  int16_t right_ticks;
  const uint8_t* rx;          ///< bytes received from the link and not yet taken (Outputs.rx_used)
  uint8_t rx_len;
  uint8_t tx_room;            ///< bytes the link can take now (at most kTxPerStep are given)
};

struct Outputs {
  int16_t left_pwm;           ///< -255..255, forward positive
  int16_t right_pwm;
  int16_t servo_cdeg;         ///< sonar servo angle wanted, relative to ahead, clockwise positive
  bool fire_sonar;            ///< ping now; report the result in a later Inputs.sonar_valid
  uint8_t rx_used;            ///< bytes of Inputs.rx taken: the rest come again, first, next step
                              ///< (a signed frame's tag is a step's heavy job: one a step)
  uint8_t tx_len;
  const uint8_t* tx;          ///< bytes to send now: the core's own queue, valid until the next step
};

}  // namespace core
}  // namespace rovernav
